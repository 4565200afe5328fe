/*
 * grasping_sym driver: a thin, fast C front end to CasADi-generated model code.
 *
 * This file is compiled next to the CasADi-generated C file (a separate
 * translation unit in the same shared library).  It is configured entirely by
 * preprocessor macros passed with -D:
 *
 *   GS_RHS        name of the CasADi DAE right-hand side, e.g. paper2d_rhs.
 *                 Inputs (t[1], x[nx], z[0], p[np], u[0]),
 *                 outputs (ode[nx], alg[0], quad[0], zero[0]).          required
 *   GS_NX         number of states nx (>= 1)                              required
 *   GS_NP         number of parameters np (>= 0)                          required
 *   GS_HAS_OUT    1 if an outputs function exists, else 0         default 0
 *   GS_OUT        name of the outputs function, inputs (x[nx], p[np]),
 *                 output y[ny]                                    needed if GS_HAS_OUT
 *   GS_NY         number of outputs ny                            default 0
 *   GS_SZ_ARG, GS_SZ_RES, GS_SZ_IW, GS_SZ_W
 *                 work sizes: maximum over the functions used of CasADi's
 *                 Function.sz_arg(), sz_res(), sz_iw(), sz_w()            required
 *   GS_CASADI_INT integer type of CasADi's iw array       default long long int
 *                 (must match casadi_int of the generated file)
 *   GS_HAS_JAC    1 if the Jacobian of GS_RHS is compiled in, else 0  default 0
 *   GS_JAC        its name, e.g. jac_paper2d_rhs (CasADi's Function.jacobian() of
 *                 GS_RHS: inputs (t, x, z, p, u, <nominal outputs>...), outputs one
 *                 block per (output, input) pair).  It is called generically: all
 *                 GS_JAC_NIN inputs are NULL except t (0), x (1) and p (3) (CasADi
 *                 reads a NULL input as zeros; the nominal outputs are structurally
 *                 unused), all GS_JAC_NOUT results are NULL except block
 *                 GS_JAC_BLOCK = d ode / d x (nx x nx), whose sparsity is read from
 *                 the generated GS_JAC##_sparsity_out(GS_JAC_BLOCK) (compressed
 *                 column format [nrow, ncol, colind[ncol+1], row[nnz]], or
 *                 [nrow, ncol, 1] when dense) and scattered into a dense matrix.
 *                                                                 needed if GS_HAS_JAC
 *   GS_JAC_NIN, GS_JAC_NOUT   Function.n_in(), n_out() of GS_JAC  needed if GS_HAS_JAC
 *   GS_JAC_BLOCK  index of the output d ode / d x                 default 1
 *                 (the GS_SZ_* maxima must include GS_JAC's work sizes)
 *   GS_HAS_CON    1 if a constraints function is compiled in, else 0  default 0
 *   GS_CON        its name, e.g. paper2d_constraints: inputs (x[nx], p[np]), outputs
 *                 C[nc] (position constraints, zero on the motion), dC/dx (nc x nx),
 *                 Cdot[nc] (d C / dt along the closed loop), dCdot/dx (nc x nx); both
 *                 Jacobians dense, column-major (CasADi's storage)   needed if GS_HAS_CON
 *   GS_NC         number of constraints nc (>= 1)                  needed if GS_HAS_CON
 *                 (the GS_SZ_* maxima must include GS_CON's work sizes)
 *
 * Exported functions (all prefixed gs_, default visibility):
 *
 *   int    gs_info(long* nx, long* np, long* ny);
 *   int    gs_rhs(const double* x, const double* p, double* xdot);
 *   int    gs_rhs_batch(long n, const double* X, const double* p, double* XDOT);
 *   int    gs_outputs(const double* x, const double* p, double* y);          (GS_HAS_OUT)
 *   int    gs_outputs_batch(long n, const double* X, const double* p, double* Y); (GS_HAS_OUT)
 *   long   gs_rk4(double t0, double h, long nsteps, long stride,
 *                 const double* x0, const double* p, const double* lo,
 *                 const double* hi, const int* proj_mask, double proj_tol, double* out,
 *                 double* stats, double* t_fail);
 *   long   gs_radau5(double t0, long n_out, const double* t_out, const double* x0,
 *                    const double* p, double rtol, double atol, double h0,
 *                    long max_steps, const double* lo, const double* hi,
 *                    const int* proj_mask, double proj_tol, double* out,
 *                    double* stats, double* t_fail);
 *   long   gs_dopri5(double t0, long n_out, const double* t_out, const double* x0,
 *                    const double* p, double rtol, double atol, double h0,
 *                    long max_steps, long nstiff, const double* lo, const double* hi,
 *                    const int* proj_mask, double proj_tol, double* out,
 *                    double* stats, double* t_fail);
 *   int    gs_con_info(long* nc);
 *   int    gs_constraints(const double* x, const double* p, double* C, double* JC,
 *                         double* Cd, double* JCd);                     (GS_HAS_CON)
 *   int    gs_project(double* x, const double* p, const int* mask, double tol,
 *                     double* stats);                                   (GS_HAS_CON)
 *   double gs_rhs_loop_ns(long n, const double* x, const double* p);
 *
 * Return codes: 0 (or a row count for gs_rk4 / gs_radau5 / gs_dopri5) on success;
 * GS_ERR_EVAL (-3) when the CasADi function reports an error; see gs_rk4,
 * gs_radau5, gs_dopri5 and gs_project for their codes.  Without a compiled Jacobian
 * (GS_HAS_JAC 0) gs_radau5 uses forward differences of GS_RHS.
 *
 * Projection (proj_mask not NULL, needs GS_HAS_CON): after every accepted step (and at
 * every dense-output time between steps) the state is projected onto the constraints,
 * see gs_project.  The stats array (GS_NSTATS doubles, see GS_ST_*) counts the constraint
 * evaluations and records the largest residuals found before projecting.
 *
 * Thread safety: CasADi work arrays live on the stack of each exported call
 * (or in thread-local storage when they are large, see GS_WORK_ON_STACK_MAX),
 * so every gs_ function is reentrant and may be called from several threads
 * at once.  p may be NULL when GS_NP == 0.
 */
#include <math.h>
#include <stddef.h>
#include <time.h>
#ifdef GS_RADAU_DEBUG
#include <stdio.h>
#endif

#ifndef GS_RHS
#error "define GS_RHS (name of the CasADi right-hand-side function)"
#endif
#ifndef GS_NX
#error "define GS_NX (number of states)"
#endif
#ifndef GS_NP
#error "define GS_NP (number of parameters)"
#endif
#if !defined(GS_SZ_ARG) || !defined(GS_SZ_RES) || !defined(GS_SZ_IW) || !defined(GS_SZ_W)
#error "define GS_SZ_ARG, GS_SZ_RES, GS_SZ_IW and GS_SZ_W (CasADi work sizes)"
#endif
#include "gs_driver.h"
#ifndef GS_CASADI_INT
#define GS_CASADI_INT long long int
#endif
#if GS_HAS_OUT && !defined(GS_OUT)
#error "GS_HAS_OUT is 1 but GS_OUT (name of the outputs function) is not defined"
#endif
#ifndef GS_HAS_JAC
#define GS_HAS_JAC 0
#endif
#if GS_HAS_JAC && (!defined(GS_JAC) || !defined(GS_JAC_NIN) || !defined(GS_JAC_NOUT))
#error "GS_HAS_JAC is 1 but GS_JAC, GS_JAC_NIN or GS_JAC_NOUT is not defined"
#endif
#ifndef GS_JAC_BLOCK
#define GS_JAC_BLOCK 1
#endif
#if GS_HAS_JAC && (GS_JAC_NIN < 5 || GS_JAC_NIN > GS_SZ_ARG || GS_JAC_NOUT <= GS_JAC_BLOCK || GS_JAC_NOUT > GS_SZ_RES)
#error "GS_JAC_NIN / GS_JAC_NOUT / GS_JAC_BLOCK inconsistent with each other or with GS_SZ_ARG / GS_SZ_RES"
#endif

#if GS_HAS_CON && (!defined(GS_CON) || !defined(GS_NC))
#error "GS_HAS_CON is 1 but GS_CON (name of the constraints function) or GS_NC is not defined"
#endif
#if GS_HAS_CON && GS_SZ_RES < 4
#error "GS_SZ_RES must be at least 4 (the constraints function has four outputs)"
#endif

#define GS_EXPORT __attribute__((visibility("default")))

/* Error codes. */
#define GS_ERR_NONFINITE (-1) /* a state component became NaN or +-inf       */
#define GS_ERR_BOUNDS    (-2) /* a state component left [lo[i], hi[i]]      */
#define GS_ERR_EVAL      (-3) /* the CasADi function returned non-zero       */
#define GS_ERR_ARGS      (-4) /* invalid arguments (h, nsteps, stride, n)    */
#define GS_ERR_STEP      (-5) /* step size too small (Newton / error test)    */
#define GS_ERR_MAXSTEPS  (-6) /* max_steps reached before the end time       */
#define GS_ERR_PROJECT   (-7) /* projection onto the constraints failed      */
#define GS_ERR_STIFF     (-8) /* gs_dopri5: the problem is stiff             */

/* Entries of the stats array (GS_NSTATS doubles). */
#define GS_ST_STEPS 0       /* accepted steps                                      */
#define GS_ST_REJECTED 1    /* rejected steps                                      */
#define GS_ST_RHS 2         /* right-hand-side evaluations                         */
#define GS_ST_JAC 3         /* Jacobian evaluations (gs_radau5)                    */
#define GS_ST_LU 4          /* LU decompositions (gs_radau5)                       */
#define GS_ST_NEWTON 5      /* Newton iterations (gs_radau5)                       */
#define GS_ST_ROWS 6        /* output rows written                                 */
#define GS_ST_HLAST 7       /* last step size                                      */
#define GS_ST_CON_EVALS 8   /* evaluations of GS_CON by the projection             */
#define GS_ST_DRIFT_C 9     /* largest max|C| found before a projection            */
#define GS_ST_DRIFT_CDOT 10 /* largest max|Cdot| found before a velocity projection */
#define GS_ST_PROJ_PHASE 11 /* projection failure: 1 positions, 2 velocities       */
#define GS_ST_PROJ_RES 12   /* projection failure: the residual left               */
#define GS_ST_HLAMBDA 13    /* gs_dopri5: last stiffness estimate h |lambda|       */
#define GS_ST_STIFF 14      /* gs_dopri5: stiffness tests with h |lambda| > 3.25   */

