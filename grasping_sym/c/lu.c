/* grasping_sym driver: dense LU factorisations (real and complex) with partial pivoting
 * of n x n matrices, for the Newton iteration of gs_radau5 (radau5.c). */
#include "gs_internal.h"

/* The sizes n <= 8 (GS_LU_CASES) take copies of the routines compiled for that n (a switch
 * on n): the real routines' loops are then unrolled, and the real factorisation runs in 43 ns
 * instead of 65 and a solve in 20 instead of 44 (n = 7, gcc 12, x86-64-v3); the complex ones
 * gain from the constant size alone (paper2d's reduced systems, 4 rows: 2.6 % faster runs).
 * The arithmetic and its order are those of the loops for any n, so are the results.
 * (Unrolling the complex routines or the solve's pivot loop measured no faster; unrolling
 * up to n = 16 cost gcc 0.5 s for this file, and a planar model with a generated Jacobian
 * solves its reduced systems, radau5.c, instead of the full ones.) */
#define GS_LU_NAME(f) f
#define GS_UNROLL
#include "lu_real.h"
#undef GS_LU_NAME
#undef GS_UNROLL
#define GS_LU_NAME(f) f##_unrolled
#if defined(__GNUC__) && !defined(__clang__)
#define GS_UNROLL _Pragma("GCC unroll 16")
#else
#define GS_UNROLL
#endif
#include "lu_real.h"

/* LU with partial pivoting of the complex row-major n x n matrix (Ar + i Ai), in
 * place.  Complex arithmetic is written out in real and imaginary parts: C99
 * complex multiplication and division go through the slow, NaN-careful
 * __muldc3 / __divdc3 unless compiled with -fcx-limited-range. */
static inline int lu_complex(double* Ar, double* Ai, int* piv, const int n) {
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

static inline void lu_solve_complex(const double* Ar, const double* Ai, const int* piv,
                                    double* br, double* bi, const int n) {
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

/* The routines for a size n given at run time (gs_radau5's full system, n = nx, or its
 * system reduced by the second-order rows, radau5.c), on matrices of row stride n. */
#define GS_LU_CASES(CASE) CASE(1) CASE(2) CASE(3) CASE(4) CASE(5) CASE(6) CASE(7) CASE(8)
GS_HIDDEN int gs_lu_real_n(double* A, int* piv, int n) {
  switch (n) {
#define GS_CASE(k) case k: return lu_real_unrolled(A, piv, k);
    GS_LU_CASES(GS_CASE)
#undef GS_CASE
    default: return lu_real(A, piv, n);
  }
}
GS_HIDDEN void gs_lu_solve_real_n(const double* LU, const int* piv, double* b, int n) {
  switch (n) {
#define GS_CASE(k) case k: lu_solve_real_unrolled(LU, piv, b, k); return;
    GS_LU_CASES(GS_CASE)
#undef GS_CASE
    default: lu_solve_real(LU, piv, b, n);
  }
}
GS_HIDDEN int gs_lu_complex_n(double* Ar, double* Ai, int* piv, int n) {
  switch (n) {
#define GS_CASE(k) case k: return lu_complex(Ar, Ai, piv, k);
    GS_LU_CASES(GS_CASE)
#undef GS_CASE
    default: return lu_complex(Ar, Ai, piv, n);
  }
}
GS_HIDDEN void gs_lu_solve_complex_n(const double* Ar, const double* Ai, const int* piv,
                                     double* br, double* bi, int n) {
  switch (n) {
#define GS_CASE(k) case k: lu_solve_complex(Ar, Ai, piv, br, bi, k); return;
    GS_LU_CASES(GS_CASE)
#undef GS_CASE
    default: lu_solve_complex(Ar, Ai, piv, br, bi, n);
  }
}
