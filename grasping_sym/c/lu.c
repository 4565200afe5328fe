/* grasping_sym driver: dense LU factorisations (real and complex) with partial pivoting
 * of n x n matrices, n = GS_NX, for the Newton iteration of gs_radau5 (radau5.c). */
#include "gs_internal.h"

#include "lu_core.h"

/* The routines for n = GS_NX (inlined with the size known: the loops unroll, see
 * lu_core.h); radau5.c inlines the same for its reduced systems. */
GS_HIDDEN int gs_lu_real(double* A, int* piv) { return lu_real(A, piv, GS_NX); }
GS_HIDDEN void gs_lu_solve_real(const double* LU, const int* piv, double* b) {
  lu_solve_real(LU, piv, b, GS_NX);
}
GS_HIDDEN int gs_lu_complex(double* Ar, double* Ai, int* piv) {
  return lu_complex(Ar, Ai, piv, GS_NX);
}
GS_HIDDEN void gs_lu_solve_complex(const double* Ar, const double* Ai, const int* piv,
                                   double* br, double* bi) {
  lu_solve_complex(Ar, Ai, piv, br, bi, GS_NX);
}
