/*
 * grasping_sym driver: many runs in one call, over a pool of threads: gs_batch (c/driver.c
 * lists the files).
 *
 * Run i integrates from X0[i] with the parameters P[i] (or the one shared p) over the common
 * output times t_out, by the same loop a single run calls (gs_radau5, gs_dopri5, gs_dop853 or
 * gs_rk4)
 * with the same arguments: its numbers are bit for bit those of the single call.  The runs
 * are handed out one at a time to the threads (an atomic counter), so a slow run holds up no
 * other; which thread ran a run changes nothing in it.  One run's failure is recorded in its
 * status and loses nothing of the others.
 *
 *   long gs_batch(int method, long n_threads, long n_runs, long n_out, const double* t_out,
 *                 double h, long nsteps, long stride,
 *                 const double* X0, const double* P, long p_stride,
 *                 double rtol, double atol, double h0, long max_steps, long nstiff,
 *                 const double* lo, const double* hi, const int* proj_mask, double proj_tol,
 *                 double time_limit, int keep, double* X, double* Y, double* Y0,
 *                 double* CD0, long* status, double* t_fail, double* stats);
 *
 *   method      0 gs_radau5, 1 gs_dopri5, 3 gs_dop853, 2 gs_rk4 (t_out then uniform: t_out[0], h, nsteps,
 *               stride as gs_rk4 takes them, n_out = nsteps / stride + 1 rows)
 *   n_threads   threads to use (>= 1; the calling thread is one of them)
 *   X0          n_runs x nx initial states, row-major
 *   P, p_stride run i reads P + i p_stride (p_stride 0: every run reads P; P may be NULL
 *               when np == 0)
 *   time_limit  seconds of wall time for the whole batch (0: none); runs not finished then
 *               stop with GS_ERR_INTERRUPT, as do all runs after Ctrl-C
 *   keep        1: X holds every output row, n_runs x n_out x nx (NaN after a failure's
 *               last written row); 0: X holds the final state, n_runs x nx (NaN on failure)
 *   Y           NULL, or the outputs (the model's) at the rows X holds: n_runs x n_out x ny
 *               (keep) or n_runs x ny, NaN where X is
 *   Y0, CD0     NULL, or the outputs at X0[i] (n_runs x ny) and max |Cdot| at X0[i] (n_runs,
 *               needs constraints): what simulate's initial checks read
 *   status      n_runs: the single loop's return value (n_out on success, a GS_ERR_* code,
 *               GS_EVENT at a watched witness's event: gs_watch_batch, watch.c);
 *               GS_ERR_INTERRUPT also for runs never started because the batch stopped (their
 *               stats row is 0 but for GS_ST_ROWS = -1, their X, Y, Y0, CD0 NaN)
 *   t_fail      n_runs: the single loop's *t_fail (NaN on success)
 *   stats       NULL or n_runs x GS_NSTATS: each run's stats
 *
 * Returns the number of runs that succeeded, or GS_ERR_ARGS (nothing run), or
 * GS_ERR_INTERRUPT after Ctrl-C (gs_stop_cause() then returns 1).
 */
#define _POSIX_C_SOURCE 200809L
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "gs_internal.h"

typedef struct {
  int method, keep;
  long n_runs, n_out, rows, nsteps, stride, max_steps, nstiff, p_stride;
  const double *t_out, *X0, *P, *lo, *hi;
  const int* mask;
  double h, rtol, atol, h0, proj_tol, deadline;
  double *X, *Y, *Y0, *CD0, *t_fail, *stats;
  long* status;
  long next;   /* the next run to hand out (atomic) */
  int stopped; /* set once a run was stopped (atomic) */
  long ok;     /* runs that succeeded (atomic) */
  const void* watch; /* gs_watch_batch's witnesses, or NULL (watch.c) */
} gs_batch_job;

static void gs_fill_nan(double* v, long n) {
  for (long k = 0; k < n; ++k) v[k] = NAN;
}

