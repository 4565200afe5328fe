/* grasping_sym driver: the Jacobian d f / d x used by gs_radau5 (radau5.c), compiled
 * (gs_has_jac) or by forward differences. */
#include "gs_internal.h"

/* J (dense row-major, nx x nx) = block gs_jac_block of the generated Jacobian, its values
 * first written to val (nx x nx doubles of scratch, the caller's).
 * Only the structural non-zeros are written: J must be zeroed once beforehand. */
GS_HIDDEN int gs_eval_jac(gs_work* wk, const double* t, const double* x, const double* p,
                          double* J, double* val) {
  const int n = gs_nx;
  const GS_CASADI_INT* sp = gs_model_jac_sparsity_out(gs_jac_block);
  for (int i = 0; i < gs_jac_nin; ++i) wk->arg[i] = NULL;
  for (int i = 0; i < gs_jac_nout; ++i) wk->res[i] = NULL;
  wk->arg[0] = t;
  wk->arg[1] = x;
  wk->arg[3] = p;
  wk->res[gs_jac_block] = val;
  if (gs_model_jac(wk->arg, wk->res, wk->iw, wk->w, 0)) return GS_ERR_EVAL;
  if (!sp || sp[0] != n || sp[1] != n) return GS_ERR_ARGS;
  if (sp[2] == 1) { /* CasADi's compressed form of a dense pattern: [nrow, ncol, 1] */
    for (int c = 0; c < n; ++c)
      for (int r = 0; r < n; ++r) J[r * n + c] = val[c * n + r];
  } else {
    const GS_CASADI_INT* colind = sp + 2;
    const GS_CASADI_INT* row = sp + 2 + n + 1;
    for (int c = 0; c < n; ++c)
      for (GS_CASADI_INT k = colind[c]; k < colind[c + 1]; ++k) J[row[k] * n + c] = val[k];
  }
  return 0;
}

/* Forward-difference Jacobian (when the model has no compiled Jacobian). */
GS_HIDDEN int gs_fd_jac(gs_work* wk, const double* t, const double* x, const double* p,
                        const double* f, double atol, double* J) {
  const int n = gs_nx;
  double xp[n], fp[n];
  for (int i = 0; i < n; ++i) xp[i] = x[i];
  for (int j = 0; j < n; ++j) {
    double d = sqrt(GS_EPS) * fmax(fabs(x[j]), fmax(atol, 1e-8) * 1e3);
    xp[j] = x[j] + d;
    d = xp[j] - x[j];
    int rc = gs_eval_rhs(wk, t, xp, p, fp);
    xp[j] = x[j];
    if (rc) return rc;
    for (int i = 0; i < n; ++i) J[i * n + j] = (fp[i] - f[i]) / d;
  }
  return 0;
}