#define GS_EPS 2.220446049250313e-16

/* Work arrays of at most this many bytes go on the stack; larger ones use
 * thread-local static storage (still thread-safe, never overflows the stack). */
#ifndef GS_WORK_ON_STACK_MAX
#define GS_WORK_ON_STACK_MAX (256L * 1024L)
#endif

#define GS_MAX1(n) ((n) > 0 ? (n) : 1)
/* Upper estimate for the preprocessor (no sizeof in #if): 8 bytes per entry. */
#define GS_WORK_BYTES \
  (8L * (GS_MAX1(GS_SZ_ARG) + GS_MAX1(GS_SZ_RES) + GS_MAX1(GS_SZ_IW) + GS_MAX1(GS_SZ_W)))

typedef struct {
  const double* arg[GS_MAX1(GS_SZ_ARG)];
  double* res[GS_MAX1(GS_SZ_RES)];
  GS_CASADI_INT iw[GS_MAX1(GS_SZ_IW)];
  double w[GS_MAX1(GS_SZ_W)];
} gs_work;

#if GS_WORK_BYTES > GS_WORK_ON_STACK_MAX
#define GS_DECLARE_WORK(name) static _Thread_local gs_work name##_storage; gs_work* name = &name##_storage
#else
#define GS_DECLARE_WORK(name) gs_work name##_storage; gs_work* name = &name##_storage
#endif

/* Prototypes of the CasADi-generated functions (standard calling convention). */
int GS_RHS(const double** arg, double** res, GS_CASADI_INT* iw, double* w, int mem);
#if GS_HAS_OUT
int GS_OUT(const double** arg, double** res, GS_CASADI_INT* iw, double* w, int mem);
#endif
#if GS_HAS_JAC
#define GS_PASTE2(a, b) a##b
#define GS_PASTE(a, b) GS_PASTE2(a, b)
#define GS_JAC_SPARSITY_OUT GS_PASTE(GS_JAC, _sparsity_out)
int GS_JAC(const double** arg, double** res, GS_CASADI_INT* iw, double* w, int mem);
const GS_CASADI_INT* GS_JAC_SPARSITY_OUT(GS_CASADI_INT i);
#endif

#if GS_HAS_CON
int GS_CON(const double** arg, double** res, GS_CASADI_INT* iw, double* w, int mem);
#endif

/* xdot = f(t, x, p) using the caller's work arrays. */
static inline int gs_eval_rhs(gs_work* wk, const double* t, const double* x, const double* p,
                              double* xdot) {
  wk->arg[0] = t;
  wk->arg[1] = x;
  wk->arg[2] = NULL;
  wk->arg[3] = p;
  wk->arg[4] = NULL;
  wk->res[0] = xdot;
  wk->res[1] = NULL;
  wk->res[2] = NULL;
  wk->res[3] = NULL;
  return GS_RHS(wk->arg, wk->res, wk->iw, wk->w, 0) ? GS_ERR_EVAL : 0;
}

GS_EXPORT int gs_info(long* nx, long* np, long* ny) {
  if (nx) *nx = GS_NX;
  if (np) *np = GS_NP;
  if (ny) *ny = GS_HAS_OUT ? GS_NY : -1;
  return GS_HAS_OUT;
}

GS_EXPORT int gs_rhs(const double* x, const double* p, double* xdot) {
  static const double t0 = 0.0;
  GS_DECLARE_WORK(wk);
  return gs_eval_rhs(wk, &t0, x, p, xdot);
}

GS_EXPORT int gs_rhs_batch(long n, const double* X, const double* p, double* XDOT) {
  static const double t0 = 0.0;
  GS_DECLARE_WORK(wk);
  if (n < 0) return GS_ERR_ARGS;
  for (long k = 0; k < n; ++k) {
    int rc = gs_eval_rhs(wk, &t0, X + k * GS_NX, p, XDOT + k * GS_NX);
    if (rc) return rc;
  }
  return 0;
}

#if GS_HAS_OUT
static inline int gs_eval_out(gs_work* wk, const double* x, const double* p, double* y) {
  wk->arg[0] = x;
  wk->arg[1] = p;
  wk->res[0] = y;
  return GS_OUT(wk->arg, wk->res, wk->iw, wk->w, 0) ? GS_ERR_EVAL : 0;
}

GS_EXPORT int gs_outputs(const double* x, const double* p, double* y) {
  GS_DECLARE_WORK(wk);
  return gs_eval_out(wk, x, p, y);
}

GS_EXPORT int gs_outputs_batch(long n, const double* X, const double* p, double* Y) {
  GS_DECLARE_WORK(wk);
  if (n < 0) return GS_ERR_ARGS;
  for (long k = 0; k < n; ++k) {
    int rc = gs_eval_out(wk, X + k * GS_NX, p, Y + k * GS_NY);
    if (rc) return rc;
  }
  return 0;
}
#endif

/* 0 if x is finite and inside [lo, hi]; otherwise GS_ERR_NONFINITE / GS_ERR_BOUNDS.
 * lo / hi may be NULL (unbounded). */
static inline int gs_check(const double* x, const double* lo, const double* hi) {
  for (int i = 0; i < GS_NX; ++i)
    if (!isfinite(x[i])) return GS_ERR_NONFINITE;
  for (int i = 0; i < GS_NX; ++i)
    if ((lo && x[i] < lo[i]) || (hi && x[i] > hi[i])) return GS_ERR_BOUNDS;
  return 0;
}

/* ========================================================================== */
/*  Projection onto the constraints: gs_project                               */
/* ========================================================================== */

#ifndef GS_PROJ_MAXIT
#define GS_PROJ_MAXIT 8 /* Gauss-Newton iterations on the positions */
#endif

GS_EXPORT int gs_con_info(long* nc) {
#if GS_HAS_CON
  if (nc) *nc = GS_NC;
#else
  if (nc) *nc = -1;
#endif
  return GS_HAS_CON;
}

#if GS_HAS_CON
/* C, dC/dx, Cdot, dCdot/dx at x (a result pointer may be NULL: that result is skipped). */
static inline int gs_eval_con(gs_work* wk, const double* x, const double* p, double* C,
                              double* JC, double* Cd, double* JCd) {
  wk->arg[0] = x;
  wk->arg[1] = p;
  wk->res[0] = C;
  wk->res[1] = JC;
  wk->res[2] = Cd;
  wk->res[3] = JCd;
  return GS_CON(wk->arg, wk->res, wk->iw, wk->w, 0) ? GS_ERR_EVAL : 0;
}

GS_EXPORT int gs_constraints(const double* x, const double* p, double* C, double* JC,
                             double* Cd, double* JCd) {
  GS_DECLARE_WORK(wk);
  return gs_eval_con(wk, x, p, C, JC, Cd, JCd);
}

/* Solve A y = b in place (A m x m row-major, overwritten) by Gaussian elimination with
 * partial pivoting.  Returns 1 when a pivot is at most m eps max|A| (numerically
 * singular: dependent constraints), else 0. */
static int gs_solve_small(int m, double* A, double* b) {
  double amax = 0.0;
  for (int i = 0; i < m * m; ++i) amax = fmax(amax, fabs(A[i]));
  if (!(amax > 0.0) || !isfinite(amax)) return 1;
  const double tiny = m * GS_EPS * amax;
  for (int k = 0; k < m; ++k) {
    int piv = k;
    for (int i = k + 1; i < m; ++i)
      if (fabs(A[i * m + k]) > fabs(A[piv * m + k])) piv = i;
    if (!(fabs(A[piv * m + k]) > tiny)) return 1;
    if (piv != k) {
      for (int j = 0; j < m; ++j) {
        const double tmp = A[k * m + j];
        A[k * m + j] = A[piv * m + j];
        A[piv * m + j] = tmp;
      }
      const double tb = b[k];
      b[k] = b[piv];
      b[piv] = tb;
    }
    for (int i = k + 1; i < m; ++i) {
      const double l = A[i * m + k] / A[k * m + k];
      for (int j = k + 1; j < m; ++j) A[i * m + j] -= l * A[k * m + j];
      b[i] -= l * b[k];
    }
  }
  for (int i = m - 1; i >= 0; --i) {
    double s = b[i];
    for (int j = i + 1; j < m; ++j) s -= A[i * m + j] * b[j];
    b[i] = s / A[i * m + i];
  }
  return 0;
}

/* The least-norm change of the states S = {i : mask[i] == which} that removes the linear
 * part of the residual r: x_S -= J_S^T (J_S J_S^T)^-1 r, with J (nc x nx, column-major)
 * the residual's Jacobian.  Returns 1 when J_S J_S^T is singular. */
static int gs_least_norm(double* x, const int* mask, int which, const double* J,
                         const double* r) {
  enum { m = GS_NC };
  double A[m * m], y[m];
  for (int a = 0; a < m; ++a) {
    y[a] = r[a];
    for (int b = 0; b <= a; ++b) {
      double s = 0.0;
      for (int i = 0; i < GS_NX; ++i)
        if (mask[i] == which) s += J[i * m + a] * J[i * m + b];
      A[a * m + b] = A[b * m + a] = s;
    }
  }
  if (gs_solve_small(m, A, y)) return 1;
  for (int i = 0; i < GS_NX; ++i)
    if (mask[i] == which) {
      double d = 0.0;
      for (int a = 0; a < m; ++a) d += J[i * m + a] * y[a];
      x[i] -= d;
    }
  return 0;
}

static inline double gs_max_abs(const double* v, int m) {
  double r = 0.0;
  for (int i = 0; i < m; ++i) {
    if (!isfinite(v[i])) return INFINITY;
    r = fmax(r, fabs(v[i]));
  }
  return r;
}

