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
 *                 const double* hi, double* out, double* t_fail);
 *   double gs_rhs_loop_ns(long n, const double* x, const double* p);
 *
 * Return codes: 0 (or a row count for gs_rk4) on success; GS_ERR_EVAL (-3)
 * when the CasADi function reports an error; see gs_rk4 for its codes.
 *
 * Thread safety: CasADi work arrays live on the stack of each exported call
 * (or in thread-local storage when they are large, see GS_WORK_ON_STACK_MAX),
 * so every gs_ function is reentrant and may be called from several threads
 * at once.  p may be NULL when GS_NP == 0.
 */
#include <math.h>
#include <stddef.h>
#include <time.h>

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
#ifndef GS_HAS_OUT
#define GS_HAS_OUT 0
#endif
#ifndef GS_NY
#define GS_NY 0
#endif
#ifndef GS_CASADI_INT
#define GS_CASADI_INT long long int
#endif
#if GS_HAS_OUT && !defined(GS_OUT)
#error "GS_HAS_OUT is 1 but GS_OUT (name of the outputs function) is not defined"
#endif

#define GS_EXPORT __attribute__((visibility("default")))

/* Error codes. */
#define GS_ERR_NONFINITE (-1) /* a state component became NaN or +-inf       */
#define GS_ERR_BOUNDS    (-2) /* a state component left [lo[i], hi[i]]      */
#define GS_ERR_EVAL      (-3) /* the CasADi function returned non-zero       */
#define GS_ERR_ARGS      (-4) /* invalid arguments (h, nsteps, stride, n)    */

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

/*
 * Classic fixed-step fourth-order Runge-Kutta, t_k = t0 + k*h, k = 0..nsteps.
 *
 * out (row-major, nx columns) receives x0 in row 0 and x(t_k) in row k/stride
 * whenever k % stride == 0, i.e. nsteps/stride + 1 rows on success.  The
 * caller MUST allocate nsteps/stride + 3 rows: on failure two extra rows are
 * written (see below).
 *
 * After every step the new state is checked: every component must be finite
 * and lo[i] <= x[i] <= hi[i] (lo / hi may be NULL or hold -inf / +inf).
 * When step k (from t_k to t_k + h) fails, integration stops and
 *   *t_fail            = t_k, the time of the last good state,
 *   row r = k/stride+1 = the last good state x(t_k),
 *   row r + 1          = the rejected state (the value that failed the check;
 *                        may contain NaN/inf; undefined for GS_ERR_EVAL),
 * and the return value is
 *   GS_ERR_NONFINITE (-1)  a component became NaN or +-inf,
 *   GS_ERR_BOUNDS    (-2)  a component left [lo[i], hi[i]],
 *   GS_ERR_EVAL      (-3)  the CasADi function returned an error,
 *   GS_ERR_ARGS      (-4)  h not finite, nsteps < 0 or stride < 1 (nothing written).
 * x0 itself is not checked.  On success the number of rows written is returned.
 */
GS_EXPORT long gs_rk4(double t0, double h, long nsteps, long stride, const double* x0,
                      const double* p, const double* lo, const double* hi, double* out,
                      double* t_fail) {
  GS_DECLARE_WORK(wk);
  double x[GS_NX], xn[GS_NX], xs[GS_NX], k1[GS_NX], k2[GS_NX], k3[GS_NX], k4[GS_NX];
  double ts;
  long row = 1;
  int rc = 0;

  if (!isfinite(h) || !isfinite(t0) || nsteps < 0 || stride < 1) return GS_ERR_ARGS;
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
    if ((rc = gs_check(xn, lo, hi))) goto fail;
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
    return rc;
  }
  return row;
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
