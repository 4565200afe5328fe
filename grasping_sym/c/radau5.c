/* grasping_sym driver: adaptive Radau IIA of order 5, gs_radau5.  Its coefficients and
 * tuning defaults are in radau5.h, its Jacobian in jac.c, its LU factorisations in lu.c. */
#include "gs_internal.h"
#include "radau5.h"
#include <stdlib.h>
#ifdef GS_RADAU_DEBUG
#include <stdio.h>
#endif

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

/* The collocation polynomial of the step just accepted (Q row-major, n x 3). */
typedef struct {
  const double *yold, *Q;
  double told, hsol;
} gs_radau_dense;

static void gs_radau_interp(const void* ctx, double t, double* x) {
  const gs_radau_dense* d = (const gs_radau_dense*)ctx;
  const double s = (t - d->told) / d->hsol, s2 = s * s, s3 = s2 * s;
  for (int i = 0; i < gs_nx; ++i)
    x[i] = d->yold[i] + d->Q[3 * i] * s + d->Q[3 * i + 1] * s2 + d->Q[3 * i + 2] * s3;
}

/* Work storage of gs_radau5: four n x n matrices (row-major) and two pivot vectors, in one
 * block sized at run time (gs_radau5: on the stack when small, else on the heap). */
typedef struct {
  double* J;         /* d f / d x                                               */
  double* LUr;       /* LU of mu_real/h I - J                                   */
  double* LUcr;      /* LU of mu_complex/h I - J, */
  double* LUci;      /* real and imaginary parts  */
  int *pr, *pc;      /* row pivots                                              */
} gs_radau_mats;

/*
 * Second-order rows (Hairer's RADAU5, IWORK(9) = M1 = IWORK(10) = M2, H&W IV.8): when the
 * first m rows of J are x_i' = x_{i+m} exactly (a mechanical system's positions and speeds,
 * J[i][j] = 1 at j = i + m and 0 elsewhere), the first m unknowns of (mu I - J) z = r are
 * z_i = (r_i + z_{i+m}) / mu, and the others solve the (n - m) x (n - m) system
 *   (mu I - J22 - J21' / mu) z2 = r2 + J21 r1 / mu,
 * J21' being J21 (the rows below m, the columns before m) moved to the speeds' columns.  The
 * same solution as the full system's, with LU factors of n - m rows instead of n (paper2d:
 * 4 instead of 7).  gs_radau5 reads m off every Jacobian it evaluates (0: none, the full
 * system; a finite-difference Jacobian is not exactly identity there).
 */
static int gs_second_order_rows(const double* J, const int n) {
  for (int m = n / 2; m > 0; --m) {
    int ok = 1;
    for (int i = 0; i < m && ok; ++i)
      for (int j = 0; j < n && ok; ++j) ok = J[i * n + j] == (j == i + m ? 1.0 : 0.0);
    if (ok) return m;
  }
  return 0;
}

/* The reduced matrices (row stride n - m) of mr I - J and (mcr + i mci) I - J, factored. */
static int gs_radau_reduced_lu(gs_radau_mats* M, const int n, int m, double mr, double mcr,
                               double mci) {
  const int k = n - m;
  const double d = 1.0 / (mcr * mcr + mci * mci), ir = mcr * d, ii = -mci * d; /* 1 / mu */
  for (int a = 0; a < k; ++a)
    for (int b = 0; b < k; ++b) {
      const double jab = M->J[(m + a) * n + m + b], jq = b < m ? M->J[(m + a) * n + b] : 0.0;
      M->LUr[a * k + b] = (a == b ? mr : 0.0) - jab - jq / mr;
      M->LUcr[a * k + b] = (a == b ? mcr : 0.0) - jab - jq * ir;
      M->LUci[a * k + b] = (a == b ? mci : 0.0) - jq * ii;
    }
  return gs_lu_real_n(M->LUr, M->pr, k) || gs_lu_complex_n(M->LUcr, M->LUci, M->pc, k);
}

/* (mr I - J)^-1 b in place: the full LU (m = 0) or the reduced one. */
static inline void gs_radau_solve_real(const gs_radau_mats* M, const int n, int m, double mr,
                                       double* b) {
  if (!m) {
    gs_lu_solve_real_n(M->LUr, M->pr, b, n);
    return;
  }
  const double inv = 1.0 / mr;
  for (int a = m; a < n; ++a) {
    double s = 0.0;
    for (int j = 0; j < m; ++j) s += M->J[a * n + j] * b[j];
    b[a] += s * inv;
  }
  gs_lu_solve_real_n(M->LUr, M->pr, b + m, n - m);
  for (int i = 0; i < m; ++i) b[i] = (b[i] + b[i + m]) * inv;
}