/* One run of the job, scratch: job->rows + 2 rows of nx. */
static void gs_batch_run(gs_batch_job* job, long i, double* scratch) {
  const long nx = gs_nx, m = job->n_out;
  const double* x0 = job->X0 + i * nx;
  const double* p = job->P ? job->P + i * job->p_stride : NULL;
  double st[GS_NSTATS] = {0};
  double tf = NAN;
  long rc;
  if (job->Y0 && gs_outputs(x0, p, job->Y0 + i * gs_ny)) gs_fill_nan(job->Y0 + i * gs_ny, gs_ny);
  if (job->CD0) {
    double cd[gs_nc];
    job->CD0[i] = gs_constraints(x0, p, NULL, NULL, cd, NULL) ? NAN : gs_max_abs(cd, gs_nc);
  }
  if (job->watch && job->method != 2 && gs_watch_batch_run(job->watch, i)) {
    rc = GS_ERR_ARGS; /* (refused before the batch: gs_watch_batch) */
  } else if (job->method == 0)
    rc = gs_radau5(job->t_out[0], m, job->t_out, x0, p, job->rtol, job->atol, job->h0,
                   job->max_steps, job->lo, job->hi, job->mask, job->proj_tol, scratch, st, &tf);
  else if (job->method == 1)
    rc = gs_dopri5(job->t_out[0], m, job->t_out, x0, p, job->rtol, job->atol, job->h0,
                   job->max_steps, job->nstiff, job->lo, job->hi, job->mask, job->proj_tol,
                   scratch, st, &tf);
  else if (job->method == 3)
    rc = gs_dop853(job->t_out[0], m, job->t_out, x0, p, job->rtol, job->atol, job->h0,
                   job->max_steps, job->nstiff, job->lo, job->hi, job->mask, job->proj_tol,
                   scratch, st, &tf);
  else
    rc = gs_rk4(job->t_out[0], job->h, job->nsteps, job->stride, x0, p, job->lo, job->hi,
                job->mask, job->proj_tol, scratch, st, &tf);
  const int ok = rc == m;
  /* rows written: all on success; else the adaptive loops count them in stats, gs_rk4's
   * are those up to t_fail */
  long written = m;
  if (!ok) {
    if (job->method == 2)
      written = isfinite(tf) ? lround((tf - job->t_out[0]) / job->h) / job->stride + 1 : 0;
    else
      written = (long)st[GS_ST_ROWS];
    if (written > m) written = m;
    if (written < 0) written = 0;
  }
  job->status[i] = rc;
  job->t_fail[i] = ok ? NAN : tf;
  if (job->stats) memcpy(job->stats + i * GS_NSTATS, st, sizeof st);
  if (job->keep) {
    double* X = job->X + i * m * nx;
    memcpy(X, scratch, (size_t)(written * nx) * sizeof(double));
    gs_fill_nan(X + written * nx, (m - written) * nx);
  } else if (ok) {
    memcpy(job->X + i * nx, scratch + (m - 1) * nx, (size_t)nx * sizeof(double));
  } else {
    gs_fill_nan(job->X + i * nx, nx);
  }
  if (job->Y) {
    const long rows = job->keep ? m : 1;
    double* Y = job->Y + i * rows * gs_ny;
    const double* X = job->keep ? job->X + i * m * nx : job->X + i * nx;
    const long good = job->keep ? written : ok;
    for (long r = 0; r < rows; ++r)
      if (r >= good || gs_outputs(X + r * nx, p, Y + r * gs_ny)) gs_fill_nan(Y + r * gs_ny, gs_ny);
  }
  if (job->watch) gs_watch_restore(0); /* the next run sets its own */
  if (ok) __atomic_fetch_add(&job->ok, 1, __ATOMIC_RELAXED);
  if (rc == GS_ERR_INTERRUPT) __atomic_store_n(&job->stopped, 1, __ATOMIC_RELAXED);
}