/* Project x in place onto C(x) = 0 and then Cdot(x) = 0 (see gs_project); counts into st.
 * *changed (may be NULL) is set to 1 when x was modified. */
static int gs_project_state(gs_work* wk, double* x, const double* p, const int* mask,
                            double tol, double* st, int* changed) {
  double C[GS_NC], JC[GS_NC * GS_NX], Cd[GS_NC], JCd[GS_NC * GS_NX];
  int rc;
  if (changed) *changed = 0;
  for (int it = 0;; ++it) { /* positions: Gauss-Newton on C(x) = 0 */
    if ((rc = gs_eval_con(wk, x, p, C, JC, Cd, JCd))) return rc;
    st[GS_ST_CON_EVALS] += 1;
    const double r = gs_max_abs(C, GS_NC);
    if (it == 0) st[GS_ST_DRIFT_C] = fmax(st[GS_ST_DRIFT_C], r);
    if (r <= tol) break;
    if (it == GS_PROJ_MAXIT || !isfinite(r) || gs_least_norm(x, mask, 1, JC, C)) {
      st[GS_ST_PROJ_PHASE] = 1;
      st[GS_ST_PROJ_RES] = r;
      return GS_ERR_PROJECT;
    }
    if (changed) *changed = 1;
  }
  /* velocities: Cdot is affine in them, Cdot = JCd v + b(q), so one least-norm step
   * zeroes it up to rounding (relative GS_EPS times the condition of JCd JCd^T, checked by
   * gs_solve_small's pivot test); it is not evaluated again. */
  const double r = gs_max_abs(Cd, GS_NC);
  st[GS_ST_DRIFT_CDOT] = fmax(st[GS_ST_DRIFT_CDOT], r);
  if (r <= tol) return 0;
  if (!isfinite(r) || gs_least_norm(x, mask, 2, JCd, Cd)) {
    st[GS_ST_PROJ_PHASE] = 2;
    st[GS_ST_PROJ_RES] = r;
    return GS_ERR_PROJECT;
  }
  if (changed) *changed = 1;
  return 0;
}

/*
 * Project x (in place) onto the constraints, the way the integrators do after every
 * accepted step:
 *   1. positions: Gauss-Newton on C(x) = 0 with the least-norm change of the states with
 *      mask[i] == 1 (those C depends on), x_S -= J^T (J J^T)^-1 C, J = dC/dx_S, until
 *      max|C| <= tol;
 *   2. velocities: one least-norm step on Cdot(x) = 0 with the states with mask[i] == 2
 *      (the speeds: Cdot depends on them affinely, C not at all), when max|Cdot| > tol;
 *      being affine, one step is exact up to rounding and Cdot is not evaluated again.
 * States with mask[i] == 0 are never changed.  The position phase stops after
 * GS_PROJ_MAXIT iterations.  stats (NULL or GS_NSTATS doubles, written) receives the GS_ST_CON_EVALS,
 * GS_ST_DRIFT_* entries and, on failure, GS_ST_PROJ_PHASE and GS_ST_PROJ_RES.
 * Returns 0, GS_ERR_PROJECT (not converged in GS_PROJ_MAXIT iterations, a singular
 * J J^T or a non-finite residual), GS_ERR_EVAL or GS_ERR_ARGS (x or mask NULL, tol <= 0).
 */
GS_EXPORT int gs_project(double* x, const double* p, const int* mask, double tol,
                         double* stats) {
  GS_DECLARE_WORK(wk);
  double st[GS_NSTATS] = {0};
  if (!x || !mask || !(tol > 0.0)) return GS_ERR_ARGS;
  const int rc = gs_project_state(wk, x, p, mask, tol, st, NULL);
  if (stats)
    for (int i = 0; i < GS_NSTATS; ++i) stats[i] = st[i];
  return rc;
}

/* After an accepted step: project x when proj_mask is given, then re-check the bounds. */
#define GS_PROJECT_STEP(x, changed)                                                   \
  do {                                                                                \
    if (proj_mask) {                                                                  \
      if ((rc = gs_project_state(wk, (x), p, proj_mask, proj_tol, st, (changed))))    \
        goto fail;                                                                    \
      if ((rc = gs_check((x), lo, hi))) goto fail;                                    \
    }                                                                                 \
  } while (0)
#else
#define GS_PROJECT_STEP(x, changed) ((void)0)
#endif

/* Validity of the projection arguments of the integrators. */
static inline int gs_proj_args_ok(const int* proj_mask, double proj_tol) {
  return !proj_mask || (GS_HAS_CON && proj_tol > 0.0 && isfinite(proj_tol));
}

/*
 * Classic fixed-step fourth-order Runge-Kutta, t_k = t0 + k*h, k = 0..nsteps.
 *
 * out (row-major, nx columns) receives x0 in row 0 and x(t_k) in row k/stride
 * whenever k % stride == 0, i.e. nsteps/stride + 1 rows on success.  The
 * caller MUST allocate nsteps/stride + 3 rows: on failure two extra rows are
 * written (see below).
 *
 * After every step the new state is checked: every component must be finite
 * and lo[i] <= x[i] <= hi[i] (lo / hi may be NULL or hold -inf / +inf); with
 * proj_mask (not NULL) it is then projected onto the constraints with tolerance
 * proj_tol (see gs_project) and checked again.
 * When step k (from t_k to t_k + h) fails, integration stops and
 *   *t_fail            = t_k, the time of the last good state,
 *   row r = k/stride+1 = the last good state x(t_k),
 *   row r + 1          = the rejected state (the value that failed the check or the
 *                        projection; may contain NaN/inf; undefined for GS_ERR_EVAL),
 * and the return value is
 *   GS_ERR_NONFINITE (-1)  a component became NaN or +-inf,
 *   GS_ERR_BOUNDS    (-2)  a component left [lo[i], hi[i]],
 *   GS_ERR_EVAL      (-3)  the CasADi function returned an error,
 *   GS_ERR_ARGS      (-4)  h not finite, nsteps < 0 or stride < 1, or projection asked
 *                          without GS_HAS_CON or with proj_tol <= 0 (nothing written),
 *   GS_ERR_PROJECT   (-7)  the projection failed (see gs_project).
 * x0 itself is not checked.  stats: NULL or GS_NSTATS doubles (GS_ST_STEPS, GS_ST_RHS
 * and the projection entries are written).  On success the number of rows written is
 * returned.
 */
GS_EXPORT long gs_rk4(double t0, double h, long nsteps, long stride, const double* x0,
                      const double* p, const double* lo, const double* hi,
                      const int* proj_mask, double proj_tol, double* out, double* stats,
                      double* t_fail) {
  GS_DECLARE_WORK(wk);
  double x[GS_NX], xn[GS_NX], xs[GS_NX], k1[GS_NX], k2[GS_NX], k3[GS_NX], k4[GS_NX];
  double ts;
  double st[GS_NSTATS] = {0};
  long row = 1;
  int rc = 0;

  if (!isfinite(h) || !isfinite(t0) || nsteps < 0 || stride < 1 ||
      !gs_proj_args_ok(proj_mask, proj_tol))
    return GS_ERR_ARGS;
  for (int i = 0; i < GS_NX; ++i) {
    x[i] = out[i] = x0[i];
    xn[i] = NAN; /* reported as the rejected state if the very first evaluation fails */
  }

  for (long k = 0; k < nsteps; ++k) {
    const double t = t0 + (double)k * h;
    if ((rc = gs_eval_rhs(wk, &t, x, p, k1))) goto fail;
    for (int i = 0; i < GS_NX; ++i) xs[i] = x[i] + 0.5 * h * k1[i];
    ts = t + 0.5 * h;
    if ((rc = gs_eval_rhs(wk, &ts, xs, p, k2))) goto fail;
    for (int i = 0; i < GS_NX; ++i) xs[i] = x[i] + 0.5 * h * k2[i];
    if ((rc = gs_eval_rhs(wk, &ts, xs, p, k3))) goto fail;
    for (int i = 0; i < GS_NX; ++i) xs[i] = x[i] + h * k3[i];
    ts = t + h;
    if ((rc = gs_eval_rhs(wk, &ts, xs, p, k4))) goto fail;
    for (int i = 0; i < GS_NX; ++i)
      xn[i] = x[i] + (h / 6.0) * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    st[GS_ST_RHS] += 4;
    if ((rc = gs_check(xn, lo, hi))) goto fail;
    GS_PROJECT_STEP(xn, NULL);
    st[GS_ST_STEPS] += 1;
    for (int i = 0; i < GS_NX; ++i) x[i] = xn[i];
    if ((k + 1) % stride == 0) {
      for (int i = 0; i < GS_NX; ++i) out[row * GS_NX + i] = x[i];
      ++row;
    }
    continue;
  fail:
    if (t_fail) *t_fail = t;
    {
      double* r = out + (k / stride + 1) * GS_NX;
      for (int i = 0; i < GS_NX; ++i) {
        r[i] = x[i];
        r[GS_NX + i] = xn[i];
      }
    }
    if (stats)
      for (int i = 0; i < GS_NSTATS; ++i) stats[i] = st[i];
    return rc;
  }
  if (stats)
    for (int i = 0; i < GS_NSTATS; ++i) stats[i] = st[i];
  return row;
}

/* ========================================================================== */
/*  Radau IIA (order 5) with adaptive steps: gs_radau5                        */
/* ========================================================================== */
/*
 * The algorithm is a port of scipy.integrate.Radau
 * (scipy/integrate/_ivp/radau.py, BSD-3-Clause, (c) the SciPy developers), which
 * follows E. Hairer, G. Wanner, "Solving Ordinary Differential Equations II:
 * Stiff and Differential-Algebraic Problems", 2nd ed., Springer 1996, Sec. IV.8
 * (the RADAU5 code): simplified Newton iteration on the collocation system
 * transformed with the eigen-decomposition of the Radau IIA matrix A (one real
 * n x n and one complex n x n linear system per iteration), Jacobian reuse
 * across steps (the Jacobian is re-evaluated only when the Newton iteration
 * converged slowly or failed), the embedded third-order error estimate with
 * its stiff filtering by (mu_real/h - J)^-1, Gustafsson's predictive step-size
 * control and the collocation polynomial as dense output.  The C code here is
 * our own; the constants are those of the reference.
 */

