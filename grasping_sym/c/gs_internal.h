/*
 * grasping_sym driver internals, shared by the driver's translation units (pyfast.c needs
 * only gs_driver.h).  Every file is compiled with the same -D macros, documented at the
 * top of driver.c.  The files:
 *
 *   driver.c   the macros' documentation; gs_info, gs_rhs, gs_rhs_batch, gs_outputs,
 *              gs_outputs_batch, gs_con_info, gs_constraints
 *   project.c  projection onto the constraints: gs_project, gs_project_state
 *   rk4.c      fixed-step classic Runge-Kutta: gs_rk4
 *   radau5.c   adaptive Radau IIA of order 5: gs_radau5 (its coefficients and tuning
 *              defaults in radau5.h)
 *   jac.c      gs_radau5's Jacobian d f / d x: gs_eval_jac (compiled) or gs_fd_jac
 *              (forward differences)
 *   lu.c       gs_radau5's dense real and complex LU factorisations
 *   dopri5.c   adaptive Dormand-Prince 5(4): gs_dopri5
 *   dop853.c   adaptive Dormand-Prince 8(5,3): gs_dop853
 *   stop.c     Ctrl-C and the wall-time limit
 *   wrap.c     a contact's coordinates wrapped a period round at a step (gs_wrap_*)
 *   watch.c    witnesses watched along a run, its stop at their events (gs_watch_*)
 *   batch.c    many runs over a pool of threads: gs_batch
 *
 * Helpers used by several files are static inline here; the functions defined in one
 * file and called from another are declared here with GS_HIDDEN, so the shared library
 * exports exactly the GS_EXPORT functions (and the CasADi-generated ones).
 */
#ifndef GS_INTERNAL_H
#define GS_INTERNAL_H

#include <math.h>
#include <stddef.h>

#if !defined(GS_SZ_ARG) || !defined(GS_SZ_RES) || !defined(GS_SZ_IW) || !defined(GS_SZ_W)
#error "define GS_SZ_ARG, GS_SZ_RES, GS_SZ_IW and GS_SZ_W (CasADi work sizes)"
#endif
#if GS_SZ_RES < 4
#error "GS_SZ_RES must be at least 4 (the rhs and the constraints function have four outputs)"
#endif
#include "gs_driver.h"
#ifndef GS_CASADI_INT
#define GS_CASADI_INT long long int
#endif

#define GS_EXPORT __attribute__((visibility("default")))
/* Functions shared between the driver's files, not exported from the library. */
#define GS_HIDDEN __attribute__((visibility("hidden")))

/* Error codes. */
#define GS_ERR_NONFINITE (-1) /* a state component became NaN or +-inf       */
#define GS_ERR_BOUNDS    (-2) /* a state component left [lo[i], hi[i]]      */
#define GS_ERR_EVAL      (-3) /* the CasADi function returned non-zero       */
#define GS_ERR_ARGS      (-4) /* invalid arguments (h, nsteps, stride, n)    */
#define GS_ERR_STEP      (-5) /* step size too small (Newton / error test)    */
#define GS_ERR_MAXSTEPS  (-6) /* max_steps reached before the end time       */
#define GS_ERR_PROJECT   (-7) /* projection onto the constraints failed      */
#define GS_ERR_STIFF     (-8) /* gs_dopri5, gs_dop853: the problem is stiff  */
#define GS_ERR_INTERRUPT (-9) /* stopped: SIGINT or the time limit (stop.c)  */
#define GS_EVENT        (-10) /* stopped at a watched witness's event (watch.c) */

