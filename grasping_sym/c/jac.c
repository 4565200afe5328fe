/* grasping_sym driver: the Jacobian d f / d x used by gs_radau5 (radau5.c), compiled
 * (GS_HAS_JAC) or by forward differences. */
#include "gs_internal.h"

#if GS_HAS_JAC
/* J (dense row-major, nx x nx) = block GS_JAC_BLOCK of the generated Jacobian.
 * Only the structural non-zeros are written: J must be zeroed once beforehand. */
GS_HIDDEN int gs_eval_jac(gs_work* wk, const double* t, const double* x, const double* p,
                          double* J) {
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
#else
/* Forward-difference Jacobian (fallback when no Jacobian was compiled in). */
GS_HIDDEN int gs_fd_jac(gs_work* wk, const double* t, const double* x, const double* p,
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
