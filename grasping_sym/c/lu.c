/* grasping_sym driver: dense LU factorisations (real and complex) with partial pivoting
 * of n x n matrices, n = GS_NX, for the Newton iteration of gs_radau5 (radau5.c). */
#include "gs_internal.h"

/* n = GS_NX is a compile-time constant (7 for paper2d): for n <= 8 the real routines'
 * loops are unrolled, and the real factorisation runs in 43 ns instead of 65 and a solve in
 * 20 instead of 44 (gcc 12, x86-64-v3); the arithmetic and its order are unchanged, so are
 * the results.  (Unrolling the complex routines or the solve's pivot loop measured no
 * faster.)  Up to n = 16 they used to be unrolled too; but gcc then takes 0.5 s for this
 * file at n = 14 (0.16 s without), in the background of a first build, and a planar model
 * with a generated Jacobian solves its reduced systems (radau5.c) instead of these. */
#if defined(__GNUC__) && !defined(__clang__) && GS_NX <= 8
#define GS_UNROLL _Pragma("GCC unroll 16")
#else
#define GS_UNROLL
#endif

/* LU with partial pivoting of the row-major n x n matrix A (in place).
 * Returns 0, or 1 if a pivot is exactly zero (singular). */
static inline int lu_real(double* A, int* piv, const int n) {
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

static inline void lu_solve_real(const double* LU, const int* piv, double* b, const int n) {
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

/* The routines for n = GS_NX (inlined with the size known: the loops unroll as above), and
 * for a smaller size n <= GS_NX given at run time (gs_radau5's system reduced by its
 * second-order rows, radau5.c), on matrices stored with row stride n. */
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
/* GS_RADAU_M (codegen.library.second_order_rows): the second-order rows the model's Jacobian
 * has by its structure, so that the reduced size GS_NR = GS_NX - GS_RADAU_M is compiled as a
 * constant too when it is small (paper2d, 4 rows: 2.6 % faster runs than with the size a
 * variable); any other size, or a larger one (whose unrolled code costs gcc more time than
 * a first build can spare), takes the general loops. */
#ifndef GS_RADAU_M
#define GS_RADAU_M 0
#endif
#define GS_NR (GS_NX - GS_RADAU_M)
#if GS_RADAU_M > 0 && GS_NR <= 5
#define GS_NR_CONST 1
#else
#define GS_NR_CONST 0
#endif
GS_HIDDEN int gs_lu_real_n(double* A, int* piv, int n) {
  if (GS_NR_CONST && n == GS_NR) return lu_real(A, piv, GS_NR);
  return lu_real(A, piv, n);
}
GS_HIDDEN void gs_lu_solve_real_n(const double* LU, const int* piv, double* b, int n) {
  if (GS_NR_CONST && n == GS_NR)
    lu_solve_real(LU, piv, b, GS_NR);
  else
    lu_solve_real(LU, piv, b, n);
}
GS_HIDDEN int gs_lu_complex_n(double* Ar, double* Ai, int* piv, int n) {
  if (GS_NR_CONST && n == GS_NR) return lu_complex(Ar, Ai, piv, GS_NR);
  return lu_complex(Ar, Ai, piv, n);
}
GS_HIDDEN void gs_lu_solve_complex_n(const double* Ar, const double* Ai, const int* piv,
                                     double* br, double* bi, int n) {
  if (GS_NR_CONST && n == GS_NR)
    lu_solve_complex(Ar, Ai, piv, br, bi, GS_NR);
  else
    lu_solve_complex(Ar, Ai, piv, br, bi, n);
}