/* Entries of the stats array (GS_NSTATS doubles). */
#define GS_ST_STEPS 0       /* accepted steps                                      */
#define GS_ST_REJECTED 1    /* rejected steps                                      */
#define GS_ST_RHS 2         /* right-hand-side evaluations                         */
#define GS_ST_JAC 3         /* Jacobian evaluations (gs_radau5)                    */
#define GS_ST_LU 4          /* LU decompositions (gs_radau5)                       */
#define GS_ST_NEWTON 5      /* Newton iterations (gs_radau5)                       */
#define GS_ST_ROWS 6        /* output rows written                                 */
#define GS_ST_HLAST 7       /* last step size                                      */
#define GS_ST_CON_EVALS 8   /* evaluations of the constraints by the projection     */
#define GS_ST_DRIFT_C 9     /* largest max|C| found before a projection            */
#define GS_ST_DRIFT_CDOT 10 /* largest max|Cdot| found before a velocity projection */
#define GS_ST_PROJ_PHASE 11 /* projection failure: 1 positions, 2 velocities       */
#define GS_ST_PROJ_RES 12   /* projection failure: the residual left               */
#define GS_ST_HLAMBDA 13    /* gs_dopri5, gs_dop853: last estimate h |lambda|      */
#define GS_ST_STIFF 14      /* stiffness tests above 3.25 (dopri5), 6.1 (dop853)   */
#define GS_ST_REDUCED 15    /* gs_radau5: second-order rows of the last Jacobian   */

#define GS_EPS 2.220446049250313e-16

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

/* stop.c: gs_stop_reset() when a loop starts; gs_stop_requested() non-zero when it must stop
 * (SIGINT, the time limit). */
GS_HIDDEN void gs_stop_reset(void);
GS_HIDDEN int gs_stop_requested(void);
/* stop.c, for gs_batch: clear Ctrl-C once; mark this thread's runs as a batch's (on = 1, with
 * the batch's deadline in monotonic s, 0: none) or not (on = 0); the monotonic clock; whether
 * Ctrl-C was pressed. */
GS_HIDDEN void gs_stop_batch_reset(void);
GS_HIDDEN void gs_stop_batch_thread(int on, double deadline);
GS_HIDDEN double gs_stop_now(void);
GS_HIDDEN int gs_stop_sigint(void);

/* The model's functions, under the fixed names the link file gives them (toolchain/objects.py:
 * ALIASES; a stub that fails for a function the model lacks, see gs_has_out ...): CasADi's
 * calling convention, and the 4-lane rhs's (codegen/lanes.py). */
int gs_model_rhs(const double** arg, double** res, GS_CASADI_INT* iw, double* w, int mem);
int gs_model_outputs(const double** arg, double** res, GS_CASADI_INT* iw, double* w, int mem);
int gs_model_jac(const double** arg, double** res, GS_CASADI_INT* iw, double* w, int mem);
const GS_CASADI_INT* gs_model_jac_sparsity_out(GS_CASADI_INT i);
int gs_model_constraints(const double** arg, double** res, GS_CASADI_INT* iw, double* w, int mem);
int gs_model_rhs_lanes(const double* t, const double* const* x, const double* p,
                       double* const* xdot);

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
  return gs_model_rhs(wk->arg, wk->res, wk->iw, wk->w, 0) ? GS_ERR_EVAL : 0;
}

/* xdot[s] = f(t[s], x[s], p) for s = 0, 1, 2: one call of the 4-lane rhs when the library
 * has it (codegen/lanes.py; bit-identical to three calls of the rhs), else three calls. */
/* A loop's start (and its start again after a chart's change, wrap.c): f = rhs(t, y), counted
 * in st; GS_ERR_NONFINITE, with x_bad = y, where f is not finite. */
static inline int gs_start_rhs(gs_work* wk, double t, const double* y, const double* p, double* f,
                               double* st, double* x_bad) {
  const int rc = gs_eval_rhs(wk, &t, y, p, f);
  if (rc) return rc;
  st[GS_ST_RHS] += 1;
  for (int i = 0; i < gs_nx; ++i)
    if (!isfinite(f[i])) {
      for (int j = 0; j < gs_nx; ++j) x_bad[j] = y[j];
      return GS_ERR_NONFINITE;
    }
  return 0;
}