/* Work storage of gs_radau5: a few n x n matrices, on the stack when small. */
typedef struct {
  double J[GS_NX * GS_NX];           /* d f / d x, row-major                     */
  double LUr[GS_NX * GS_NX];         /* LU of mu_real/h I - J (row-major)        */
  double LUcr[GS_NX * GS_NX];        /* LU of mu_complex/h I - J (row-major), */
  double LUci[GS_NX * GS_NX];        /* real and imaginary parts              */
  int pr[GS_NX], pc[GS_NX];          /* row pivots                               */
} gs_radau_mats;

#define GS_RADAU_MATS_BYTES (8L * 4L * GS_NX * GS_NX + 8L * GS_NX)
#if GS_RADAU_MATS_BYTES > GS_WORK_ON_STACK_MAX
#define GS_DECLARE_MATS(name) static _Thread_local gs_radau_mats name##_storage; gs_radau_mats* name = &name##_storage
#else
#define GS_DECLARE_MATS(name) gs_radau_mats name##_storage; gs_radau_mats* name = &name##_storage
#endif

#if GS_HAS_JAC
/* J (dense row-major, nx x nx) = block GS_JAC_BLOCK of the generated Jacobian.
 * Only the structural non-zeros are written: J must be zeroed once beforehand. */
static int gs_eval_jac(gs_work* wk, const double* t, const double* x, const double* p, double* J) {
  double val[GS_NX * GS_NX];
  const GS_CASADI_INT* sp = GS_JAC_SPARSITY_OUT(GS_JAC_BLOCK);
  for (int i = 0; i < GS_JAC_NIN; ++i) wk->arg[i] = NULL;
  for (int i = 0; i < GS_JAC_NOUT; ++i) wk->res[i] = NULL;
  wk->arg[0] = t;
  wk->arg[1] = x;
  wk->arg[3] = p;
  wk->res[GS_JAC_BLOCK] = val;
  if (GS_JAC(wk->arg, wk->res, wk->iw, wk->w, 0)) return GS_ERR_EVAL;
  if (!sp || sp[0] != GS_NX || sp[1] != GS_NX) return GS_ERR_ARGS;
  if (sp[2] == 1) { /* CasADi's compressed form of a dense pattern: [nrow, ncol, 1] */
    for (int c = 0; c < GS_NX; ++c)
      for (int r = 0; r < GS_NX; ++r) J[r * GS_NX + c] = val[c * GS_NX + r];
  } else {
    const GS_CASADI_INT* colind = sp + 2;
    const GS_CASADI_INT* row = sp + 2 + GS_NX + 1;
    for (int c = 0; c < GS_NX; ++c)
      for (GS_CASADI_INT k = colind[c]; k < colind[c + 1]; ++k) J[row[k] * GS_NX + c] = val[k];
  }
  return 0;
}
#endif

/* LU with partial pivoting of the row-major n x n matrix A (in place).
 * Returns 0, or 1 if a pivot is exactly zero (singular). */
static int gs_lu_real(double* A, int* piv) {
  const int n = GS_NX;
  for (int k = 0; k < n; ++k) {
    int m = k;
    double amax = fabs(A[k * n + k]);
    for (int i = k + 1; i < n; ++i)
      if (fabs(A[i * n + k]) > amax) amax = fabs(A[i * n + k]), m = i;
    piv[k] = m;
    if (amax == 0.0) return 1;
    if (m != k)
      for (int j = 0; j < n; ++j) {
        double tmp = A[k * n + j];
        A[k * n + j] = A[m * n + j];
        A[m * n + j] = tmp;
      }
    const double inv = 1.0 / A[k * n + k];
    for (int i = k + 1; i < n; ++i) {
      const double l = (A[i * n + k] *= inv);
      if (l != 0.0)
        for (int j = k + 1; j < n; ++j) A[i * n + j] -= l * A[k * n + j];
    }
  }
  return 0;
}

static void gs_lu_solve_real(const double* LU, const int* piv, double* b) {
  const int n = GS_NX;
  for (int k = 0; k < n; ++k) {
    const int pk = piv[k];
    if (pk > k && pk < n) {
      double tmp = b[k];
      b[k] = b[pk];
      b[pk] = tmp;
    }
  }
  for (int i = 1; i < n; ++i) {
    double s = b[i];
    for (int j = 0; j < i; ++j) s -= LU[i * n + j] * b[j];
    b[i] = s;
  }
  for (int i = n - 1; i >= 0; --i) {
    double s = b[i];
    for (int j = i + 1; j < n; ++j) s -= LU[i * n + j] * b[j];
    b[i] = s / LU[i * n + i];
  }
}

/* LU with partial pivoting of the complex row-major n x n matrix (Ar + i Ai), in
 * place.  Complex arithmetic is written out in real and imaginary parts: C99
 * complex multiplication and division go through the slow, NaN-careful
 * __muldc3 / __divdc3 unless compiled with -fcx-limited-range. */
static int gs_lu_complex(double* Ar, double* Ai, int* piv) {
  const int n = GS_NX;
  for (int k = 0; k < n; ++k) {
    int m = k;
    double amax = fabs(Ar[k * n + k]) + fabs(Ai[k * n + k]);
    for (int i = k + 1; i < n; ++i) {
      const double v = fabs(Ar[i * n + k]) + fabs(Ai[i * n + k]);
      if (v > amax) amax = v, m = i;
    }
    piv[k] = m;
    if (amax == 0.0) return 1;
    if (m != k)
      for (int j = 0; j < n; ++j) {
        double tr = Ar[k * n + j], ti = Ai[k * n + j];
        Ar[k * n + j] = Ar[m * n + j];
        Ai[k * n + j] = Ai[m * n + j];
        Ar[m * n + j] = tr;
        Ai[m * n + j] = ti;
      }
    const double pr = Ar[k * n + k], pi = Ai[k * n + k];
    const double d = 1.0 / (pr * pr + pi * pi);
    const double ir = pr * d, ii = -pi * d; /* 1 / pivot */
    for (int i = k + 1; i < n; ++i) {
      const double ar = Ar[i * n + k], ai = Ai[i * n + k];
      const double lr = ar * ir - ai * ii, li = ar * ii + ai * ir;
      Ar[i * n + k] = lr;
      Ai[i * n + k] = li;
      if (lr != 0.0 || li != 0.0)
        for (int j = k + 1; j < n; ++j) {
          const double ur = Ar[k * n + j], ui = Ai[k * n + j];
          Ar[i * n + j] -= lr * ur - li * ui;
          Ai[i * n + j] -= lr * ui + li * ur;
        }
    }
  }
  return 0;
}

static void gs_lu_solve_complex(const double* Ar, const double* Ai, const int* piv, double* br,
                                double* bi) {
  const int n = GS_NX;
  for (int k = 0; k < n; ++k) {
    const int pk = piv[k];
    if (pk > k && pk < n) {
      double tr = br[k], ti = bi[k];
      br[k] = br[pk];
      bi[k] = bi[pk];
      br[pk] = tr;
      bi[pk] = ti;
    }
  }
  for (int i = 1; i < n; ++i) {
    double sr = br[i], si = bi[i];
    for (int j = 0; j < i; ++j) {
      const double lr = Ar[i * n + j], li = Ai[i * n + j];
      sr -= lr * br[j] - li * bi[j];
      si -= lr * bi[j] + li * br[j];
    }
    br[i] = sr;
    bi[i] = si;
  }
  for (int i = n - 1; i >= 0; --i) {
    double sr = br[i], si = bi[i];
    for (int j = i + 1; j < n; ++j) {
      const double ur = Ar[i * n + j], ui = Ai[i * n + j];
      sr -= ur * br[j] - ui * bi[j];
      si -= ur * bi[j] + ui * br[j];
    }
    const double pr = Ar[i * n + i], pi = Ai[i * n + i];
    const double d = 1.0 / (pr * pr + pi * pi);
    br[i] = (sr * pr + si * pi) * d;
    bi[i] = (si * pr - sr * pi) * d;
  }
}

/* Root-mean-square norm of v / scale over m entries. */
static inline double gs_rms(const double* v, const double* scale, int m) {
  double s = 0.0;
  for (int i = 0; i < m; ++i) {
    const double q = v[i] / scale[i % GS_NX];
    s += q * q;
  }
  return sqrt(s / (double)m);
}

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
 * tuned on paper2d: THETA_TARGET, JAC_AT and FNEWT_MIN are ours).  Compiling with
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
#ifndef GS_RADAU_FNEWT_MAX
#define GS_RADAU_FNEWT_MAX 0.03 /* Newton tolerance max(10 eps / rtol, min(FNEWT_MAX, sqrt(rtol))) */
#endif
#ifndef GS_RADAU_THETA_TARGET
#define GS_RADAU_THETA_TARGET 0.2 /* Newton-aware step limit, see below (0: off) */
#endif
#ifndef GS_RADAU_THETA_EXP
#define GS_RADAU_THETA_EXP 3.0
#endif
#ifndef GS_RADAU_FNEWT_MIN
#define GS_RADAU_FNEWT_MIN 1e-4 /* floor: smaller Newton increments are rounding noise */
#endif
#ifndef GS_RADAU_JAC_AT
#define GS_RADAU_JAC_AT 0.5 /* evaluate J at t + JAC_AT h (predicted state), see below */
#endif
/* First step size for an error estimate of order `order` (Hairer-Norsett-Wanner I, II.4, as
 * scipy's select_initial_step): h with h^(order+1) max(|f|, |f'|) = 0.01 in the weighted
 * RMS norm, at most `interval` and, when probe_cap > 0, at most probe_cap times the
 * explicit Euler probe 0.01 |y| / |f|.  That probe assumes every component changes
 * relative to its own size: a start at rest (zero speeds, non-zero accelerations) makes
 * it ~1e-8 s, and the step then needs ~6 steps of 8x growth to reach the dynamics' scale.
 * gs_radau5 passes probe_cap = 0 (a too large first step costs one rejected step there:
 * its first rejection divides h by 10); gs_dopri5 keeps scipy's 100. */