/* ((mcr + i mci) I - J)^-1 (br + i bi) in place. */
static inline void gs_radau_solve_complex(const gs_radau_mats* M, const int n, int m, double mcr,
                                          double mci, double* br, double* bi) {
  if (!m) {
    gs_lu_solve_complex_n(M->LUcr, M->LUci, M->pc, br, bi, n);
    return;
  }
  const double d = 1.0 / (mcr * mcr + mci * mci), ir = mcr * d, ii = -mci * d;
  for (int a = m; a < n; ++a) {
    double sr = 0.0, si = 0.0;
    for (int j = 0; j < m; ++j) {
      sr += M->J[a * n + j] * br[j];
      si += M->J[a * n + j] * bi[j];
    }
    br[a] += sr * ir - si * ii;
    bi[a] += sr * ii + si * ir;
  }
  gs_lu_solve_complex_n(M->LUcr, M->LUci, M->pc, br + m, bi + m, n - m);
  for (int i = 0; i < m; ++i) {
    const double xr = br[i] + br[i + m], xi = bi[i] + bi[i + m];
    br[i] = xr * ir - xi * ii;
    bi[i] = xr * ii + xi * ir;
  }
}

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
 *   t0          initial time; x0[nx] the initial state, checked like every step's end
 *               (finite, inside [lo, hi]: else GS_ERR_NONFINITE / GS_ERR_BOUNDS, no row written)
 *   n_out,t_out output times, strictly increasing, t_out[0] >= t0 (t_out[0] == t0 allowed);
 *               the integration ends at t_out[n_out - 1] exactly (never steps beyond it);
 *               states between steps come from the collocation polynomial (order 3
 *               accurate in the step, continuous), a state at a step end is the step's.
 *   p           parameters (may be NULL when np == 0)
 *   rtol, atol  scalar tolerances, local error measured with atol + rtol |x| (RMS norm);
 *               rtol is raised to 100 eps if smaller.
 *   h0          first step; <= 0 selects it automatically (Hairer-Norsett-Wanner I, II.4,
 *               as scipy's select_initial_step with the error order 3, without its cap at
 *               100 explicit-Euler probes: see gs_initial_step)
 *   max_steps   maximum number of accepted steps (>= 1)
 *   lo, hi      bounds checked on every accepted step's end state (may be NULL)
 *   proj_mask, proj_tol
 *               NULL, or project every accepted step's end state and (proj_tol > 0)
 *               every output between steps onto the constraints, to |proj_tol| (see
 *               gs_project and gs_proj_args_ok; needs constraints)
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
static long gs_radau5_run(gs_radau_mats* M, double t0, long n_out, const double* t_out,
                          const double* x0, const double* p, double rtol, double atol, double h0,
                          long max_steps, const double* lo, const double* hi,
                          const int* proj_mask, double proj_tol, double* out, double* stats,
                          double* t_fail) {
  const int n = gs_nx;
  enum { nit = GS_RADAU_NIT };
  GS_DECLARE_WORK(wk);
  double y[n], f[n], ynew[n], fnew[n], scale[n], tmp[n], err[n], ze[n];
  double Z[3][n], W[3][n], F[3][n], dW[3][n], Q[n][3], yold[n];
  double st[GS_NSTATS] = {0};
  long row = 0;
  int rc = 0, have_sol = 0, lu_valid = 0, caljac = 0, need_jac = 1, reject = 0, first = 1;
  int nsing = 0, m2 = 0; /* m2: the Jacobian's second-order rows (0: none) */
  double t = t0, told = t0, hsol = 0.0, h;
  double faccon = 1.0, theta = GS_RADAU_THET, theta_meas = 0.0, hacc = 0.0, erracc = 0.0;
  const double t_end = t_out ? t_out[n_out > 0 ? n_out - 1 : 0] : t0;
  const double cfac = GS_RADAU_SAFE * (1 + 2 * nit);
  double fnewt;

  if (!gs_adaptive_args_ok(t0, n_out, t_out, x0, out, max_steps, rtol, atol, h0, proj_mask,
                           proj_tol))
    return GS_ERR_ARGS;
  const int proj_rows = proj_mask && proj_tol > 0.0; /* gs_proj_args_ok */
  proj_tol = fabs(proj_tol);
  gs_stop_reset();
  p = gs_wrap_params(p); /* a chart that changes in the loop is written there (wrap.c) */
  if (rtol < 100.0 * GS_EPS) rtol = 100.0 * GS_EPS;
  fnewt = fmax(GS_RADAU_FNEWT, GS_RADAU_NEWTON_FLOOR * GS_EPS / rtol);

  for (int i = 0; i < n; ++i) yold[i] = Q[i][0] = Q[i][1] = Q[i][2] = 0.0;
  if ((rc = gs_adaptive_begin(t0, n_out, t_out, x0, lo, hi, y, ynew, out, &row))) goto fail;
  if (row == n_out) goto done;
  if (gs_watching() && (rc = gs_watch_begin(wk, t0, y, p, t_out[n_out - 1]))) goto fail;

  if ((rc = gs_start_rhs(wk, t, y, p, f, st, ynew))) goto fail;

  /* Initial step (scipy's select_initial_step with error order 3, no probe cap). */
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
    if (gs_stop_requested()) {
      rc = GS_ERR_INTERRUPT;
      goto fail;
    }
    /* The last step: shortened to end at t_end, or stretched by at most 1 % so that no
     * sliver of a step is left; never stretched right after a rejection (the rejected size
     * would come back, and a sliver that fails would be retried forever); a remainder of
     * under 10 ulp (too short to be a step) is always taken in. */
    if (t + h >= t_end || t_end - (t + h) < 10.0 * (nextafter(t_end, INFINITY) - t_end) ||
        (!reject && t + 1.01 * h >= t_end)) {
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
      /* gs_watch_refine's trials: the differenced Jacobian at their common start, once */
      const int kept = !gs_has_jac && yj == y && gs_refine_jac_get(t, y, M->J);
      if (!kept) {
        if (gs_has_jac) {
          if ((rc = gs_eval_jac(wk, &tj, yj, p, M->J, M->LUr))) goto fail; /* LUr: scratch */
        } else if (yj != y) {
          if ((rc = gs_eval_rhs(wk, &tj, yj, p, fnew))) goto fail;
          st[2] += 1;
          if ((rc = gs_fd_jac(wk, &tj, yj, p, fnew, atol, M->J))) goto fail;
        } else if ((rc = gs_fd_jac(wk, &t, y, p, f, atol, M->J))) {
          goto fail;
        }
        if (!gs_has_jac) {
          st[2] += n;
          if (yj == y) gs_refine_jac_put(t, y, M->J);
        }
        st[3] += 1;
      }
      m2 = gs_second_order_rows(M->J, n);
      st[GS_ST_REDUCED] = m2;
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
    if (!lu_valid && m2) {
      st[4] += 2;
      if (gs_radau_reduced_lu(M, n, m2, mr, mcr, mci)) {
        if (++nsing >= 5) {
          rc = GS_ERR_STEP;
          goto fail;
        }
        goto unexpected; /* singular: halve h */
      }
      lu_valid = 1;
    }
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
      if (gs_lu_real_n(M->LUr, M->pr, n) || gs_lu_complex_n(M->LUcr, M->LUci, M->pc, n)) {
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
        {
          double ts[3], ys[3][n];
          for (int s = 0; s < 3; ++s) {
            ts[s] = t + h * gs_rd_C[s];
            for (int i = 0; i < n; ++i) ys[s][i] = y[i] + Z[s][i];
          }
          const double* yp[3] = {ys[0], ys[1], ys[2]};
          double* fp[3] = {F[0], F[1], F[2]};
          if ((rc = gs_eval_rhs3(wk, ts, yp, p, fp))) goto fail;
        }
        for (int s = 0; s < 3; ++s)
          for (int i = 0; i < n; ++i) finite &= isfinite(F[s][i]);
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
        gs_radau_solve_real(M, n, m2, mr, dW[0]);
        gs_radau_solve_complex(M, n, m2, mcr, mci, dW[1], dW[2]);
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
          gs_radau_solve_real(M, n, m2, mr, err);
          for (int i = 0; i < n; ++i) scale[i] = atol + fmax(fabs(y[i]), fabs(ynew[i])) * rtol;
          double err_norm = gs_rms(err, scale, n);
          if (!(err_norm < 1.0) && (first || reject)) {
            for (int i = 0; i < n; ++i) tmp[i] = y[i] + err[i];
            if ((rc = gs_eval_rhs(wk, &t, tmp, p, fnew))) goto fail;
            st[2] += 1;
            for (int i = 0; i < n; ++i) err[i] = fnew[i] + ze[i];
            gs_radau_solve_real(M, n, m2, mr, err);
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
          if (st[0] >= 1.0 && hacc > 0.0) { /* (none yet since the loop's start or a change) */
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
      if ((rc = gs_check(ynew, lo, hi))) {
        const int w = rc == GS_ERR_BOUNDS ? gs_wrap_step(wk, t, y, ynew, p, lo, hi, NULL, 0) : 0;
        if (!w) goto fail;
        rc = 0; /* 1: a contact's coordinate a period round (wrap.c): Z, Q are differences */
        if (w == 2) { /* a chart's change: y mapped at t; the step not taken, the loop anew */
          st[0] -= 1;
          st[1] += 1;
          if ((rc = gs_start_rhs(wk, t, y, p, f, st, ynew))) goto fail;
          have_sol = 0;
          need_jac = 1;
          lu_valid = 0;
          caljac = 0;
          reject = 0;
          first = 1; /* the loop's start again: no step, Newton rate or error accepted yet */
          faccon = 1.0;
          hacc = 0.0;
          /* a first step chosen anew: the coordinates' rates differ in the new chart (the step
           * kept from the old one was rejected at every change of the lap benchmark's) */
          if ((rc = gs_initial_step(wk, t, y, f, p, rtol, atol, t_end - t, 3, 0.0, st, &h))) goto fail;
          continue;
        }
      }
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
      int event = 0;
      double t_ev = t;
      if (gs_watching()) {
        const gs_radau_dense dense = {yold, &Q[0][0], told, hsol};
        event = gs_watch_step(wk, told, t, y, p, gs_radau_interp, &dense, &t_ev, tmp);
        if (event < 0) {
          rc = event;
          goto fail;
        }
        while (event == 2 && row > 0 && t_out[row - 1] >= t_ev) --row; /* an earlier step's */
      }
      while (row < n_out && (event ? t_out[row] < t_ev : t_out[row] <= t)) {
        double* o = out + row * n;
        if (t_out[row] == t) {
          for (int i = 0; i < n; ++i) o[i] = y[i];
        } else {
          const double x = (t_out[row] - told) / hsol;
          const double x2 = x * x, x3 = x2 * x;
          for (int i = 0; i < n; ++i) o[i] = yold[i] + Q[i][0] * x + Q[i][1] * x2 + Q[i][2] * x3;
          if (proj_rows && (rc = gs_project_state(wk, o, p, proj_mask, proj_tol, st, NULL))) {
            for (int i = 0; i < n; ++i) ynew[i] = o[i];
            goto fail;
          }
        }
        ++row;
      }
      if (event) { /* stop at the event: its state, and its step's start (gs_adaptive_end) */
        if (!gs_has_jac) gs_watch_offer_jac(M->J);
        for (int i = 0; i < n; ++i) {
          y[i] = tmp[i];
          ynew[i] = yold[i];
        }
        if (event == 2) gs_watch_event_start(ynew);
        t = t_ev;
        rc = GS_EVENT;
        goto fail;
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
  return gs_adaptive_end(n_out, row, t, st, stats, t_fail, out, y, ynew);

fail:
  rc = gs_watch_failed(wk, rc, p, t_out, &row, &t, y, ynew); /* an event left unwatched first */
  return gs_adaptive_end(rc, row, t, st, stats, t_fail, out, y, ynew);
}

/* gs_radau5's matrices: on the stack up to GS_WORK_ON_STACK_MAX bytes, on the heap above
 * (n > 90 with the default): no size is too large but for the memory. */
GS_EXPORT long gs_radau5(double t0, long n_out, const double* t_out, const double* x0,
                         const double* p, double rtol, double atol, double h0, long max_steps,
                         const double* lo, const double* hi, const int* proj_mask,
                         double proj_tol, double* out, double* stats, double* t_fail) {
  const size_t n = (size_t)gs_nx, doubles = 4 * n * n;
  const int small = doubles * sizeof(double) <= (size_t)GS_WORK_ON_STACK_MAX;
  double on_stack[small ? doubles : 1];
  int piv[2 * n];
  double* block = small ? on_stack : malloc(doubles * sizeof(double));
  if (!block) return GS_ERR_ARGS; /* out of memory: nothing written */
  gs_radau_mats M = {block, block + n * n, block + 2 * n * n, block + 3 * n * n, piv, piv + n};
  const long rc = gs_radau5_run(&M, t0, n_out, t_out, x0, p, rtol, atol, h0, max_steps, lo, hi,
                                proj_mask, proj_tol, out, stats, t_fail);
  if (!small) free(block);
  return rc;
}
