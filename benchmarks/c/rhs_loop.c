/*
 * Benchmark helper, not part of any model: time a model library's right-hand side in a C
 * loop.  The model's gs_rhs (driver.c) is passed as a function pointer, so this file is
 * compiled once and serves every model loaded in the process (benchmarks/rhs_loop.py).
 */
#include <time.h>

typedef int (*gs_rhs_fn)(const double* x, const double* p, double* xdot);

/* Evaluate rhs n times; xdot has the model's nx entries. Returns ns per call (wall clock). */
double bench_rhs_loop_ns(gs_rhs_fn rhs, long n, long nx, const double* x, const double* p,
                         double* xdot) {
  volatile double sink = 0.0;
  struct timespec a, b;
  if (n <= 0 || nx <= 0) return 0.0;
  clock_gettime(CLOCK_MONOTONIC, &a);
  for (long k = 0; k < n; ++k) {
    rhs(x, p, xdot);
    sink += xdot[k % nx];
  }
  clock_gettime(CLOCK_MONOTONIC, &b);
  (void)sink;
  return ((double)(b.tv_sec - a.tv_sec) * 1e9 + (double)(b.tv_nsec - a.tv_nsec)) / (double)n;
}
