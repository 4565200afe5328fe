/*
 * grasping_sym driver: witnesses watched along an adaptive run, for the runs with contact
 * modes (runtime/modes.py): gs_watch_witnesses, gs_watch_clear, gs_watch_result.
 *
 * A witness is a linear combination of the model's outputs less the length of a vector of
 * them, g = sum_k c_k y[i_k] - sqrt(sum_m (c_m y[i_m])^2) (the terms flagged as the norm's;
 * none: a linear combination; a term of index -1 is the constant c_k): a cone's margin
 * mu f - |F_t|, a normal force, a slip velocity along a direction, a gap, a relative
 * curvature above its threshold (runtime/watch.py's checks). With a
 * watch set on this thread, gs_radau5, gs_dopri5 and gs_dop853 evaluate every witness at
 * the run's start, then after each accepted step at its end and at points of its dense
 * output no farther apart than dt. A witness is armed once it was seen > tol (>= 0, its
 * own). An event is an armed witness <= 0 at a watched point, or, when tol > 0, an unarmed
 * one below -tol (a gap that closes again within the interval that opened it; a slip that
 * reverses before it was ever faster than tol: the noise of a slip that starts from rest
 * does not count). An unarmed one's interval is first probed on the dense output for a
 * time it was above tol (gs_watch_probe, for the witnesses flagged so: a gap, whose tol is
 * far above the dense output's error; not a slip's, whose tol is its noise): one found arms
 * it, and brackets its return to 0.
 * Its root (of g, or of g + tol unarmed) in its bracket is located on the dense output
 * (Illinois' regula falsi, to GS_WATCH_TTOL of the interval), the earliest of the step's
 * events is taken, and the loop stops there with GS_EVENT: the output rows before the event
 * are written, row r (r = stats[6]) holds the dense output's state at the event, row r + 1
 * the state at the start of the step, *t_fail the event's time, and gs_watch_result gives
 * the rest (below).
 * runtime/events.py then locates the root on the trajectory integrated again from the
 * step's start, the dense output's root as its first guess.
 *
 * A watched point (a step's end or a point of its dense output) is left unwatched while
 * every witness is armed and would still be above 0 there by `safety` (gs_watch_witnesses; 8
 * in runtime/modes.py) times what its rate and the change of its rate (from its last three
 * watched points) take off it: a margin far from its event costs no evaluation at every step. Never the run's end, never
 * more than GS_WATCH_SKIPS dt after the last watched point (another bound, or none, by
 * gs_watch_span: the run-time checks'), and at most GS_WATCH_SKIPS steps'
 * ends in a row, which are kept (with the start of the step of the last watched point); and
 * never for a model whose outputs read the time (a law of time: its forcing has no rate
 * before it acts). A
 * witness that fires at the next watched point is first looked for at them, in order; an
 * event found between two of them is bracketed by that step (the root's first guess the
 * secant between them; its step's start, kept, the state runtime/events.py integrates again
 * from), and the loop told to drop its output rows at or after it (gs_watch_step returns
 * 2); a loop that fails (not a stop) with ends kept looks for an event among them first
 * (gs_watch_failed). gs_watch_witnesses(safety = 0) watches every point.
 *
 * The outputs the witnesses read take p with the inputs at the watched time (p[k .. k+m) =
 * a + b t and p[k+m .. k+2m) = 0, as runtime.parameters.with_inputs does) and, for a model
 * whose outputs read the time (gs_out_time), t as one more last entry.
 *
 * The watch is thread-local, and off during gs_batch (its runs never watch, the calling
 * thread's included). gs_watch_resume: the next run continues the last one (a table of
 * inputs restarts the loop at its knots), its witnesses keep what they were armed by.
 */
#include <stdlib.h>
#include <string.h>

#include "gs_internal.h"

/* One watch: its witnesses (terms in compressed rows), and the run's state of them. */
typedef struct {
  int on, resume, n, in_k, in_m;
  double dt;
  int ptr[GS_WATCH_MAX + 1], idx[GS_WATCH_TERMS], norm[GS_WATCH_TERMS];
  double coef[GS_WATCH_TERMS], tol[GS_WATCH_MAX];
  int armed[GS_WATCH_MAX], probe[GS_WATCH_MAX];
  double g_prev[GS_WATCH_MAX], t_prev;
  /* the last event: which witness, armed or not, its bracket, the dense output's slope
   * there, the start of its step */
  int which, armed_at_event;
  double t_lo, t_hi, slope, t_step, t_root;
  /* leaving points unwatched (safety > 0): the run's end, each witness's last rate and the
   * change of its rate (known once two and three points were watched; t_rate where the rate
   * is), the ends left (kept[0] the start of the step of the last watched point, kept[1 ..
   * n_kept] the ends left since), the witnesses firing at a kept end, and the counts of the
   * points watched and left */
  int have_rate, have_curve, n_kept, n_fired;
  double safety, t_end, rate[GS_WATCH_MAX], curve[GS_WATCH_MAX], t_rate, t_kept[GS_WATCH_SKIPS + 1];
  /* the longest time a point may be left unwatched after the last watched one (0: no such
   * bound, the prediction and the steps' ends alone): GS_WATCH_SKIPS dt unless gs_watch_span */
  double span;
  double n_eval, n_left;
  /* GS_WATCH_SKIPS + 2 states (malloc'd by gs_watch_witnesses, freed by gs_watch_clear):
   * the ends kept (x_kept(i), i = 0 .. n_kept) and the event's step start (x_step) */
  double* kept;
  /* the Jacobian gs_radau5 offered at the event (gs_watch_offer_jac; nx x nx, malloc'd
   * there): kept past gs_watch_clear for the event's gs_watch_refine, which frees it; a
   * new watch or run forgets it (a thread that ends between an event and its refine leaves
   * this one block) */
  double* jac;
  int jac_valid;
} gs_watch_state;