static inline int gs_eval_rhs3(gs_work* wk, const double* t, const double* const* x,
                               const double* p, double* const* xdot) {
  if (gs_has_lanes) {
    double spare[gs_nx];
    const double tl[4] = {t[0], t[1], t[2], t[2]};
    const double* xl[4] = {x[0], x[1], x[2], x[2]};
    double* yl[4] = {xdot[0], xdot[1], xdot[2], spare};
    return gs_model_rhs_lanes(tl, xl, p, yl) ? GS_ERR_EVAL : 0;
  }
  int rc;
  for (int s = 0; s < 3; ++s)
    if ((rc = gs_eval_rhs(wk, t + s, x[s], p, xdot[s]))) return rc;
  return 0;
}

/* The outputs (gs_has_out: the caller's to ask) at x. */
static inline int gs_eval_out(gs_work* wk, const double* x, const double* p, double* y) {
  wk->arg[0] = x;
  wk->arg[1] = p;
  wk->res[0] = y;
  return gs_model_outputs(wk->arg, wk->res, wk->iw, wk->w, 0) ? GS_ERR_EVAL : 0;
}

/* (gs_has_con: the caller's to ask) C, dC/dx, Cdot, dCdot/dv at x (a result pointer may be NULL: that result is skipped). */
static inline int gs_eval_con(gs_work* wk, const double* x, const double* p, double* C,
                              double* JC, double* Cd, double* JCd) {
  wk->arg[0] = x;
  wk->arg[1] = p;
  wk->res[0] = C;
  wk->res[1] = JC;
  wk->res[2] = Cd;
  wk->res[3] = JCd;
  return gs_model_constraints(wk->arg, wk->res, wk->iw, wk->w, 0) ? GS_ERR_EVAL : 0;
}

/* 0 if x is finite and inside [lo, hi]; otherwise GS_ERR_NONFINITE / GS_ERR_BOUNDS.
 * lo / hi may be NULL (unbounded). */
static inline int gs_check(const double* x, const double* lo, const double* hi) {
  for (int i = 0; i < gs_nx; ++i)
    if (!isfinite(x[i])) return GS_ERR_NONFINITE;
  for (int i = 0; i < gs_nx; ++i)
    if ((lo && x[i] < lo[i]) || (hi && x[i] > hi[i])) return GS_ERR_BOUNDS;
  return 0;
}

/* A vector's components v[0], v[1] in a frame (x, y) turned by delta about the normal
 * (x' = cos delta x + sin delta y): its components in the new frame (runtime/modes.py's
 * _turned). A sliding contact's slip in its fingertip's frame at a change of chart (wrap.c,
 * watch.c). */
static inline void gs_turn2(double* v, double delta) {
  const double a = v[0], b = v[1], c = cos(delta), s = sin(delta);
  v[0] = a * c + b * s;
  v[1] = b * c - a * s;
}

/* watch.c: a sliding contact's slip witness w turned with its fingertip's frame by delta at a
 * change of that frame's chart (wrap.c); delta 0 only asks whether it can be: 0 yes, 1 no. */
GS_HIDDEN int gs_watch_turn(int w, double delta);
/* wrap.c: the parameters a loop runs on (its own copy where a chart may change in it). */
GS_HIDDEN const double* gs_wrap_params(const double* p);
/* wrap.c: a step's end outside [lo, hi] at a contact's coordinates that wrap a period round
 * (gs_wrap_set): the step's start y (at t), its end y_end and also[0..n_also-1] moved by whole
 * periods, 1 returned; or (a change of chart) y mapped, p's chart changed, 2 returned (the
 * step not taken); else 0, nothing changed. The watch's ends left unwatched are watched
 * first (gs_watch_settle): an event among them, neither. */
GS_HIDDEN int gs_wrap_step(gs_work* wk, double t, double* y, double* y_end, const double* p,
                           const double* lo, const double* hi, double** also, int n_also);

/* max |v[i]| over m entries; +inf when an entry is not finite. */
static inline double gs_max_abs(const double* v, int m) {
  double r = 0.0;
  for (int i = 0; i < m; ++i) {
    if (!isfinite(v[i])) return INFINITY;
    r = fmax(r, fabs(v[i]));
  }
  return r;
}

/* Root-mean-square norm of v / scale over m entries. */
static inline double gs_rms(const double* v, const double* scale, int m) {
  double s = 0.0;
  for (int i = 0; i < m; ++i) {
    const double q = v[i] / scale[i % gs_nx];
    s += q * q;
  }
  return sqrt(s / (double)m);
}