static int gs_initial_step(gs_work* wk, double t0, const double* y, const double* f,
                           const double* p, double rtol, double atol, double interval,
                           int order, double probe_cap, double* st, double* h_out) {
  double scale[GS_NX], tmp[GS_NX], fnew[GS_NX];
  for (int i = 0; i < GS_NX; ++i) scale[i] = atol + fabs(y[i]) * rtol;
  const double d0 = gs_rms(y, scale, GS_NX), d1 = gs_rms(f, scale, GS_NX);
  double hh = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
  if (hh > interval) hh = interval;
  for (int i = 0; i < GS_NX; ++i) tmp[i] = y[i] + hh * f[i];
  const double t1 = t0 + hh;
  const int rc = gs_eval_rhs(wk, &t1, tmp, p, fnew);
  if (rc) return rc;
  st[GS_ST_RHS] += 1;
  for (int i = 0; i < GS_NX; ++i) tmp[i] = fnew[i] - f[i];
  const double d2 = gs_rms(tmp, scale, GS_NX) / hh;
  double h1;
  if (d1 <= 1e-15 && d2 <= 1e-15)
    h1 = fmax(1e-6, hh * 1e-3);
  else
    h1 = pow(0.01 / fmax(d1, d2), 1.0 / (order + 1));
  double h = fmin(probe_cap > 0.0 ? fmin(probe_cap * hh, h1) : h1, interval);
  if (!isfinite(h) || h <= 0.0) h = 1e-6 * interval;
  *h_out = h;
  return 0;
}

#if !GS_HAS_JAC
/* Forward-difference Jacobian (fallback when no Jacobian was compiled in). */
static int gs_fd_jac(gs_work* wk, const double* t, const double* x, const double* p,
                     const double* f, double atol, double* J) {
  double xp[GS_NX], fp[GS_NX];
  for (int i = 0; i < GS_NX; ++i) xp[i] = x[i];
  for (int j = 0; j < GS_NX; ++j) {
    double d = sqrt(GS_EPS) * fmax(fabs(x[j]), fmax(atol, 1e-8) * 1e3);
    xp[j] = x[j] + d;
    d = xp[j] - x[j];
    int rc = gs_eval_rhs(wk, t, xp, p, fp);
    xp[j] = x[j];
    if (rc) return rc;
    for (int i = 0; i < GS_NX; ++i) J[i * GS_NX + j] = (fp[i] - f[i]) / d;
  }
  return 0;
}
#endif

/*
 * Adaptive Radau IIA (order 5) integration of x' = f(t, x, p), see the comment above.
 *
 * Step control (Hairer's RADAU5, H&W IV.8): the Newton contraction rate theta is
 * estimated from successive increments; convergence is declared when
 * theta / (1 - theta) * |dW| <= fnewt (the rate of the previous step is used for the
 * first iteration, so a step may converge after one iteration); a step whose Newton
 * iteration is predicted not to converge within GS_RADAU_NIT iterations is retried
 * with a smaller h (by the predicted amount, or halved on divergence); the Jacobian
 * is re-evaluated after a step whose rate exceeded GS_RADAU_THET and after every
 * rejection, the LU factors are reused when h does not change; after a rejection the
 * next step may not grow; the error estimate and Gustafsson's predictive controller
 * are those of scipy / RADAU5 (weights atol + rtol max(|x_old|, |x_new|), RMS norm).
 *
 * Arguments
 *   t0          initial time; x0[nx] the initial state (not checked against lo / hi)
 *   n_out,t_out output times, strictly increasing, t_out[0] >= t0 (t_out[0] == t0 allowed);
 *               the integration ends at t_out[n_out - 1] exactly (never steps beyond it);
 *               states between steps come from the collocation polynomial (order 3
 *               accurate in the step, continuous), a state at a step end is the step's.
 *   p           parameters (may be NULL when np == 0)
 *   rtol, atol  scalar tolerances, local error measured with atol + rtol |x| (RMS norm);
 *               rtol is raised to 100 eps if smaller.
 *   h0          first step; <= 0 selects it automatically (Hairer-Norsett-Wanner I, II.4,
 *               as scipy's select_initial_step with the error order 3)
 *   max_steps   maximum number of accepted steps (>= 1)
 *   lo, hi      bounds checked on every accepted step's end state (may be NULL)
 *   proj_mask, proj_tol
 *               NULL, or project every accepted step's end state and every output
 *               between steps onto the constraints (see gs_project; needs GS_HAS_CON)
 *   out         row-major, nx columns, at least n_out + 1 rows (see failures)
 *   stats       NULL or GS_NSTATS doubles (GS_ST_*): [0] accepted steps, [1] rejected
 *               steps (error test or Newton failures), [2] right-hand-side evaluations,
 *               [3] Jacobian evaluations, [4] LU decompositions (real and complex each
 *               count 1), [5] Newton iterations, [6] output rows written, [7] last step
 *               size, [8..12] projection counts and residuals
 *   t_fail      receives the last accepted time on failure (may be NULL)
 *
 * Returns n_out on success.  On failure, with r = the number of output rows written
 * (also stats[6]; they are the rows with t_out <= *t_fail),
 *   row r      = the last accepted state x(*t_fail),
 *   row r + 1  = for GS_ERR_NONFINITE / GS_ERR_BOUNDS / GS_ERR_PROJECT the rejected state
 *                (the end of the step that failed the check or the projection, or the
 *                state whose derivative was non-finite), otherwise NaN,
 * and the return value is
 *   GS_ERR_NONFINITE (-1)  a state or its derivative became NaN / +-inf,
 *   GS_ERR_BOUNDS    (-2)  a component left [lo[i], hi[i]] at the end of a step,
 *   GS_ERR_EVAL      (-3)  a CasADi function returned an error,
 *   GS_ERR_ARGS      (-4)  invalid arguments (nothing written),
 *   GS_ERR_STEP      (-5)  the step size fell below 10 ulp(t) (repeated Newton
 *                          failures, error-test failures or singular matrices),
 *   GS_ERR_MAXSTEPS  (-6)  max_steps steps were taken before the end,
 *   GS_ERR_PROJECT   (-7)  the projection failed.
 */
