/*
 * Constants of gs_radau5 (radau5.c, the only file including this header): the Radau IIA
 * coefficients and the defaults of its tuning macros.
 */
#ifndef GS_RADAU5_H
#define GS_RADAU5_H

/* Radau IIA constants (scipy's radau.py; Hairer & Wanner IV.8). */
#define GS_S6 2.4494897427831780981972840747058913919659474806567
static const double gs_rd_C[3] = {(4.0 - GS_S6) / 10.0, (4.0 + GS_S6) / 10.0, 1.0};
static const double gs_rd_E[3] = {(-13.0 - 7.0 * GS_S6) / 3.0, (-13.0 + 7.0 * GS_S6) / 3.0,
                                  -1.0 / 3.0};
/* Eigenvalues of A^-1: MU_REAL = 3 + 3^(2/3) - 3^(1/3),
 * MU_COMPLEX = 3 + (3^(1/3) - 3^(2/3))/2 - i (3^(5/6) + 3^(7/6))/2. */
#define GS_MU_REAL 3.6378342527444957322
#define GS_MU_CRE 2.6810828736277521339
#define GS_MU_CIM (-3.0504301992474105694)
static const double gs_rd_T[3][3] = {
    {0.09443876248897524, -0.14125529502095421, 0.03002919410514742},
    {0.25021312296533332, 0.20412935229379994, -0.38294211275726192},
    {1.0, 1.0, 0.0}};
static const double gs_rd_TI[3][3] = {
    {4.17871859155190428, 0.32768282076106237, 0.52337644549944951},
    {-4.17871859155190428, -0.32768282076106237, 0.47662355450055044},
    {0.50287263494578682, -2.57192694985560522, 0.59603920482822492}};
/* Dense output: y(t_old + x h) = y_old + sum_m Q[:, m] x^(m+1), Q = Z^T P. */
static const double gs_rd_P[3][3] = {
    {13.0 / 3.0 + 7.0 * GS_S6 / 3.0, -23.0 / 3.0 - 22.0 * GS_S6 / 3.0, 10.0 / 3.0 + 5.0 * GS_S6},
    {13.0 / 3.0 - 7.0 * GS_S6 / 3.0, -23.0 / 3.0 + 22.0 * GS_S6 / 3.0, 10.0 / 3.0 - 5.0 * GS_S6},
    {1.0 / 3.0, -8.0 / 3.0, 10.0 / 3.0}};

/* Tuning constants (defaults of Hairer's RADAU5 unless noted; override with -D;
 * tuned on paper2d: THETA_TARGET, JAC_AT and FNEWT are ours).  Compiling with
 * -DGS_RADAU_DEBUG prints per-step diagnostics to stderr. */
#ifndef GS_RADAU_NIT
#define GS_RADAU_NIT 7 /* maximum Newton iterations per step                      */
#endif
#ifndef GS_RADAU_THET
#define GS_RADAU_THET 0.001 /* re-evaluate J after a step whose Newton rate > THET */
#endif
#ifndef GS_RADAU_SAFE
#define GS_RADAU_SAFE 0.9 /* safety factor of the step-size selection            */
#endif
#ifndef GS_RADAU_FACL
#define GS_RADAU_FACL 5.0 /* h_new >= h / FACL                                   */
#endif
#ifndef GS_RADAU_FACR
#define GS_RADAU_FACR 0.125 /* h_new <= h / FACR                                 */
#endif
#ifndef GS_RADAU_QUOT1
#define GS_RADAU_QUOT1 1.0 /* keep h (and the LU) when h_new / h is in [QUOT1, QUOT2] */
#endif
#ifndef GS_RADAU_QUOT2
#define GS_RADAU_QUOT2 1.2
#endif
#ifndef GS_RADAU_FNEWT
/* Newton's stopping tolerance, max(FNEWT, NEWTON_FLOOR eps / rtol) in the scaled norm: it
 * stops at 3 % of the error tolerance, at every rtol. RADAU5's default min(0.03, sqrt(rtol))
 * asks more as rtol tightens; a stiffly stabilised model's Newton increments (paper2d's
 * CSM gains, 1500-3000 1/s) stall at their rounding floor above it, the steps are refused
 * as not converging, and paper2d at rtol 1e-9 took 8030 steps, 4953 refused, where 1e-8
 * takes 482: with 0.03, 809 and none refused, the final state as accurate (4e-13). */
#define GS_RADAU_FNEWT 0.03
#endif
#ifndef GS_RADAU_NEWTON_FLOOR
/* ... and never below the rounding of the stage values: increments of 1e4 ulp of the state
 * count as converged (fnewt >= NEWTON_FLOOR eps / rtol, which acts below rtol 7e-11; RADAU5
 * has 10 uround / rtol). The stage values of a stiffly stabilised model carry the rounding of
 * its rhs (gains times small differences) and of the LU. With 10 ulp, paper2d refused 5112 of
 * 24 608 steps at rtol 1e-11 as not converging (64 ms a 3 s run), and 14 344 at 1e-12 (253
 * ms); with 1e4, 1247 of 13 162 (31 ms) and 10 615 (128 ms), the final state as accurate
 * (1e-12 against CVODES at 1e-13). 1e5 also freed rtol 1e-10 (2257 steps, 260 refused, to
 * 1450, none) but moved a located slip by 1.4e-12 s between two ways of watching it that the
 * tests hold to 1e-12 s. Below ~1e-11 the error test itself meets its rounding floor. */
#define GS_RADAU_NEWTON_FLOOR 1e4
#endif
#ifndef GS_RADAU_THETA_TARGET
#define GS_RADAU_THETA_TARGET 0.2 /* Newton-aware step limit, see gs_radau5 (0: off) */
#endif
#ifndef GS_RADAU_THETA_EXP
#define GS_RADAU_THETA_EXP 3.0
#endif
#ifndef GS_RADAU_JAC_AT
#define GS_RADAU_JAC_AT 0.5 /* evaluate J at t + JAC_AT h (predicted state), see gs_radau5 */
#endif

#endif /* GS_RADAU5_H */