/* Validity of the projection arguments of the integrators: with a mask, a tolerance > 0
 * projects every accepted step and every output row between steps; a tolerance < 0 projects
 * the steps only, to -proj_tol (the rows are the dense output between projected steps). */
static inline int gs_proj_args_ok(const int* proj_mask, double proj_tol) {
  return !proj_mask || (gs_has_con && proj_tol != 0.0 && isfinite(proj_tol));
}

/* Validity of the arguments gs_radau5 and gs_dopri5 share (see gs_radau5): finite scalars,
 * rtol, atol >= 0, output times finite, strictly increasing and starting at or after t0. */
static inline int gs_adaptive_args_ok(double t0, long n_out, const double* t_out,
                                      const double* x0, const double* out, long max_steps,
                                      double rtol, double atol, double h0,
                                      const int* proj_mask, double proj_tol) {
  if (n_out < 1 || !t_out || !x0 || !out || max_steps < 1 || !isfinite(t0) || !isfinite(rtol) ||
      !isfinite(atol) || !(rtol >= 0.0) || !(atol >= 0.0) || !isfinite(h0) || !(t_out[0] >= t0) ||
      !gs_proj_args_ok(proj_mask, proj_tol))
    return 0;
  for (long k = 1; k < n_out; ++k)
    if (!(t_out[k] > t_out[k - 1]) || !isfinite(t_out[k])) return 0;
  return isfinite(t_out[n_out - 1]);
}

/* The start of an adaptive loop: y = x0 and x_bad NaN (x_bad = x0 when x0 itself is refused:
 * GS_ERR_NONFINITE / GS_ERR_BOUNDS, nothing written), then the output rows at t0 (t_out[r] <=
 * t0) written with x0; *row the next row. Returns 0 or the refusal's code. */
static inline int gs_adaptive_begin(double t0, long n_out, const double* t_out, const double* x0,
                                    const double* lo, const double* hi, double* y,
                                    double* x_bad, double* out, long* row) {
  for (int i = 0; i < gs_nx; ++i) {
    y[i] = x0[i];
    x_bad[i] = NAN;
  }
  const int rc = gs_check(y, lo, hi);
  if (rc) {
    for (int i = 0; i < gs_nx; ++i) x_bad[i] = y[i];
    return rc;
  }
  for (; *row < n_out && t_out[*row] <= t0; ++*row)
    for (int i = 0; i < gs_nx; ++i) out[*row * gs_nx + i] = y[i];
  return 0;
}

/* The end of an adaptive loop (gs_radau5, gs_dopri5, gs_dop853), rc its result: the rows
 * written and the counters go into stats; on a failure (rc < 0) *t_fail = t, output row
 * `row` holds y (the last accepted state) and row `row` + 1 x_bad (the rejected state of the
 * failures that have one, see gs_radau5; at GS_EVENT the start of the event's step) or NaN.
 * Returns rc. */
static inline long gs_adaptive_end(long rc, long row, double t, double* st, double* stats,
                                   double* t_fail, double* out, const double* y,
                                   const double* x_bad) {
  st[GS_ST_ROWS] = (double)row;
  if (stats)
    for (int i = 0; i < GS_NSTATS; ++i) stats[i] = st[i];
  if (rc >= 0) return rc;
  if (t_fail) *t_fail = t;
  const int bad = rc == GS_ERR_NONFINITE || rc == GS_ERR_BOUNDS || rc == GS_ERR_PROJECT ||
                  rc == GS_EVENT;
  for (int i = 0; i < gs_nx; ++i) {
    out[row * gs_nx + i] = y[i];
    out[(row + 1) * gs_nx + i] = bad ? x_bad[i] : NAN;
  }
  return rc;
}

