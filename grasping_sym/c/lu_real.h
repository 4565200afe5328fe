/*
 * gs_radau5's real LU routines (lu.c, the only file including this header, twice): lu.c
 * defines GS_LU_NAME(f) (the routines' names) and GS_UNROLL (a loop pragma or nothing)
 * before each inclusion, so that the routines exist with their loops as written (any n) and
 * unrolled (for the small sizes lu.c dispatches to, n a constant there).
 */
/* LU with partial pivoting of the row-major n x n matrix A (in place).
 * Returns 0, or 1 if a pivot is exactly zero (singular). */
static inline int GS_LU_NAME(lu_real)(double* A, int* piv, const int n) {
  GS_UNROLL for (int k = 0; k < n; ++k) {
    int m = k;
    double amax = fabs(A[k * n + k]);
    GS_UNROLL for (int i = k + 1; i < n; ++i)
      if (fabs(A[i * n + k]) > amax) amax = fabs(A[i * n + k]), m = i;
    piv[k] = m;
    if (amax == 0.0) return 1;
    if (m != k)
      GS_UNROLL for (int j = 0; j < n; ++j) {
        double tmp = A[k * n + j];
        A[k * n + j] = A[m * n + j];
        A[m * n + j] = tmp;
      }
    const double inv = 1.0 / A[k * n + k];
    GS_UNROLL for (int i = k + 1; i < n; ++i) {
      const double l = (A[i * n + k] *= inv);
      if (l != 0.0)
        GS_UNROLL for (int j = k + 1; j < n; ++j) A[i * n + j] -= l * A[k * n + j];
    }
  }
  return 0;
}

static inline void GS_LU_NAME(lu_solve_real)(const double* LU, const int* piv, double* b, const int n) {
  for (int k = 0; k < n; ++k) {
    const int pk = piv[k];
    if (pk > k && pk < n) {
      double tmp = b[k];
      b[k] = b[pk];
      b[pk] = tmp;
    }
  }
  GS_UNROLL for (int i = 1; i < n; ++i) {
    double s = b[i];
    GS_UNROLL for (int j = 0; j < i; ++j) s -= LU[i * n + j] * b[j];
    b[i] = s;
  }
  GS_UNROLL for (int i = n - 1; i >= 0; --i) {
    double s = b[i];
    GS_UNROLL for (int j = i + 1; j < n; ++j) s -= LU[i * n + j] * b[j];
    b[i] = s / LU[i * n + i];
  }
}