GS_EXPORT long gs_radau5(double t0, long n_out, const double* t_out, const double* x0,
                         const double* p, double rtol, double atol, double h0, long max_steps,
                         const double* lo, const double* hi, const int* proj_mask,
                         double proj_tol, double* out, double* stats, double* t_fail) {
  enum { n = GS_NX, nit = GS_RADAU_NIT };
  GS_DECLARE_WORK(wk);
  GS_DECLARE_MATS(M);
  double y[n], f[n], ynew[n], fnew[n], scale[n], tmp[n], err[n], ze[n];
  double Z[3][n], W[3][n], F[3][n], dW[3][n], Q[n][3], yold[n];
  double st[GS_NSTATS] = {0};
  long row = 0;
  int rc = 0, have_sol = 0, lu_valid = 0, caljac = 0, need_jac = 1, reject = 0, first = 1;
  int nsing = 0;
  double t = t0, told = t0, hsol = 0.0, h;
  double faccon = 1.0, theta = GS_RADAU_THET, theta_meas = 0.0, hacc = 0.0, erracc = 0.0;
  const double t_end = t_out ? t_out[n_out > 0 ? n_out - 1 : 0] : t0;
  const double cfac = GS_RADAU_SAFE * (1 + 2 * nit);
  double fnewt;

  if (n_out < 1 || !t_out || !x0 || !out || max_steps < 1 || !isfinite(t0) || !isfinite(rtol) ||
      !isfinite(atol) || !(rtol >= 0.0) || !(atol >= 0.0) || !isfinite(h0) || !(t_out[0] >= t0) ||
      !gs_proj_args_ok(proj_mask, proj_tol))
    return GS_ERR_ARGS;
  for (long k = 1; k < n_out; ++k)
    if (!(t_out[k] > t_out[k - 1]) || !isfinite(t_out[k])) return GS_ERR_ARGS;
  if (!isfinite(t_end)) return GS_ERR_ARGS;
  if (rtol < 100.0 * GS_EPS) rtol = 100.0 * GS_EPS;
  fnewt = fmax(GS_RADAU_FNEWT_MIN, fmax(10.0 * GS_EPS / rtol, fmin(GS_RADAU_FNEWT_MAX, sqrt(rtol))));

  for (int i = 0; i < n; ++i) {
    y[i] = x0[i];
    ynew[i] = NAN;
    yold[i] = Q[i][0] = Q[i][1] = Q[i][2] = 0.0;
  }
  while (row < n_out && t_out[row] <= t0) {
    for (int i = 0; i < n; ++i) out[row * n + i] = y[i];
    ++row;
  }
  if (row == n_out) goto done;

  if ((rc = gs_eval_rhs(wk, &t, y, p, f))) goto fail;
  st[2] += 1;
  for (int i = 0; i < n; ++i)
    if (!isfinite(f[i])) {
      for (int j = 0; j < n; ++j) ynew[j] = y[j];
      rc = GS_ERR_NONFINITE;
      goto fail;
    }

  /* Initial step (scipy's select_initial_step with error order 3). */
  if (h0 > 0.0)
    h = h0;
  else if ((rc = gs_initial_step(wk, t0, y, f, p, rtol, atol, t_end - t0, 3, 0.0, st, &h)))
    goto fail;
  for (int i = 0; i < n * n; ++i) M->J[i] = 0.0;

  while (1) { /* one attempted step per pass */
    if (st[0] >= (double)max_steps) {
      rc = GS_ERR_MAXSTEPS;
      goto fail;
    }
    if (t + h >= t_end || t_end - (t + h) < 1e-12 * fabs(t_end)) {
      if (h != t_end - t) lu_valid = 0;
      h = t_end - t;
    }
    if (need_jac) {
      /* J at the state predicted (by the previous step's collocation polynomial) at
       * t + GS_RADAU_JAC_AT h: the simplified Newton iteration contracts faster with
       * a Jacobian from the middle of the step than from its start when J varies
       * along the step (constraint-stabilised models: curvature times large gains). */
      const double tj = t + GS_RADAU_JAC_AT * h;
      const double* yj = y;
      if (have_sol && GS_RADAU_JAC_AT > 0.0) {
        const double x = (tj - told) / hsol;
        const double x2 = x * x, x3 = x2 * x;
        for (int i = 0; i < n; ++i) tmp[i] = yold[i] + Q[i][0] * x + Q[i][1] * x2 + Q[i][2] * x3;
        yj = tmp;
      }
#if GS_HAS_JAC
      if ((rc = gs_eval_jac(wk, &tj, yj, p, M->J))) goto fail;
#else
      if (yj != y) {
        if ((rc = gs_eval_rhs(wk, &tj, yj, p, fnew))) goto fail;
        st[2] += 1;
        if ((rc = gs_fd_jac(wk, &tj, yj, p, fnew, atol, M->J))) goto fail;
      } else if ((rc = gs_fd_jac(wk, &t, y, p, f, atol, M->J))) {
        goto fail;
      }
      st[2] += n;
#endif
      st[3] += 1;
      need_jac = 0;
      caljac = 1;
      lu_valid = 0;
    }
    double hnew = h;
    const double min_step = 10.0 * fabs(nextafter(t, INFINITY) - t);
    if (!(h >= min_step)) {
      rc = GS_ERR_STEP;
      goto fail;
    }
    const double mr = GS_MU_REAL / h;
    const double mcr = GS_MU_CRE / h, mci = GS_MU_CIM / h;
    if (!lu_valid) {
      for (int i = 0; i < n * n; ++i) {
        M->LUr[i] = -M->J[i];
        M->LUcr[i] = -M->J[i];
        M->LUci[i] = 0.0;
      }
      for (int i = 0; i < n; ++i) {
        M->LUr[i * n + i] += mr;
        M->LUcr[i * n + i] += mcr;
        M->LUci[i * n + i] = mci;
      }
      st[4] += 2;
      if (gs_lu_real(M->LUr, M->pr) || gs_lu_complex(M->LUcr, M->LUci, M->pc)) {
        if (++nsing >= 5) {
          rc = GS_ERR_STEP;
          goto fail;
        }
        goto unexpected; /* singular: halve h */
      }
      lu_valid = 1;
    }

    /* Starting guess: the previous step's collocation polynomial, extrapolated. */
    if (have_sol) {
      for (int s = 0; s < 3; ++s) {
        const double x = (t + h * gs_rd_C[s] - told) / hsol;
        const double x2 = x * x, x3 = x2 * x;
        for (int i = 0; i < n; ++i)
          Z[s][i] = yold[i] + Q[i][0] * x + Q[i][1] * x2 + Q[i][2] * x3 - y[i];
      }
    } else {
      for (int s = 0; s < 3; ++s)
        for (int i = 0; i < n; ++i) Z[s][i] = 0.0;
    }
    for (int s = 0; s < 3; ++s)
      for (int i = 0; i < n; ++i)
        W[s][i] = gs_rd_TI[s][0] * Z[0][i] + gs_rd_TI[s][1] * Z[1][i] + gs_rd_TI[s][2] * Z[2][i];
    for (int i = 0; i < n; ++i) scale[i] = atol + fabs(y[i]) * rtol;

    /* Simplified Newton iteration on the transformed collocation system. */
    faccon = pow(fmax(faccon, GS_EPS), 0.8);
    theta = GS_RADAU_THET;
    theta_meas = 0.0;
    {
      int newt = 0;
      double dynold = 0.0, thqold = 0.0;
      while (1) {
        if (newt >= nit) goto unexpected;
        int finite = 1;
        for (int s = 0; s < 3; ++s) {
          const double ts = t + h * gs_rd_C[s];
          for (int i = 0; i < n; ++i) tmp[i] = y[i] + Z[s][i];
          if ((rc = gs_eval_rhs(wk, &ts, tmp, p, F[s]))) goto fail;
          for (int i = 0; i < n; ++i) finite &= isfinite(F[s][i]);
        }
        st[2] += 3;
        st[5] += 1;
        if (!finite) goto unexpected;
        for (int i = 0; i < n; ++i) {
          dW[0][i] = gs_rd_TI[0][0] * F[0][i] + gs_rd_TI[0][1] * F[1][i] +
                     gs_rd_TI[0][2] * F[2][i] - mr * W[0][i];
          const double re = gs_rd_TI[1][0] * F[0][i] + gs_rd_TI[1][1] * F[1][i] + gs_rd_TI[1][2] * F[2][i];
          const double im = gs_rd_TI[2][0] * F[0][i] + gs_rd_TI[2][1] * F[1][i] + gs_rd_TI[2][2] * F[2][i];
          /* (re + i im) - (mcr + i mci) (W1 + i W2) */
          dW[1][i] = re - (mcr * W[1][i] - mci * W[2][i]);
          dW[2][i] = im - (mcr * W[2][i] + mci * W[1][i]);
        }
        gs_lu_solve_real(M->LUr, M->pr, dW[0]);
        gs_lu_solve_complex(M->LUcr, M->LUci, M->pc, dW[1], dW[2]);
        ++newt;
        const double dyno = gs_rms(&dW[0][0], scale, 3 * n);
        if (newt > 1 && newt < nit) {
          const double thq = dyno / dynold;
          theta = newt == 2 ? thq : sqrt(thq * thqold);
          theta_meas = theta;
          thqold = thq;
#ifdef GS_RADAU_DEBUG
          fprintf(stderr, "   newt=%d dyno=%.3g dynold=%.3g theta=%.3g fnewt=%.3g h=%.3g\n", newt, dyno, dynold, theta, fnewt, h);
#endif
          if (theta < 0.99) {
            faccon = theta / (1.0 - theta);
            double thpow = 1.0; /* theta^(nit - 1 - newt), without libm's pow */
            for (int k = newt; k < nit - 1; ++k) thpow *= theta;
            const double dyth = faccon * dyno * thpow / fnewt;
            if (dyth >= 1.0) { /* predicted not to converge in time: smaller h */
              const double qnewt = fmax(1e-4, fmin(20.0, dyth));
              h *= 0.8 * pow(qnewt, -1.0 / (4.0 + nit - 1 - newt));
              goto rejected;
            }
          } else {
            goto unexpected;
          }
        }
        dynold = fmax(dyno, GS_EPS);
        for (int s = 0; s < 3; ++s)
          for (int i = 0; i < n; ++i) W[s][i] += dW[s][i];
        for (int s = 0; s < 3; ++s)
          for (int i = 0; i < n; ++i)
            Z[s][i] = gs_rd_T[s][0] * W[0][i] + gs_rd_T[s][1] * W[1][i] + gs_rd_T[s][2] * W[2][i];
        if (faccon * dyno <= fnewt) {
          /* Error estimate (H&W IV.8 (8.19)-(8.20)), filtered by (mu_real/h - J)^-1. */
          for (int i = 0; i < n; ++i) {
            ynew[i] = y[i] + Z[2][i];
            ze[i] = (gs_rd_E[0] * Z[0][i] + gs_rd_E[1] * Z[1][i] + gs_rd_E[2] * Z[2][i]) / h;
            err[i] = f[i] + ze[i];
          }
          gs_lu_solve_real(M->LUr, M->pr, err);
          for (int i = 0; i < n; ++i) scale[i] = atol + fmax(fabs(y[i]), fabs(ynew[i])) * rtol;
          double err_norm = gs_rms(err, scale, n);
          if (!(err_norm < 1.0) && (first || reject)) {
            for (int i = 0; i < n; ++i) tmp[i] = y[i] + err[i];
            if ((rc = gs_eval_rhs(wk, &t, tmp, p, fnew))) goto fail;
            st[2] += 1;
            for (int i = 0; i < n; ++i) err[i] = fnew[i] + ze[i];
            gs_lu_solve_real(M->LUr, M->pr, err);
            err_norm = gs_rms(err, scale, n);
          }
          if (!isfinite(err_norm)) goto unexpected;
          err_norm = fmax(err_norm, 1e-10);
#ifdef GS_RADAU_DEBUG
          fprintf(stderr, "t=%.6g h=%.4g newt=%d theta=%.3g err=%.3g caljac=%d\n", t, h, newt, theta,
                  err_norm, caljac);
#endif
          /* New step size, 1/FACL <= h_new / h <= 1/FACR. */
          const double fac = fmin(GS_RADAU_SAFE, cfac / (newt + 2 * nit));
          double quot = fmax(GS_RADAU_FACR, fmin(GS_RADAU_FACL, sqrt(sqrt(err_norm)) / fac));
          hnew = h / quot;
          if (!(err_norm < 1.0)) { /* error test failed */
            h = first ? 0.1 * h : hnew;
            goto rejected;
          }
          /* Accepted: Gustafsson's predictive controller. */
          if (st[0] >= 1.0) {
            double facgus = (hacc / h) * sqrt(sqrt(err_norm * err_norm / erracc)) / GS_RADAU_SAFE;
            facgus = fmax(GS_RADAU_FACR, fmin(GS_RADAU_FACL, facgus));
            quot = fmax(quot, facgus);
            hnew = h / quot;
          }
          hacc = h;
          erracc = fmax(1e-2, err_norm);
          break;
        }
      }
    }

    /* Accepted step from t to t + h. */
    st[0] += 1;
    {
      const double tnew = (h == t_end - t) ? t_end : t + h;
      if ((rc = gs_check(ynew, lo, hi))) goto fail;
      GS_PROJECT_STEP(ynew, NULL); /* the dense output below is the unprojected step's */
      if ((rc = gs_eval_rhs(wk, &tnew, ynew, p, fnew))) goto fail;
      st[2] += 1;
      for (int i = 0; i < n; ++i)
        if (!isfinite(fnew[i])) {
          rc = GS_ERR_NONFINITE;
          goto fail;
        }
      /* Dense output of this step: Q = Z^T P. */
      for (int i = 0; i < n; ++i) {
        yold[i] = y[i];
        y[i] = ynew[i];
        f[i] = fnew[i];
        for (int m = 0; m < 3; ++m)
          Q[i][m] = Z[0][i] * gs_rd_P[0][m] + Z[1][i] * gs_rd_P[1][m] + Z[2][i] * gs_rd_P[2][m];
      }
      told = t;
      hsol = h;
      have_sol = 1;
      t = tnew;
      st[7] = h;
      while (row < n_out && t_out[row] <= t) {
        double* o = out + row * n;
        if (t_out[row] == t) {
          for (int i = 0; i < n; ++i) o[i] = y[i];
        } else {
          const double x = (t_out[row] - told) / hsol;
          const double x2 = x * x, x3 = x2 * x;
          for (int i = 0; i < n; ++i) o[i] = yold[i] + Q[i][0] * x + Q[i][1] * x2 + Q[i][2] * x3;
#if GS_HAS_CON
          if (proj_mask && (rc = gs_project_state(wk, o, p, proj_mask, proj_tol, st, NULL))) {
            for (int i = 0; i < n; ++i) ynew[i] = o[i];
            goto fail;
          }
#endif
        }
        ++row;
      }
      if (t >= t_end) break;

      /* Next step size: hnew (no growth right after a rejection); keep h and the LU
       * when the change would be small and the Newton iteration converged fast;
       * re-evaluate J (at the new point) when it converged slowly. */
      if (theta_meas > 0.0 && GS_RADAU_THETA_TARGET > 0.0) {
        /* Newton-aware limit: the contraction rate grows like h^THETA_EXP; keep the
         * predicted rate of the next step near THETA_TARGET. */
        const double ratio = GS_RADAU_THETA_TARGET / theta_meas;
        const double cap = fmax(0.5, GS_RADAU_THETA_EXP == 3.0 ? cbrt(ratio) : pow(ratio, 1.0 / GS_RADAU_THETA_EXP));
        hnew = fmin(hnew, cap * h);
      }
      if (reject) hnew = fmin(hnew, h);
      reject = 0;
      first = 0;
      const double qt = hnew / h;
      if (!(theta <= GS_RADAU_THET && qt >= GS_RADAU_QUOT1 && qt <= GS_RADAU_QUOT2)) {
        h = hnew;
        lu_valid = 0;
      }
      if (theta > GS_RADAU_THET) need_jac = 1;
      caljac = 0;
    }
    continue;

  unexpected: /* Newton divergence, too many iterations, non-finite values, singular matrix */
#ifdef GS_RADAU_DEBUG
    fprintf(stderr, "t=%.6g h=%.4g UNEXPECTED theta=%.3g\n", t, h, theta);
#endif
    h *= 0.5;
  rejected:
#ifdef GS_RADAU_DEBUG
    fprintf(stderr, "t=%.6g REJECT -> h=%.4g theta=%.3g\n", t, h, theta);
#endif
    st[1] += 1;
    reject = 1;
    lu_valid = 0;
    if (!caljac) need_jac = 1;
  }

done:
  st[6] = (double)row;
  if (stats)
    for (int i = 0; i < GS_NSTATS; ++i) stats[i] = st[i];
  return n_out;

fail:
  if (t_fail) *t_fail = t;
  st[6] = (double)row;
  if (stats)
    for (int i = 0; i < GS_NSTATS; ++i) stats[i] = st[i];
  for (int i = 0; i < n; ++i) {
    out[row * n + i] = y[i];
    out[(row + 1) * n + i] =
        (rc == GS_ERR_NONFINITE || rc == GS_ERR_BOUNDS || rc == GS_ERR_PROJECT) ? ynew[i] : NAN;
  }
  return rc;
}