static _Thread_local gs_watch_state gs_w;

#define x_kept(i) (gs_w.kept + (size_t)(i) * gs_nx)
#define x_step_kept (gs_w.kept + (size_t)(GS_WATCH_SKIPS + 1) * gs_nx)

GS_HIDDEN int gs_watching(void) { return gs_w.on; }


/* The witnesses at (t, x), into g. */
static int gs_watch_eval(gs_work* wk, double t, const double* x, const double* p, double* g) {
  double pw[gs_np + 1], y[gs_ny > 0 ? gs_ny : 1];
  for (int i = 0; i < gs_np; ++i) pw[i] = p[i];
  for (int i = 0; i < gs_w.in_m; ++i) {
    pw[gs_w.in_k + i] = p[gs_w.in_k + i] + p[gs_w.in_k + gs_w.in_m + i] * t;
    pw[gs_w.in_k + gs_w.in_m + i] = 0.0;
  }
  pw[gs_np] = t; /* read only by outputs that take the time (gs_out_time) */
  const int rc = gs_eval_out(wk, x, pw, y);
  if (rc) return rc;
  gs_w.n_eval += 1;
  for (int k = 0; k < gs_w.n; ++k) {
    double s = 0.0, q = 0.0;
    for (int j = gs_w.ptr[k]; j < gs_w.ptr[k + 1]; ++j) {
      const double v = gs_w.idx[j] < 0 ? gs_w.coef[j] : gs_w.coef[j] * y[gs_w.idx[j]];
      if (gs_w.norm[j])
        q += v * v;
      else
        s += v;
    }
    g[k] = s - sqrt(q);
  }
  return 0;
}

GS_HIDDEN int gs_watch_begin(gs_work* wk, double t0, const double* x0, const double* p,
                             double t_end) {
  double g[GS_WATCH_MAX];
  gs_w.t_end = t_end;
  gs_w.have_rate = 0;
  gs_w.have_curve = 0;
  gs_w.n_fired = 0;
  gs_w.n_kept = 0;
  gs_w.which = -1;
  gs_w.jac_valid = 0; /* an earlier run's event's Jacobian: never this run's */
  const int rc = gs_watch_eval(wk, t0, x0, p, g);
  if (rc) return rc;
  for (int k = 0; k < gs_w.n; ++k) {
    gs_w.armed[k] = (gs_w.resume && gs_w.armed[k]) || g[k] > gs_w.tol[k];
    gs_w.g_prev[k] = g[k];
  }
  gs_w.resume = 0;
  gs_w.t_prev = t0;
  return 0;
}

GS_HIDDEN void gs_watch_offer_jac(const double* J) {
  if (!gs_w.jac) gs_w.jac = malloc((size_t)gs_nx * gs_nx * sizeof(double));
  if (!gs_w.jac) return; /* no memory: the trials difference their own */
  for (int i = 0; i < gs_nx * gs_nx; ++i) gs_w.jac[i] = J[i];
  gs_w.jac_valid = 1;
}

/* Whether witness k's value v (after gs_w.g_prev at gs_w.t_prev) is an event. */
static int gs_watch_fires(int k, double v) {
  return gs_w.armed[k] ? !(v > 0.0) : (gs_w.tol[k] > 0.0 && v < -gs_w.tol[k]);
}

/* Witness k's root in [a, b] (ga = g(a) on the fired side's other side, gb = g(b)) on the
 * dense output: Illinois' regula falsi. */
static int gs_watch_root(gs_work* wk, int k, double a, double ga, double b, double gb,
                         const double* p, gs_interp interp, const void* ctx, double* x,
                         double* root, double* slope) {
  double g[GS_WATCH_MAX];
  const double tol = GS_WATCH_TTOL * (b - a);
  int side = 0;
  /* the sign change sought: from ga's side to gb's (gb <= 0 < ga, or gb < -tol <= ga) */
  const double level = gs_w.armed[k] ? 0.0 : -gs_w.tol[k];
  ga -= level;
  gb -= level;
  for (int it = 0; it < GS_WATCH_ITERATIONS && b - a > tol && ga != gb; ++it) {
    double c = b - gb * (b - a) / (gb - ga);
    if (!(c > a && c < b)) c = 0.5 * (a + b);
    interp(ctx, c, x);
    const int rc = gs_watch_eval(wk, c, x, p, g);
    if (rc) return rc;
    const double gc = g[k] - level;
    if (gc > 0.0) {
      a = c;
      ga = gc;
      if (side == -1) gb *= 0.5;
      side = -1;
    } else {
      b = c;
      gb = gc;
      if (side == 1) ga *= 0.5;
      side = 1;
    }
  }
  *root = b;
  *slope = ga != gb ? (gb - ga) / (b - a) : 0.0;
  return 0;
}

