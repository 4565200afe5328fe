/* grasping_sym driver: fixed-step classic Runge-Kutta, gs_rk4. */
#include "gs_internal.h"

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
 *                          without constraints or with proj_tol <= 0 (nothing written),
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
  double x[gs_nx], xn[gs_nx], xs[gs_nx], k1[gs_nx], k2[gs_nx], k3[gs_nx], k4[gs_nx];
  double ts;
  double st[GS_NSTATS] = {0};
  long row = 1;
  int rc = 0;

  if (!isfinite(h) || !isfinite(t0) || nsteps < 0 || stride < 1 ||
      !gs_proj_args_ok(proj_mask, proj_tol))
    return GS_ERR_ARGS;
  proj_tol = fabs(proj_tol); /* its rows are its steps' states */
  gs_stop_reset();
  for (int i = 0; i < gs_nx; ++i) {
    x[i] = out[i] = x0[i];
    xn[i] = NAN; /* reported as the rejected state if the very first evaluation fails */
  }

  for (long k = 0; k < nsteps; ++k) {
    const double t = t0 + (double)k * h;
    if (gs_stop_requested()) {
      rc = GS_ERR_INTERRUPT;
      goto fail;
    }
    if ((rc = gs_eval_rhs(wk, &t, x, p, k1))) goto fail;
    for (int i = 0; i < gs_nx; ++i) xs[i] = x[i] + 0.5 * h * k1[i];
    ts = t + 0.5 * h;
    if ((rc = gs_eval_rhs(wk, &ts, xs, p, k2))) goto fail;
    for (int i = 0; i < gs_nx; ++i) xs[i] = x[i] + 0.5 * h * k2[i];
    if ((rc = gs_eval_rhs(wk, &ts, xs, p, k3))) goto fail;
    for (int i = 0; i < gs_nx; ++i) xs[i] = x[i] + h * k3[i];
    ts = t + h;
    if ((rc = gs_eval_rhs(wk, &ts, xs, p, k4))) goto fail;
    for (int i = 0; i < gs_nx; ++i)
      xn[i] = x[i] + (h / 6.0) * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
    st[GS_ST_RHS] += 4;
    if ((rc = gs_check(xn, lo, hi))) goto fail;
    GS_PROJECT_STEP(xn, NULL);
    st[GS_ST_STEPS] += 1;
    for (int i = 0; i < gs_nx; ++i) x[i] = xn[i];
    if ((k + 1) % stride == 0) {
      for (int i = 0; i < gs_nx; ++i) out[row * gs_nx + i] = x[i];
      ++row;
    }
    continue;
  fail:
    if (t_fail) *t_fail = t;
    {
      double* r = out + (k / stride + 1) * gs_nx;
      for (int i = 0; i < gs_nx; ++i) {
        r[i] = x[i];
        r[gs_nx + i] = xn[i];
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