/* ========================================================================== */
/*  Dormand-Prince 5(4) with adaptive steps: gs_dopri5                        */
/* ========================================================================== */
/*
 * Follows E. Hairer, S. P. Norsett, G. Wanner, "Solving Ordinary Differential
 * Equations I: Nonstiff Problems", 2nd ed., Springer 1993, Sec. II.4-II.6, and their
 * DOPRI5 code: the Dormand-Prince pair (fifth-order solution, embedded fourth-order
 * error estimate, first stage of a step = last stage of the previous one), step-size
 * control with Lund stabilisation (beta = 0.04), the continuous extension of order 4 as
 * dense output (no extra evaluations), and DOPRI5's stiffness detection (Hairer &
 * Wanner, "Solving ODEs II", Sec. IV.2): h |lambda| is estimated from the last two
 * stages, both at t + h, as h |k7 - k6| / |y1 - y6|; a step whose estimate exceeds 3.25
 * (the stability boundary of the method on the negative real axis is 3.31) counts as
 * stiff, 6 non-stiff steps in a row reset the count, and 15 stiff steps stop the
 * integration.  The test runs on every nstiff-th accepted step and, once a stiff step
 * was seen, on every step.  The C code here is our own; the constants are those of the
 * reference.
 */
#ifndef GS_DOPRI_SAFE
#define GS_DOPRI_SAFE 0.9 /* safety factor of the step-size selection            */
#endif
#ifndef GS_DOPRI_FAC1
#define GS_DOPRI_FAC1 0.2 /* h_new / h >= FAC1                                    */
#endif
#ifndef GS_DOPRI_FAC2
#define GS_DOPRI_FAC2 10.0 /* h_new / h <= FAC2                                   */
#endif
#ifndef GS_DOPRI_BETA
#define GS_DOPRI_BETA 0.04 /* Lund stabilisation of the step-size controller       */
#endif
#ifndef GS_DOPRI_STIFF_HLAMBDA
#define GS_DOPRI_STIFF_HLAMBDA 3.25 /* a step is stiff when h |lambda| exceeds this   */
#endif
#ifndef GS_DOPRI_STIFF_COUNT
#define GS_DOPRI_STIFF_COUNT 15 /* this many stiff steps (no 6 non-stiff in between) stop */
#endif
#ifndef GS_DOPRI_NONSTIFF_RESET
#define GS_DOPRI_NONSTIFF_RESET 6
#endif

static const double gs_dp_c[5] = {1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0};
static const double gs_dp_a21 = 1.0 / 5.0;
static const double gs_dp_a3[2] = {3.0 / 40.0, 9.0 / 40.0};
static const double gs_dp_a4[3] = {44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0};
static const double gs_dp_a5[4] = {19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0,
                                   -212.0 / 729.0};
static const double gs_dp_a6[5] = {9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0,
                                   49.0 / 176.0, -5103.0 / 18656.0};
/* The solution (= stage 7, a72 = 0). */
static const double gs_dp_b[6] = {35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0,
                                  -2187.0 / 6784.0, 11.0 / 84.0};
/* Error estimate: fifth- minus fourth-order solution, weights of k1..k7. */
static const double gs_dp_e[7] = {71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0,
                                  -17253.0 / 339200.0, 22.0 / 525.0, -1.0 / 40.0};
/* Dense output: the fifth coefficient's weights of k1..k7. */
static const double gs_dp_d[7] = {-12715105075.0 / 11282082432.0, 0.0,
                                  87487479700.0 / 32700410799.0, -10690763975.0 / 1880347072.0,
                                  701980252875.0 / 199316789632.0, -1453857185.0 / 822651844.0,
                                  69997945.0 / 29380423.0};

/*
 * Adaptive Dormand-Prince 5(4) integration of x' = f(t, x, p), see the comment above.
 *
 * Arguments as gs_radau5, and
 *   nstiff      run the stiffness test on every nstiff-th accepted step (DOPRI5's NSTIFF,
 *               Hairer's default 1000); <= 0: never (max_steps then bounds the work)
 *   t_out       the outputs between steps come from the continuous extension of order 4
 *               (continuous; a state at a step end is the step's); with proj_mask they
 *               are projected onto the constraints, like the step ends.
 *   stats       as gs_radau5 ([3], [4], [5] stay 0), and [13] the last estimate of
 *               h |lambda|, [14] the number of stiffness tests above 3.25.
 * Error estimate: weights atol + rtol max(|x_old|, |x_new|), RMS norm (as gs_radau5);
 * rtol is raised to 100 eps if smaller.
 *
 * Returns n_out on success; on failure the rows, *t_fail and the codes of gs_radau5, and
 *   GS_ERR_STEP      (-5)  the step size fell below 10 ulp(t) (repeated error-test
 *                          failures, or a right-hand side non-finite inside the steps),
 *   GS_ERR_STIFF     (-8)  the problem is stiff: *t_fail and row r are the start of the
 *                          step on which the stiffness test fired for the 15th time.
 */