/* An unarmed witness k fired (below -tol at b): the dense output is probed at
 * GS_WATCH_PROBES - 1 points of (a, b) for a time it was above tol (a gap open for less than
 * the watched points' spacing, within one step: a short bounce). From the first such point
 * it is armed, and its bracket becomes the last point above 0 before the first at or below
 * 0 after it (or b). None: it stays unarmed, the bracket (a, b). */
static int gs_watch_probe(gs_work* wk, int k, double* a, double* ga, double* b, double* gb,
                          const double* p, gs_interp interp, const void* ctx, double* x) {
  double g[GS_WATCH_MAX];
  const double a0 = *a, b0 = *b;
  int up = 0;
  for (int s = 1; s < GS_WATCH_PROBES; ++s) {
    const double ts = a0 + (b0 - a0) * ((double)s / GS_WATCH_PROBES);
    interp(ctx, ts, x);
    const int rc = gs_watch_eval(wk, ts, x, p, g);
    if (rc) return rc;
    if (up && !(g[k] > 0.0)) {
      *b = ts;
      *gb = g[k];
      return 0;
    }
    if (up || g[k] > gs_w.tol[k]) {
      up = 1;
      gs_w.armed[k] = 1;
      *a = ts;
      *ga = g[k];
    }
  }
  return 0;
}

/* Whether the point t may be left unwatched: every witness armed, above 0 and still above 0
 * at t by gs_w.safety times what its last rate and the change of its rate (from the last
 * three watched points: a margin at its turning point is not taken for a constant one) would
 * take off it by then; t before the run's end, and no more than GS_WATCH_SKIPS dt after the
 * last watched point (dt > 0). Never for a model whose outputs read the time (gs_out_time:
 * a law of time): a pulse of its torque moves a contact's force at once, with nothing in the
 * witnesses' rates before it to foresee it (a review's 2 ms pulse opened a resting grasp's
 * contact unseen, radau stepping over it in one 30 ms step). */
static int gs_watch_may_leave(double t) {
  const double span = t - gs_w.t_prev, lever = t - gs_w.t_rate;
  if (gs_out_time || !(gs_w.safety > 0.0) || !gs_w.kept || !gs_w.have_curve || !(t < gs_w.t_end) ||
      (gs_w.span > 0.0 && span > gs_w.span))
    return 0;
  for (int k = 0; k < gs_w.n; ++k)
    if (!gs_w.armed[k] ||
        !(gs_w.g_prev[k] > gs_w.safety * span * (fabs(gs_w.rate[k]) + fabs(gs_w.curve[k]) * lever)))
      return 0;
  return 1;
}

/* A witness fired at the first point watched after steps' ends left unwatched (gs_w.kept):
 * the first of them where one fires, and the event in its step (1: *t_ev, x_ev, gs_w's
 * bracket and x_step set), or 0 with gs_w.t_prev, g_prev at the last of them (the event is in
 * the step being watched), or an error code. */
static int gs_watch_kept(gs_work* wk, const double* p, double* t_ev, double* x_ev) {
  double g[GS_WATCH_MAX];
  for (int i = 1; i <= gs_w.n_kept; ++i) { /* t_prev: in the step from kept i - 1 to kept i */
    const double a = gs_w.t_prev, b = gs_w.t_kept[i];
    const int rc = gs_watch_eval(wk, b, x_kept(i), p, g);
    if (rc) return rc;
    int best = -1, fired = 0;
    double best_t = b, best_slope = 0.0;
    for (int k = 0; k < gs_w.n; ++k) {
      if (!gs_watch_fires(k, g[k])) continue;
      const double level = gs_w.armed[k] ? 0.0 : -gs_w.tol[k];
      const double ga = gs_w.g_prev[k] - level, gb = g[k] - level;
      const double root = ga > gb ? a + (b - a) * ga / (ga - gb) : b;
      ++fired;
      if (best < 0 || root < best_t) {
        best = k;
        best_t = fmin(fmax(root, a), b);
        best_slope = (gb - ga) / (b - a);
      }
    }
    if (best >= 0) {
      const double w = (best_t - gs_w.t_kept[i - 1]) / (b - gs_w.t_kept[i - 1]);
      gs_w.n_fired = fired; /* more than one: their order is the secants' (runtime/modes.py) */
      gs_w.which = best;
      gs_w.armed_at_event = gs_w.armed[best];
      gs_w.t_lo = a;
      gs_w.t_hi = b;
      gs_w.slope = best_slope;
      gs_w.t_step = gs_w.t_kept[i - 1];
      gs_w.t_root = best_t;
      *t_ev = best_t;
      for (int j = 0; j < gs_nx; ++j) {
        x_ev[j] = (1.0 - w) * x_kept(i - 1)[j] + w * x_kept(i)[j];
        x_step_kept[j] = x_kept(i - 1)[j];
      }
      return 1;
    }
    for (int k = 0; k < gs_w.n; ++k) {
      gs_w.armed[k] |= g[k] > gs_w.tol[k];
      gs_w.g_prev[k] = g[k];
    }
    gs_w.t_prev = b;
  }
  return 0;
}

/* gs_watch_refine's Jacobian at the state its trials start from (gs_refine_jac_get): on
 * while it runs; x, then J, in one block. */
static _Thread_local struct {
  int on, valid;
  double t, *x;
} gs_rj;

GS_HIDDEN int gs_refine_jac_get(double t, const double* x, double* J) {
  if (!gs_rj.on || !gs_rj.valid || t != gs_rj.t) return 0;
  for (int i = 0; i < gs_nx; ++i)
    if (x[i] != gs_rj.x[i]) return 0;
  const double* kept = gs_rj.x + gs_nx;
  for (int i = 0; i < gs_nx * gs_nx; ++i) J[i] = kept[i];
  return 1;
}

