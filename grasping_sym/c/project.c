/*
 * grasping_sym driver: projection of a state onto the model's constraints (gs_project),
 * and gs_project_state, the same projection used by the integrators after every accepted
 * step (see GS_PROJECT_STEP in gs_internal.h).  Needs constraints: gs_project
 * refuses a model without them (gs_con_info, in driver.c, reports none).
 */
#include "gs_internal.h"

#ifndef GS_PROJ_MAXIT
#define GS_PROJ_MAXIT 8 /* Gauss-Newton iterations on the positions */
#endif

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
  const int m = gs_nc;
  double A[m * m], y[m];
  for (int a = 0; a < m; ++a) {
    y[a] = r[a];
    for (int b = 0; b <= a; ++b) {
      double s = 0.0;
      for (int i = 0; i < gs_nx; ++i)
        if (mask[i] == which) s += J[i * m + a] * J[i * m + b];
      A[a * m + b] = A[b * m + a] = s;
    }
  }
  if (gs_solve_small(m, A, y)) return 1;
  for (int i = 0; i < gs_nx; ++i)
    if (mask[i] == which) {
      double d = 0.0;
      for (int a = 0; a < m; ++a) d += J[i * m + a] * y[a];
      x[i] -= d;
    }
  return 0;
}


/* Project x in place onto C(x) = 0 and then Cdot(x) = 0 (see gs_project); counts into st.
 * *changed (may be NULL) is set to 1 when x was modified. */
GS_HIDDEN int gs_project_state(gs_work* wk, double* x, const double* p, const int* mask,
                               double tol, double* st, int* changed) {
  double C[gs_nc], JC[gs_nc * gs_nx], Cd[gs_nc], JCd[gs_nc * gs_nx];
  int rc;
  if (changed) *changed = 0;
  for (int it = 0;; ++it) { /* positions: Gauss-Newton on C(x) = 0 */
    if ((rc = gs_eval_con(wk, x, p, C, JC, Cd, JCd))) return rc;
    st[GS_ST_CON_EVALS] += 1;
    const double r = gs_max_abs(C, gs_nc);
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
  const double r = gs_max_abs(Cd, gs_nc);
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
  if (!gs_has_con || !x || !mask || !(tol > 0.0)) return GS_ERR_ARGS;
  const int rc = gs_project_state(wk, x, p, mask, tol, st, NULL);
  if (stats)
    for (int i = 0; i < GS_NSTATS; ++i) stats[i] = st[i];
  return rc;
}