/* First step size for an error estimate of order `order` (Hairer-Norsett-Wanner I, II.4, as
 * scipy's select_initial_step): h with h^(order+1) max(|f|, |f'|) = 0.01 in the weighted
 * RMS norm, at most `interval` and, when probe_cap > 0, at most probe_cap times the
 * explicit Euler probe 0.01 |y| / |f|.  That probe assumes every component changes
 * relative to its own size: a start at rest (zero speeds, non-zero accelerations) makes
 * it ~1e-8 s, and the step then needs ~6 steps of 8x growth to reach the dynamics' scale.
 * gs_radau5 passes probe_cap = 0 (a too large first step costs one rejected step there:
 * its first rejection divides h by 10); gs_dopri5 keeps scipy's 100. */
static inline int gs_initial_step(gs_work* wk, double t0, const double* y, const double* f,
                                  const double* p, double rtol, double atol, double interval,
                                  int order, double probe_cap, double* st, double* h_out) {
  double scale[gs_nx], tmp[gs_nx], fnew[gs_nx];
  for (int i = 0; i < gs_nx; ++i) scale[i] = atol + fabs(y[i]) * rtol;
  const double d0 = gs_rms(y, scale, gs_nx), d1 = gs_rms(f, scale, gs_nx);
  double hh = (d0 < 1e-5 || d1 < 1e-5) ? 1e-6 : 0.01 * d0 / d1;
  if (hh > interval) hh = interval;
  for (int i = 0; i < gs_nx; ++i) tmp[i] = y[i] + hh * f[i];
  const double t1 = t0 + hh;
  const int rc = gs_eval_rhs(wk, &t1, tmp, p, fnew);
  if (rc) return rc;
  st[GS_ST_RHS] += 1;
  for (int i = 0; i < gs_nx; ++i) tmp[i] = fnew[i] - f[i];
  const double d2 = gs_rms(tmp, scale, gs_nx) / hh;
  double h1;
  if (d1 <= 1e-15 && d2 <= 1e-15)
    h1 = fmax(1e-6, hh * 1e-3);
  else
    h1 = pow(0.01 / fmax(d1, d2), 1.0 / (order + 1));
  double h = fmin(probe_cap > 0.0 ? fmin(probe_cap * hh, h1) : h1, interval);
  if (!isfinite(h) || h <= 0.0) h = 1e-6 * interval;
  *h_out = h;
  return 0;
}

/* ---- Defined in project.c ---- */
/* Project x in place onto C(x) = 0 and then Cdot(x) = 0 (see gs_project); counts into st.
 * *changed (may be NULL) is set to 1 when x was modified. */
GS_HIDDEN int gs_project_state(gs_work* wk, double* x, const double* p, const int* mask,
                               double tol, double* st, int* changed);

/* After an accepted step: project x when proj_mask is given, then re-check the bounds.
 * For the integrators: expects rc, wk, p, proj_mask, proj_tol, st, lo, hi in scope and a
 * label fail. */
#define GS_PROJECT_STEP(x, changed)                                                   \
  do {                                                                                \
    if (proj_mask) {                                                                  \
      if ((rc = gs_project_state(wk, (x), p, proj_mask, proj_tol, st, (changed))))    \
        goto fail;                                                                    \
      if ((rc = gs_check((x), lo, hi))) goto fail;                                    \
    }                                                                                 \
  } while (0)

/* ---- Defined in watch.c (used by the adaptive loops): witnesses watched along a run ---- */
#define GS_WATCH_MAX 64     /* witnesses of one watch                                 */
#define GS_WATCH_TERMS 512  /* their terms in all                                     */
#define GS_WATCH_TTOL 1e-9  /* a root on the dense output: to this fraction of its
                               interval (runtime/events.py locates it exactly)         */
#define GS_WATCH_ITERATIONS 60
#define GS_WATCH_NOISE 100  /* gs_watch_refine: a bracket this many times its ttol where a
                             * trial is no nearer 0 than the last is the witness's noise     */
#define GS_WATCH_PROBES 16  /* points of the dense output an unarmed witness's firing
                             * interval is probed at for a time it was above its tol      */
#define GS_WATCH_SKIPS 16   /* steps' ends at most left unwatched in a row (watch.c)      */
/* The dense output of the step just accepted: x at t (between the step's start and end). */
typedef void (*gs_interp)(const void* ctx, double t, double* x);
/* Non-zero when this thread's runs watch witnesses (gs_watch_witnesses; never without
 * outputs). */