GS_HIDDEN void gs_refine_jac_put(double t, const double* x, const double* J) {
  if (!gs_rj.on) return;
  double* kept = gs_rj.x + gs_nx;
  for (int i = 0; i < gs_nx; ++i) gs_rj.x[i] = x[i];
  for (int i = 0; i < gs_nx * gs_nx; ++i) kept[i] = J[i];
  gs_rj.t = t;
  gs_rj.valid = 1;
}

/* A sliding contact's slip witness w after its fingertip's chart changed in the loop (wrap.c):
 * its first two terms' coefficients, the slip direction in the fingertip's frame
 * (runtime/modes.py's slip_terms), turned with that frame by delta as runtime/modes.py's
 * _slip_across turns it (x' = cos delta x + sin delta y). gs_watch_turn(w, 0) only asks
 * whether w can be turned: 0 when it can, else 1 (nothing changed). The witness's value is
 * the same quantity in either frame: its last value and rates stay. */
GS_HIDDEN int gs_watch_turn(int w, double delta) {
  if (!gs_w.on || w < 0 || w >= gs_w.n || gs_w.ptr[w + 1] - gs_w.ptr[w] < 2 ||
      gs_w.norm[gs_w.ptr[w]] || gs_w.norm[gs_w.ptr[w] + 1] || gs_w.idx[gs_w.ptr[w]] < 0 ||
      gs_w.idx[gs_w.ptr[w] + 1] < 0)
    return 1;
  if (delta == 0.0) return 0;
  gs_turn2(gs_w.coef + gs_w.ptr[w], delta);
  return 0;
}

/* Before wrap.c moves a step by whole periods: the step ends left unwatched since the last
 * watched point (x_kept, in the range before) watched now. 0: none left (none fired; the watch
 * goes on from the last of them, as at its next watched point); 1: an event among them (kept:
 * the loop stops at the bound and gs_watch_failed takes it); < 0: an error. */
GS_HIDDEN int gs_watch_settle(gs_work* wk, const double* p) {
  if (!gs_w.on || gs_w.n_kept == 0) return 0;
  double t_ev, x_ev[gs_nx];
  const int found = gs_watch_kept(wk, p, &t_ev, x_ev);
  if (found == 0) gs_w.n_kept = 0;
  return found;
}

GS_HIDDEN long gs_watch_failed(gs_work* wk, long rc, const double* p, const double* t_out, long* row,
                              double* t, double* y, double* x_step) {
  if (!gs_w.on || gs_w.n_kept == 0) return rc;
  if (rc >= 0 || rc == GS_EVENT || rc == GS_ERR_INTERRUPT || rc == GS_ERR_ARGS) { /* or a stop */
    gs_w.n_kept = 0;
    return rc;
  }
  double t_ev;
  const int found = gs_watch_kept(wk, p, &t_ev, y);
  gs_w.n_kept = 0;
  if (found != 1) return found < 0 ? found : rc;
  *t = t_ev;
  while (*row > 0 && t_out[*row - 1] >= t_ev) --*row;
  gs_watch_event_start(x_step);
  return GS_EVENT;
}

GS_HIDDEN void gs_watch_event_start(double* x) {
  for (int i = 0; i < gs_nx; ++i) x[i] = x_step_kept[i];
}