static void* gs_batch_worker(void* arg) {
  gs_batch_job* job = (gs_batch_job*)arg;
  double* scratch = malloc((size_t)((job->rows + 2) * gs_nx) * sizeof(double));
  if (job->watch) gs_watch_batch_enter();
  gs_stop_batch_thread(1, job->deadline);
  for (;;) {
    const long i = __atomic_fetch_add(&job->next, 1, __ATOMIC_RELAXED);
    if (i >= job->n_runs) break;
    if (!scratch || __atomic_load_n(&job->stopped, __ATOMIC_RELAXED) || gs_stop_sigint() ||
        (job->deadline > 0.0 && gs_stop_now() > job->deadline)) {
      /* never started: the batch was stopped (or no memory: a failed allocation of the
       * scratch rows stops the batch as well, rather than losing runs silently) */
      __atomic_store_n(&job->stopped, 1, __ATOMIC_RELAXED);
      job->status[i] = GS_ERR_INTERRUPT;
      job->t_fail[i] = job->t_out[0];
      if (job->stats) {
        memset(job->stats + i * GS_NSTATS, 0, GS_NSTATS * sizeof(double));
        job->stats[i * GS_NSTATS + GS_ST_ROWS] = -1.0; /* the mark of a run never started */
      }
      gs_fill_nan(job->X + i * (job->keep ? job->n_out : 1) * gs_nx,
                  (job->keep ? job->n_out : 1) * gs_nx);
      if (job->Y) gs_fill_nan(job->Y + i * (job->keep ? job->n_out : 1) * gs_ny,
                              (job->keep ? job->n_out : 1) * gs_ny);
      if (job->Y0) gs_fill_nan(job->Y0 + i * gs_ny, gs_ny);
      if (job->CD0) job->CD0[i] = NAN;
      continue;
    }
    gs_batch_run(job, i, scratch);
  }
  gs_stop_batch_thread(0, 0.0);
  if (job->watch) gs_watch_batch_leave();
  free(scratch);
  return NULL;
}

GS_EXPORT long gs_batch(int method, long n_threads, long n_runs, long n_out, const double* t_out,
                        double h, long nsteps, long stride, const double* X0, const double* P,
                        long p_stride, double rtol, double atol, double h0, long max_steps,
                        long nstiff, const double* lo, const double* hi, const int* proj_mask,
                        double proj_tol, double time_limit, int keep, double* X, double* Y,
                        double* Y0, double* CD0, long* status, double* t_fail, double* stats) {
  const void* watch = gs_watch_batch_take(); /* first: never left pending for a later batch */
  if (method < 0 || method > 3 || n_threads < 1 || n_runs < 0 || n_out < 2 || !t_out || !X0 ||
      !X || !status || !t_fail || p_stride < 0 || (gs_np > 0 && !P) || !(time_limit >= 0.0) ||
      (method == 2 && (nsteps < 1 || stride < 1 || nsteps % stride || nsteps / stride + 1 != n_out)))
    return GS_ERR_ARGS;
  if ((!gs_has_out && (Y || Y0)) || (!gs_has_con && CD0)) return GS_ERR_ARGS;
  gs_batch_job job = {
      .method = method, .keep = keep != 0, .n_runs = n_runs, .n_out = n_out, .rows = n_out,
      .nsteps = nsteps, .stride = stride, .max_steps = max_steps, .nstiff = nstiff,
      .p_stride = p_stride, .t_out = t_out, .X0 = X0, .P = P, .lo = lo, .hi = hi,
      .mask = proj_mask, .h = h, .rtol = rtol, .atol = atol, .h0 = h0, .proj_tol = proj_tol,
      .deadline = time_limit > 0.0 ? gs_stop_now() + time_limit : 0.0, .X = X, .Y = Y,
      .Y0 = Y0, .CD0 = CD0, .t_fail = t_fail, .stats = stats, .status = status, .next = 0,
      .stopped = 0, .ok = 0, .watch = watch};
  gs_stop_batch_reset();
  if (n_threads > n_runs) n_threads = n_runs > 0 ? n_runs : 1;
  pthread_t* threads = n_threads > 1 ? malloc((size_t)(n_threads - 1) * sizeof(pthread_t)) : NULL;
  long started = 0;
  if (threads)
    for (; started < n_threads - 1; ++started)
      if (pthread_create(&threads[started], NULL, gs_batch_worker, &job)) break;
  /* without gs_watch_batch's witnesses, a batch's runs never watch (watch.c) */
  const int watching = job.watch ? 0 : gs_watch_suspend();
  gs_batch_worker(&job); /* the calling thread works too */
  if (!job.watch) gs_watch_restore(watching);
  for (long k = 0; k < started; ++k) pthread_join(threads[k], NULL);
  free(threads);
  if (gs_stop_sigint()) {
    gs_stop_requested(); /* gs_stop_cause() now says 1 (Ctrl-C) in the calling thread */
    return GS_ERR_INTERRUPT;
  }
  return job.ok;
}