GS_EXPORT long gs_dopri5(double t0, long n_out, const double* t_out, const double* x0,
                         const double* p, double rtol, double atol, double h0, long max_steps,
                         long nstiff, const double* lo, const double* hi, const int* proj_mask,
                         double proj_tol, double* out, double* stats, double* t_fail) {
  enum { n = GS_NX };
  GS_DECLARE_WORK(wk);
  double y[n], y1[n], ys[n], ysti[n], scale[n], dense[5][n];
  double k1[n], k2[n], k3[n], k4[n], k5[n], k6[n], k7[n];
  double st[GS_NSTATS] = {0};
  long row = 0;
  int rc = 0, reject = 0, last = 0, iasti = 0, nonsti = 0;
  double t = t0, told = t0, hsol = 0.0, h, facold = 1e-4;
  const double t_end = t_out ? t_out[n_out > 0 ? n_out - 1 : 0] : t0;
  const double expo1 = 0.2 - GS_DOPRI_BETA * 0.75;

  if (n_out < 1 || !t_out || !x0 || !out || max_steps < 1 || !isfinite(t0) || !isfinite(rtol) ||
      !isfinite(atol) || !(rtol >= 0.0) || !(atol >= 0.0) || !isfinite(h0) || !(t_out[0] >= t0) ||
      !gs_proj_args_ok(proj_mask, proj_tol))
    return GS_ERR_ARGS;
  for (long k = 1; k < n_out; ++k)
    if (!(t_out[k] > t_out[k - 1]) || !isfinite(t_out[k])) return GS_ERR_ARGS;
  if (!isfinite(t_end)) return GS_ERR_ARGS;
  if (rtol < 100.0 * GS_EPS) rtol = 100.0 * GS_EPS;
  const double interval = t_end - t0;

  for (int i = 0; i < n; ++i) {
    y[i] = x0[i];
    y1[i] = NAN;
  }
  while (row < n_out && t_out[row] <= t0) {
    for (int i = 0; i < n; ++i) out[row * n + i] = y[i];
    ++row;
  }
  if (row == n_out) goto done;

  if ((rc = gs_eval_rhs(wk, &t, y, p, k1))) goto fail;
  st[GS_ST_RHS] += 1;
  for (int i = 0; i < n; ++i)
    if (!isfinite(k1[i])) {
      for (int j = 0; j < n; ++j) y1[j] = y[j];
      rc = GS_ERR_NONFINITE;
      goto fail;
    }
  if (h0 > 0.0)
    h = fmin(h0, interval);
  else if ((rc = gs_initial_step(wk, t0, y, k1, p, rtol, atol, interval, 4, 100.0, st, &h)))
    goto fail;

  while (1) { /* one attempted step per pass */
    if (st[GS_ST_STEPS] >= (double)max_steps) {
      rc = GS_ERR_MAXSTEPS;
      goto fail;
    }
    if (!(h >= 10.0 * fabs(nextafter(t, INFINITY) - t))) {
      rc = GS_ERR_STEP;
      goto fail;
    }
    if (t + 1.01 * h >= t_end) {
      h = t_end - t;
      last = 1;
    }
    /* Stages 2..7; stage 7 is the fifth-order solution y1, evaluated for the next step. */
    double ts = t + gs_dp_c[0] * h;
    for (int i = 0; i < n; ++i) ys[i] = y[i] + h * gs_dp_a21 * k1[i];
    if ((rc = gs_eval_rhs(wk, &ts, ys, p, k2))) goto fail;
    ts = t + gs_dp_c[1] * h;
    for (int i = 0; i < n; ++i) ys[i] = y[i] + h * (gs_dp_a3[0] * k1[i] + gs_dp_a3[1] * k2[i]);
    if ((rc = gs_eval_rhs(wk, &ts, ys, p, k3))) goto fail;
    ts = t + gs_dp_c[2] * h;
    for (int i = 0; i < n; ++i)
      ys[i] = y[i] + h * (gs_dp_a4[0] * k1[i] + gs_dp_a4[1] * k2[i] + gs_dp_a4[2] * k3[i]);
    if ((rc = gs_eval_rhs(wk, &ts, ys, p, k4))) goto fail;
    ts = t + gs_dp_c[3] * h;
    for (int i = 0; i < n; ++i)
      ys[i] = y[i] + h * (gs_dp_a5[0] * k1[i] + gs_dp_a5[1] * k2[i] + gs_dp_a5[2] * k3[i] +
                          gs_dp_a5[3] * k4[i]);
    if ((rc = gs_eval_rhs(wk, &ts, ys, p, k5))) goto fail;
    const double tph = last ? t_end : t + h;
    for (int i = 0; i < n; ++i)
      ysti[i] = y[i] + h * (gs_dp_a6[0] * k1[i] + gs_dp_a6[1] * k2[i] + gs_dp_a6[2] * k3[i] +
                            gs_dp_a6[3] * k4[i] + gs_dp_a6[4] * k5[i]);
    if ((rc = gs_eval_rhs(wk, &tph, ysti, p, k6))) goto fail;
    for (int i = 0; i < n; ++i)
      y1[i] = y[i] + h * (gs_dp_b[0] * k1[i] + gs_dp_b[2] * k3[i] + gs_dp_b[3] * k4[i] +
                          gs_dp_b[4] * k5[i] + gs_dp_b[5] * k6[i]);
    if ((rc = gs_eval_rhs(wk, &tph, y1, p, k7))) goto fail;
    st[GS_ST_RHS] += 6;

    /* Error estimate (ys reused) and the new step size, FAC1 <= h_new / h <= FAC2. */
    for (int i = 0; i < n; ++i) {
      ys[i] = h * (gs_dp_e[0] * k1[i] + gs_dp_e[2] * k3[i] + gs_dp_e[3] * k4[i] +
                   gs_dp_e[4] * k5[i] + gs_dp_e[5] * k6[i] + gs_dp_e[6] * k7[i]);
      scale[i] = atol + fmax(fabs(y[i]), fabs(y1[i])) * rtol;
    }
    const double err = gs_rms(ys, scale, n);
    if (!isfinite(err)) { /* a stage left the region where f is finite: shrink */
      h *= GS_DOPRI_FAC1;
      reject = 1;
      last = 0;
      st[GS_ST_REJECTED] += 1;
      continue;
    }
    const double fac11 = pow(err, expo1);
    const double fac = fmax(1.0 / GS_DOPRI_FAC2,
                            fmin(1.0 / GS_DOPRI_FAC1,
                                 fac11 / pow(facold, GS_DOPRI_BETA) / GS_DOPRI_SAFE));
    double hnew = h / fac;
    if (!(err <= 1.0)) { /* rejected */
      h /= fmin(1.0 / GS_DOPRI_FAC1, fac11 / GS_DOPRI_SAFE);
      reject = 1;
      last = 0;
      st[GS_ST_REJECTED] += 1;
      continue;
    }

    /* Accepted. */
    facold = fmax(err, 1e-4);
    st[GS_ST_STEPS] += 1;
    if (nstiff > 0 && (((long)st[GS_ST_STEPS]) % nstiff == 0 || iasti > 0)) {
      double stnum = 0.0, stden = 0.0;
      for (int i = 0; i < n; ++i) {
        stnum += (k7[i] - k6[i]) * (k7[i] - k6[i]);
        stden += (y1[i] - ysti[i]) * (y1[i] - ysti[i]);
      }
      if (stden > 0.0) st[GS_ST_HLAMBDA] = h * sqrt(stnum / stden);
      if (st[GS_ST_HLAMBDA] > GS_DOPRI_STIFF_HLAMBDA) {
        nonsti = 0;
        st[GS_ST_STIFF] += 1;
        if (++iasti == GS_DOPRI_STIFF_COUNT) {
          rc = GS_ERR_STIFF;
          goto fail;
        }
      } else if (++nonsti == GS_DOPRI_NONSTIFF_RESET) {
        iasti = 0;
      }
    }
    /* Continuous extension of the unprojected step:
     * y(t_old + s h) = d0 + s (d1 + (1-s) (d2 + s (d3 + (1-s) d4))). */
    for (int i = 0; i < n; ++i) {
      const double ydiff = y1[i] - y[i], bspl = h * k1[i] - ydiff;
      dense[0][i] = y[i];
      dense[1][i] = ydiff;
      dense[2][i] = bspl;
      dense[3][i] = ydiff - h * k7[i] - bspl;
      dense[4][i] = h * (gs_dp_d[0] * k1[i] + gs_dp_d[2] * k3[i] + gs_dp_d[3] * k4[i] +
                         gs_dp_d[4] * k5[i] + gs_dp_d[5] * k6[i] + gs_dp_d[6] * k7[i]);
    }
    if ((rc = gs_check(y1, lo, hi))) goto fail;
    {
      int changed = 0;
      GS_PROJECT_STEP(y1, &changed);
      if (changed) { /* the next step starts from f at the projected state */
        if ((rc = gs_eval_rhs(wk, &tph, y1, p, k7))) goto fail;
        st[GS_ST_RHS] += 1;
      }
    }
    for (int i = 0; i < n; ++i)
      if (!isfinite(k7[i])) {
        rc = GS_ERR_NONFINITE;
        goto fail;
      }
    told = t;
    hsol = h;
    t = tph;
    st[GS_ST_HLAST] = h;
    for (int i = 0; i < n; ++i) {
      y[i] = y1[i];
      k1[i] = k7[i];
    }
    while (row < n_out && t_out[row] <= t) {
      double* o = out + row * n;
      if (t_out[row] == t) {
        for (int i = 0; i < n; ++i) o[i] = y[i];
      } else {
        const double s = (t_out[row] - told) / hsol, s1 = 1.0 - s;
        for (int i = 0; i < n; ++i)
          o[i] = dense[0][i] +
                 s * (dense[1][i] + s1 * (dense[2][i] + s * (dense[3][i] + s1 * dense[4][i])));
#if GS_HAS_CON
        if (proj_mask && (rc = gs_project_state(wk, o, p, proj_mask, proj_tol, st, NULL))) {
          for (int i = 0; i < n; ++i) y1[i] = o[i];
          goto fail;
        }
#endif
      }
      ++row;
    }
    if (last) break;
    hnew = fmin(hnew, interval);
    if (reject) hnew = fmin(hnew, h);
    reject = 0;
    h = hnew;
  }

done:
  st[GS_ST_ROWS] = (double)row;
  if (stats)
    for (int i = 0; i < GS_NSTATS; ++i) stats[i] = st[i];
  return n_out;

fail:
  if (t_fail) *t_fail = t;
  st[GS_ST_ROWS] = (double)row;
  if (stats)
    for (int i = 0; i < GS_NSTATS; ++i) stats[i] = st[i];
  for (int i = 0; i < n; ++i) {
    out[row * n + i] = y[i];
    out[(row + 1) * n + i] =
        (rc == GS_ERR_NONFINITE || rc == GS_ERR_BOUNDS || rc == GS_ERR_PROJECT) ? y1[i] : NAN;
  }
  return rc;
}

/* Evaluate gs_rhs n times in a C loop; returns wall-clock nanoseconds per call. */
GS_EXPORT double gs_rhs_loop_ns(long n, const double* x, const double* p) {
  double xdot[GS_NX];
  volatile double sink = 0.0;
  struct timespec a, b;
  if (n <= 0) return 0.0;
  clock_gettime(CLOCK_MONOTONIC, &a);
  for (long k = 0; k < n; ++k) {
    gs_rhs(x, p, xdot);
    sink += xdot[k % GS_NX];
  }
  clock_gettime(CLOCK_MONOTONIC, &b);
  (void)sink;
  return ((double)(b.tv_sec - a.tv_sec) * 1e9 + (double)(b.tv_nsec - a.tv_nsec)) / (double)n;
}