GS_HIDDEN int gs_watch_step(gs_work* wk, double told, double t, const double* y_end,
                            const double* p, gs_interp interp, const void* ctx, double* t_ev,
                            double* x_ev) {
  double g[GS_WATCH_MAX], x[gs_nx];
  const int m = gs_w.dt > 0.0 ? (int)fmin(ceil((t - told) / gs_w.dt), 1e6) : 1;
  for (int j = 1; j <= (m > 1 ? m : 1); ++j) {
    const double tj = j == m || m <= 1 ? t : told + (t - told) * ((double)j / m);
    if (gs_watch_may_leave(tj)) {
      if (tj != t) { /* a point of the dense output: its step is at hand if one fires later.
                      * gs_watch_may_leave is monotone in t (what it compares grows with t):
                      * every point up to the last it leaves is left, found by bisection */
        int lo = j, hi = m - 1;
        while (lo < hi) {
          const int mid = lo + (hi - lo + 1) / 2;
          if (gs_watch_may_leave(told + (t - told) * ((double)mid / m)))
            lo = mid;
          else
            hi = mid - 1;
        }
        gs_w.n_left += lo - j + 1;
        j = lo;
        continue;
      }
      if (gs_w.kept && gs_w.n_kept < GS_WATCH_SKIPS) { /* the step's end, kept */
        if (gs_w.n_kept == 0) { /* the last watched point is in this step: its start */
          gs_w.t_kept[0] = told;
          interp(ctx, told, x_kept(0));
        }
        const int i = ++gs_w.n_kept;
        gs_w.t_kept[i] = t;
        for (int c = 0; c < gs_nx; ++c) x_kept(i)[c] = y_end[c];
        gs_w.n_left += 1;
        return 0;
      }
    }
    const double* xj = y_end;
    if (tj != t) {
      interp(ctx, tj, x);
      xj = x;
    }
    int rc = gs_watch_eval(wk, tj, xj, p, g);
    if (rc) return rc;
    if (gs_w.n_kept > 0) { /* the first point watched after ends left unwatched */
      int fired = 0;
      for (int k = 0; k < gs_w.n && !fired; ++k) fired = gs_watch_fires(k, g[k]);
      if (fired) {
        rc = gs_watch_kept(wk, p, t_ev, x_ev);
        if (rc) {
          gs_w.n_kept = 0;
          return rc < 0 ? rc : 2;
        }
        /* none fires at the ends kept: the event is in this step, as if they were watched */
      }
      gs_w.n_kept = 0;
    }
    int best = -1;
    double best_t = tj, best_slope = 0.0, best_a = gs_w.t_prev, best_b = tj;
    for (int k = 0; k < gs_w.n; ++k) {
      if (!gs_watch_fires(k, g[k])) continue;
      double a = gs_w.t_prev, ga = gs_w.g_prev[k], b = tj, gb = g[k], root, slope;
      if (!gs_w.armed[k] && gs_w.probe[k]) {
        rc = gs_watch_probe(wk, k, &a, &ga, &b, &gb, p, interp, ctx, x);
        if (rc) return rc;
      }
      rc = gs_watch_root(wk, k, a, ga, b, gb, p, interp, ctx, x, &root, &slope);
      if (rc) return rc;
      if (best < 0 || root < best_t) {
        best = k;
        best_t = root;
        best_slope = slope;
        best_a = a;
        best_b = b;
      }
    }
    if (best >= 0) {
      gs_w.n_fired = 0;
      gs_w.which = best;
      gs_w.armed_at_event = gs_w.armed[best];
      gs_w.t_lo = best_a;
      gs_w.t_hi = best_b;
      gs_w.slope = best_slope;
      gs_w.t_step = told;
      gs_w.t_root = best_t;
      *t_ev = best_t;
      if (best_t == t)
        for (int i = 0; i < gs_nx; ++i) x_ev[i] = y_end[i];
      else
        interp(ctx, best_t, x_ev);
      return 1;
    }
    const double mid = 0.5 * (tj + gs_w.t_prev); /* where the new rate is the rate */
    const int moved = tj > gs_w.t_prev, curved = moved && gs_w.have_rate && mid > gs_w.t_rate;
    for (int k = 0; k < gs_w.n; ++k) {
      if (moved) {
        const double rate = (g[k] - gs_w.g_prev[k]) / (tj - gs_w.t_prev);
        if (curved) gs_w.curve[k] = (rate - gs_w.rate[k]) / (mid - gs_w.t_rate);
        gs_w.rate[k] = rate;
      }
      gs_w.armed[k] |= g[k] > gs_w.tol[k];
      gs_w.g_prev[k] = g[k];
    }
    if (moved) {
      gs_w.have_curve = gs_w.have_curve || curved;
      gs_w.have_rate = 1;
      gs_w.t_rate = mid;
    }
    gs_w.t_prev = tj;
  }
  return 0;
}

/* The last event's witness at the state integrated again from the step's start (t_step,
 * x_step) to t, one step of the loop `method` tried (0 radau5, 1 dopri5, 2 dop853), the watch
 * off: into *g (less its level: 0 armed, -tol not), the state into x. */
static int gs_refine_at(int method, double t, const double* x_step, const double* p, double rtol,
                        double atol, long max_steps, const double* lo, const double* hi,
                        double* x, double* g) {
  GS_DECLARE_WORK(wk);
  const double t_out[2] = {gs_w.t_step, t};
  double out[3 * gs_nx], st[GS_NSTATS] = {0}, tf = NAN, all[GS_WATCH_MAX];
  const double h0 = t - gs_w.t_step;
  long rc;
  if (!(h0 > 0.0)) {
    for (int i = 0; i < gs_nx; ++i) x[i] = x_step[i];
  } else {
    if (method == 0)
      rc = gs_radau5(t_out[0], 2, t_out, x_step, p, rtol, atol, h0, max_steps, lo, hi, NULL, 0.0,
                     out, st, &tf);
    else if (method == 1)
      rc = gs_dopri5(t_out[0], 2, t_out, x_step, p, rtol, atol, h0, max_steps, 0, lo, hi, NULL,
                     0.0, out, st, &tf);
    else
      rc = gs_dop853(t_out[0], 2, t_out, x_step, p, rtol, atol, h0, max_steps, 0, lo, hi, NULL,
                     0.0, out, st, &tf);
    if (rc != 2) return rc < 0 ? (int)rc : GS_ERR_ARGS;
    for (int i = 0; i < gs_nx; ++i) x[i] = out[gs_nx + i];
  }
  const int rc2 = gs_watch_eval(wk, t, x, p, all);
  if (rc2) return rc2;
  const int k = gs_w.which;
  *g = all[k] - (gs_w.armed_at_event ? 0.0 : -gs_w.tol[k]);
  if (isnan(*g)) *g = -1e300; /* a blow-up counts as past the event */
  return 0;
}

/* The witness (less its level, as gs_refine_at) at t near an anchor (ta, xa) of the
 * trajectory integrated again, fa = f(ta, xa): one step of Heun's method from it, taken when
 * it is far below the tolerances (the explicit Euler step differs from it by at most
 * GS_REFINE_NEAR (atol + rtol |x|) in every component; Heun's own error is smaller still by
 * |t - ta| times the rates' change). The secant steps near a root are 1e-11 s or less: there
 * this is the trajectory to round-off, at two right-hand sides and one outputs' evaluation
 * instead of a step of the loop integrated again from the step's start; and it is smooth in
 * t, where the trials integrated again each carry their Newton iteration's noise. Returns 0
 * (x, *g set), 1 when the step would be too long (the caller integrates again), or an error
 * code. */