GS_HIDDEN int gs_watching(void);
/* The run's start (t0, x0; it ends at t_end): the witnesses' values there, each armed if > 0. */
GS_HIDDEN int gs_watch_settle(gs_work* wk, const double* p);
GS_HIDDEN int gs_watch_begin(gs_work* wk, double t0, const double* x0, const double* p,
                             double t_end);
/* After an accepted step from told to t (end state y_end, dense output interp(ctx, .)): 1 and
 * (*t_ev, x_ev) at the earliest event, 0 without one, or GS_ERR_EVAL; 2 for an event in an
 * earlier step whose end was left unwatched (watch.c): the loop drops its output rows at or
 * after *t_ev and takes the event's step start from gs_watch_event_start. */
GS_HIDDEN int gs_watch_step(gs_work* wk, double told, double t, const double* y_end,
                            const double* p, gs_interp interp, const void* ctx, double* t_ev,
                            double* x_ev);
/* The start of the last event's step (gs_watch_step returned 2), into x. */
GS_HIDDEN void gs_watch_event_start(double* x);
/* The end of a loop (its result rc) with steps' ends left unwatched (gs_watch_step): they
 * are dropped; a failure (not a stop: Ctrl-C, the time limit) where a witness fired at one of
 * them becomes that event, GS_EVENT returned (its time into *t, its state into y, its step's
 * start into x_step, the output rows at or after it dropped); else rc, or an error code. */
GS_HIDDEN long gs_watch_failed(gs_work* wk, long rc, const double* p, const double* t_out,
                               long* row, double* t, double* y, double* x_step);
/* While gs_watch_refine integrates again from one state, the Jacobian there, computed once:
 * 1 and J (nx x nx) copied when (t, x) is that state and J is kept, else 0; and kept. */
GS_HIDDEN int gs_refine_jac_get(double t, const double* x, double* J);
GS_HIDDEN void gs_refine_jac_put(double t, const double* x, const double* J);
/* gs_radau5 at an event, with a differenced Jacobian: the J its last steps used, for
 * gs_watch_refine's trials from the event's step start (a simplified Newton iteration takes
 * any J near the true one: the trials converge to the same collocation solution, without a
 * differenced J of their own, nx right-hand sides). Forgotten at the next gs_watch_begin. */
GS_HIDDEN void gs_watch_offer_jac(const double* J);
/* gs_batch: the watch off during the batch (returns whether it was on), then restored. */
GS_HIDDEN int gs_watch_suspend(void);
GS_HIDDEN void gs_watch_restore(int on);
/* gs_batch's watch (gs_watch_batch, watch.c): taken by gs_batch, set per run by its threads */
GS_HIDDEN const void* gs_watch_batch_take(void);
GS_HIDDEN void gs_watch_batch_enter(void);
GS_HIDDEN void gs_watch_batch_leave(void);
GS_HIDDEN int gs_watch_batch_run(const void* spec, long i);

/* ---- Defined in jac.c (used by gs_radau5): J = d f / d x (nx x nx, row-major), compiled
 * (gs_eval_jac, when gs_has_jac) or by forward differences ---- */
GS_HIDDEN int gs_eval_jac(gs_work* wk, const double* t, const double* x, const double* p,
                          double* J, double* val);
GS_HIDDEN int gs_fd_jac(gs_work* wk, const double* t, const double* x, const double* p,
                        const double* f, double atol, double* J);

/* ---- Defined in lu.c (used by gs_radau5): dense n x n LU, row-major (row stride n) ---- */
GS_HIDDEN int gs_lu_real_n(double* A, int* piv, int n);
GS_HIDDEN void gs_lu_solve_real_n(const double* LU, const int* piv, double* b, int n);
GS_HIDDEN int gs_lu_complex_n(double* Ar, double* Ai, int* piv, int n);
GS_HIDDEN void gs_lu_solve_complex_n(const double* Ar, const double* Ai, const int* piv,
                                     double* br, double* bi, int n);

#endif /* GS_INTERNAL_H */