#define GS_REFINE_NEAR 1e-3
/* Heun's error is about the Euler-Heun difference times |lambda dt| / 3 (lambda the largest
 * rate of the Jacobian): the step is also capped at GS_REFINE_SPAN (1 + |t|) s, where a
 * stiff rate of 1e6 1/s still leaves it below 1e-3 of that difference. */
#define GS_REFINE_SPAN 1e-9
static int gs_refine_near(double t, double ta, const double* xa, const double* fa, const double* p,
                          double rtol, double atol, double* x, double* g) {
  GS_DECLARE_WORK(wk);
  const double dt = t - ta;
  if (!(fabs(dt) <= GS_REFINE_SPAN * (1.0 + fabs(ta)))) return 1;
  double xe[gs_nx], fe[gs_nx], all[GS_WATCH_MAX];
  for (int i = 0; i < gs_nx; ++i) xe[i] = xa[i] + dt * fa[i];
  int rc = gs_eval_rhs(wk, &t, xe, p, fe);
  if (rc) return rc;
  for (int i = 0; i < gs_nx; ++i) {
    const double change = 0.5 * dt * (fe[i] - fa[i]);
    if (!(fabs(change) <= GS_REFINE_NEAR * (atol + rtol * fabs(xa[i])))) return 1;
    x[i] = xe[i] + change;
  }
  if ((rc = gs_watch_eval(wk, t, x, p, all))) return rc;
  const int k = gs_w.which;
  *g = all[k] - (gs_w.armed_at_event ? 0.0 : -gs_w.tol[k]);
  if (isnan(*g)) *g = -1e300;
  return 0;
}

/* The last event located on the trajectory integrated again from its step's start (t_step
 * of gs_watch_result; its state x_step) by the run's loop `method` with the run's p, rtol,
 * atol, max_steps, lo, hi: secant steps from the dense output's root and slope, each trial
 * one step from t_step (runtime/events.py's refine, in C), stopped when the next step would
 * be below ttol s, or when the bracket of the sign change is within GS_WATCH_NOISE ttol and a
 * trial is no nearer 0 than the one before (the witness's noise: the one before is taken
 * when inside the bracket, else the trial). Returns 0 with the time in *t, the state in x and the witness (less its
 * level) in *g; 1 when the secant steps do not converge in `steps` or the trajectory
 * integrated again shows no sign change where it is looked for (the caller takes Brent's
 * method); < 0 an integration's error code. The watch is off meanwhile. */
GS_EXPORT int gs_watch_refine(int method, const double* x_step, const double* p, double rtol,
                              double atol, long max_steps, const double* lo, const double* hi,
                              double ttol, long steps, double* t, double* x, double* g) {
  if (!gs_has_out || gs_w.which < 0 || !(ttol > 0.0) || method < 0 || method > 2)
    return GS_ERR_ARGS;
  const int on = gs_watch_suspend();
  gs_rj.x = malloc((size_t)(gs_nx + gs_nx * gs_nx) * sizeof(double)); /* none: J every trial */
  gs_rj.on = gs_rj.x != NULL;
  gs_rj.valid = 0;
  if (method == 0 && gs_w.jac_valid) /* the loop's J, for the trials from the step's start */
    gs_refine_jac_put(gs_w.t_step, x_step, gs_w.jac);
  double a = gs_w.t_lo, b = gs_w.t_hi, slope = gs_w.slope, xt[gs_nx];
  double t1 = fmin(fmax(gs_w.t_root, a), b), g1, g2, t2;
  /* the anchor of the trials near the first (gs_refine_near): its state, integrated again;
   * none when its rates cannot be had */
  double ta = t1, xa[gs_nx], fa[gs_nx];
  int anchored = 0;
  int rc = gs_refine_at(method, t1, x_step, p, rtol, atol, max_steps, lo, hi, x, &g1);
  if (rc) goto done;
  {
    GS_DECLARE_WORK(wk);
    for (int i = 0; i < gs_nx; ++i) xa[i] = x[i];
    anchored = gs_eval_rhs(wk, &ta, xa, p, fa) == 0;
    for (int i = 0; anchored && i < gs_nx; ++i) anchored = isfinite(fa[i]);
  }
  if (g1 > 0.0)
    a = t1;
  else
    b = t1;
  t2 = slope < 0.0 && isfinite(slope) ? t1 - g1 / slope : 0.5 * (a + b);
  if (fabs(t2 - t1) <= ttol && a <= t2 && t2 <= b) { /* the dense output's root was the root */
    *t = t1;
    *g = g1;
    goto done;
  }
  rc = 1;
  for (long it = 0; it < steps; ++it) {
    if (g1 == 0.0 || b - a <= ttol) { /* x holds t1's state */
      *t = t1;
      *g = g1;
      rc = 0;
      break;
    }
    if (!(a <= t2 && t2 <= b) || t2 == t1) t2 = 0.5 * (a + b);
    int r2 = anchored ? gs_refine_near(t2, ta, xa, fa, p, rtol, atol, xt, &g2) : 1;
    if (r2 == 1)
      r2 = gs_refine_at(method, t2, x_step, p, rtol, atol, max_steps, lo, hi, xt, &g2);
    if (r2) {
      rc = r2;
      break;
    }
    if (g2 > 0.0)
      a = t2;
    else
      b = t2;
    if (b - a <= GS_WATCH_NOISE * ttol && !(fabs(g2) < fabs(g1))) {
      /* the witness integrated again is at its noise (the Newton iterations'): the bracket
       * [a, b] of its sign change is within GS_WATCH_NOISE ttol and t2 came no nearer 0 than
       * t1. Taken: t1 when inside the bracket (x holds its state), else t2 (an end of it) */
      if (a <= t1 && t1 <= b) {
        *t = t1;
        *g = g1;
      } else {
        *t = t2;
        *g = g2;
        for (int i = 0; i < gs_nx; ++i) x[i] = xt[i];
      }
      rc = 0;
      break;
    }
    const double t3 = g2 != g1 ? t2 - g2 * (t2 - t1) / (g2 - g1) : 0.5 * (a + b);
    for (int i = 0; i < gs_nx; ++i) x[i] = xt[i];
    if (g2 == 0.0 || fabs(t3 - t2) <= ttol) { /* the next secant step would be below ttol */
      *t = t2;
      *g = g2;
      rc = 0;
      break;
    }
    t1 = t2;
    g1 = g2;
    t2 = t3;
  }
done:
  gs_rj.on = 0;
  free(gs_rj.x);
  gs_rj.x = NULL;
  free(gs_w.jac); /* the event's offered J: used */
  gs_w.jac = NULL;
  gs_w.jac_valid = 0;
  gs_watch_restore(on);
  return rc;
}

/* Watch n witnesses in this thread's next runs: witness k is sum_j coef[j] y[idx[j]] over
 * the j in [ptr[k], ptr[k + 1]) with norm[j] 0, less sqrt(sum_j (coef[j] y[idx[j]])^2) over
 * those with norm[j] 1; tol[k] and probe[k] (0 or 1) as above; the inputs (a, b) at p[in_k .. in_k + 2
 * in_m) (in_m = 0: none); watched points at most dt apart (0: the steps' ends only); safety >
 * 0 the factor by which steps' ends are left unwatched (above), 0 every step's end watched.
 * idx[j] = -1: the constant term coef[j] (not a norm's). Returns 0, or GS_ERR_ARGS (nothing
 * set) for a model without outputs, more than GS_WATCH_MAX witnesses or GS_WATCH_TERMS terms,
 * an index out of range or a non-finite number. */
GS_EXPORT int gs_watch_witnesses(long n, const long* ptr, const long* idx, const double* coef,
                           const long* norm, const double* tol, const long* probe, long in_k,
                           long in_m, double dt, double safety) {
  if (!gs_has_out || n < 0 || n > GS_WATCH_MAX || !ptr || ptr[0] != 0 || ptr[n] > GS_WATCH_TERMS ||
      !(dt >= 0.0) || !isfinite(dt) || !(safety >= 0.0) || !isfinite(safety) || in_m < 0 || in_k < 0 || in_k + 2 * in_m > gs_np)
    return GS_ERR_ARGS;
  for (long k = 0; k < n; ++k) {
    if (ptr[k + 1] < ptr[k] || !(tol[k] >= 0.0) || !isfinite(tol[k])) return GS_ERR_ARGS;
    for (long j = ptr[k]; j < ptr[k + 1]; ++j)
      if (idx[j] < -1 || idx[j] >= gs_ny || !isfinite(coef[j]) || (norm[j] != 0 && norm[j] != 1) ||
          (idx[j] == -1 && norm[j] != 0))
        return GS_ERR_ARGS;
  }
  gs_w.n = (int)n;
  gs_w.in_k = (int)in_k;
  gs_w.in_m = (int)in_m;
  gs_w.dt = dt;
  gs_w.safety = safety;
  gs_w.span = GS_WATCH_SKIPS * dt;
  gs_w.n_kept = 0;
  if (safety > 0.0 && !gs_w.kept) /* none (no memory): every point is watched */
    gs_w.kept = malloc((size_t)(GS_WATCH_SKIPS + 2) * gs_nx * sizeof(double));
  gs_w.jac_valid = 0;
  gs_w.n_eval = 0.0;
  gs_w.n_left = 0.0;
  for (long k = 0; k <= n; ++k) gs_w.ptr[k] = (int)ptr[k];
  for (long j = 0; j < ptr[n]; ++j) {
    gs_w.idx[j] = (int)idx[j];
    gs_w.coef[j] = coef[j];
    gs_w.norm[j] = (int)norm[j];
  }
  for (long k = 0; k < n; ++k) {
    gs_w.tol[k] = tol[k];
    gs_w.probe[k] = probe[k] != 0;
  }
  gs_w.which = -1;
  gs_w.resume = 0;
  gs_w.on = 1;
  return 0;
}

/* The watch's bound on the time a point may be left unwatched (after gs_watch_witnesses,
 * which sets GS_WATCH_SKIPS dt): span > 0 that many seconds, 0 none (a point is left while
 * the prediction says every witness stays above 0, at most GS_WATCH_SKIPS steps' ends in a
 * row). Returns 0, or GS_ERR_ARGS for a negative or non-finite span. */
GS_EXPORT int gs_watch_span(double span) {
  if (!(span >= 0.0) || !isfinite(span)) return GS_ERR_ARGS;
  gs_w.span = span;
  return 0;
}

GS_EXPORT void gs_watch_clear(void) {
  gs_w.on = 0;
  free(gs_w.kept);
  gs_w.kept = NULL;
}

/* The next run continues the last one (a piece of a table of inputs after a knot): its
 * witnesses keep what they were armed by. */
GS_EXPORT void gs_watch_resume(void) {
  gs_w.resume = 1;
}

/* gs_batch's watch (gs_watch_batch): the witnesses each run of the calling thread's next
 * gs_batch watches, as gs_watch_witnesses takes them, run i with its own coefficients
 * coef + i coef_stride; the arrays stay the caller's, alive until gs_batch returns. */
typedef struct {
  int set;
  long n, in_k, in_m, coef_stride;
  double dt, safety, span;
  const long *ptr, *idx, *norm, *probe;
  const double *coef, *tol;
} gs_watch_spec;

static _Thread_local gs_watch_spec gs_spec;
/* a batch thread's own watch replaces the thread's (the calling thread's): kept meanwhile */
static _Thread_local gs_watch_state gs_w_saved;

/* The witnesses every run of this thread's next gs_batch watches (the runs of a batch
 * without one never watch): n witnesses as gs_watch_witnesses, run i's coefficients at
 * coef + i coef_stride (every run's checked finite by the caller), span as gs_watch_span. Returns 0, or GS_ERR_ARGS
 * (nothing set) where gs_watch_witnesses would refuse run 0's. */
GS_EXPORT int gs_watch_batch(long n, const long* ptr, const long* idx, const double* coef,
                             long coef_stride, const long* norm, const double* tol,
                             const long* probe, long in_k, long in_m, double dt, double safety,
                             double span) {
  gs_watch_state keep = gs_w;
  gs_w.kept = NULL;
  const int rc = coef_stride < 0 || !(span >= 0.0) || !isfinite(span) ? GS_ERR_ARGS
                                 : gs_watch_witnesses(n, ptr, idx, coef, norm, tol, probe, in_k,
                                                      in_m, dt, safety);
  free(gs_w.kept);
  gs_w = keep;
  if (rc) return rc;
  gs_spec = (gs_watch_spec){.set = 1, .n = n, .in_k = in_k, .in_m = in_m, .coef_stride = coef_stride,
                            .dt = dt, .safety = safety, .span = span, .ptr = ptr, .idx = idx, .norm = norm,
                            .probe = probe, .coef = coef, .tol = tol};
  return 0;
}

/* Forget the watch gs_watch_batch set when its batch is not run (its arrays go). */
GS_EXPORT void gs_watch_batch_cancel(void) {
  gs_spec.set = 0;
}

/* gs_batch: the watch gs_watch_batch set for it (NULL: none; taken once). */
GS_HIDDEN const void* gs_watch_batch_take(void) {
  if (!gs_spec.set) return NULL;
  gs_spec.set = 0;
  return &gs_spec;
}

/* A batch thread's start and end with a watch: the thread's own watch kept aside, then
 * restored (the batch's freed). */
GS_HIDDEN void gs_watch_batch_enter(void) {
  gs_w_saved = gs_w;
  memset(&gs_w, 0, sizeof gs_w);
}

GS_HIDDEN void gs_watch_batch_leave(void) {
  free(gs_w.kept);
  free(gs_w.jac);
  gs_w = gs_w_saved;
}

/* Run i of a batch with a watch (spec: gs_watch_batch_take's): its witnesses set. */
GS_HIDDEN int gs_watch_batch_run(const void* spec, long i) {
  const gs_watch_spec* s = (const gs_watch_spec*)spec;
  const int rc = gs_watch_witnesses(s->n, s->ptr, s->idx, s->coef + i * s->coef_stride, s->norm,
                                    s->tol, s->probe, s->in_k, s->in_m, s->dt, s->safety);
  if (!rc) gs_w.span = s->span;
  return rc;
}

/* gs_batch without a watch: its runs never watch, the calling thread's too (the watch is off
 * during the batch and restored after it). */
GS_HIDDEN int gs_watch_suspend(void) {
  const int on = gs_w.on;
  gs_w.on = 0;
  return on;
}

GS_HIDDEN void gs_watch_restore(int on) {
  gs_w.on = on;
}

/* The last event of this thread's watched run: out[0] the witness (-1: none), out[1] 1 if it
 * was armed (else it fell below -tol), out[2], out[3] the watched points around it,
 * out[4] the dense output's slope of the witness there, out[5] the start of its step; out[6]
 * the points watched and out[7] those left unwatched since gs_watch_witnesses; out[8] the
 * witnesses that fired at the end of the event's step when it was left unwatched (more than
 * one: which is first is the secants' guess, runtime/modes.py looks again), else 0. */
GS_EXPORT void gs_watch_result(double* out) {
  if (!gs_has_out) { /* nothing is ever watched */
    out[0] = -1;
    for (int i = 1; i < 9; ++i) out[i] = NAN;
    return;
  }
  out[0] = gs_w.which;
  out[1] = gs_w.armed_at_event;
  out[2] = gs_w.t_lo;
  out[3] = gs_w.t_hi;
  out[4] = gs_w.slope;
  out[5] = gs_w.t_step;
  out[6] = gs_w.n_eval;
  out[7] = gs_w.n_left;
  out[8] = gs_w.n_fired;
}
