/*
 * grasping_sym driver: a contact's coordinates wrapped a period round inside the adaptive
 * loops (c/driver.c lists the files; runtime/atlas.py is the whole of the atlases' map).
 *
 * A surface whose longitude or repeating coordinate reaches its bound at a step's end is the
 * same point a whole period round. runtime/atlas.py's `transition` takes the contact there
 * when the loop stops at the bound (GS_ERR_BOUNDS), and the run goes on from a new loop: half
 * a millisecond of Python and a restart. Here, in the loop, the step is kept and its start and
 * end are moved by the same whole periods (the same `transition`, on the step's start): the
 * dense output is differences from the start, the right-hand side, its Jacobian, the
 * constraints and the witnesses are periodic in the coordinate, so the loop goes on as if
 * nothing happened, and writes this step's rows in the new range. What needs a chart of
 * another map (an atlas's other chart, where it covers the point better; a bound that is no
 * period's) is left to runtime/atlas.py: the loop stops at the bound as before. The step ends
 * the watch (watch.c) left unwatched, in the range before, are watched first: an event among
 * them stops the loop there, unwrapped.
 *
 *   gs_wrap_set(n, slots, records, capacity)
 *            this thread's next loops wrap the n slots (GS_WRAP_COLS doubles each: u's and
 *            v's state columns; kind 0 a repeating chart, 1 an atlas of F(d) = diag(a) d, 2
 *            one of F(d) = rho(d) d; u's and v's periods, 0 where it does not repeat, and
 *            their domains' middles; the chart parameter's index, -1 for none; the frame
 *            angle psi's column, -1 for none; the semi-axes a and the exponent n; 1 where the
 *            loop may change the chart itself, else 0; for a fingertip's chart whose contact
 *            slides, the index in p of its slip direction (two entries, in the fingertip's
 *            frame: turned with it by delta at a change, with the watch's slip witness, whose
 *            index follows; watch.c's gs_watch_turn), else -1 and -1) and write each wrap or change to
 *            records (GS_WRAP_REC doubles: the step's start time, the slot, u and v there
 *            before and after, the chart before and after, delta), at most capacity of them
 *            (past that the loop stops at the bound, as without); n = 0 clears.
 *   gs_wrap_count()   the records written since gs_wrap_set.
 *   gs_wrap_cols()    GS_WRAP_COLS: the slots' row this library reads (runtime/compiled.py
 *                     wraps nothing with a library whose rows differ from its own).
 */
#include <math.h>

#include "gs_internal.h"

#define GS_WRAP_SLOTS 16
#define GS_WRAP_COLS 16
#define GS_WRAP_REC 9
#define GS_WRAP_NP 512 /* the parameters a loop's own copy holds (a chart's change writes it) */

static _Thread_local struct {
  int n, changes;         /* slots; whether any may change its chart */
  double slots[GS_WRAP_SLOTS * GS_WRAP_COLS];
  double* records;
  long capacity, count;
  double p[GS_WRAP_NP];   /* the running loop's parameters (gs_wrap_params) */
} gs_wr;

static int gs_wrap_refuse(void) {
  gs_wr.n = 0;
  return GS_ERR_ARGS;
}

GS_EXPORT int gs_wrap_set(long n, const double* slots, double* records, long capacity) {
  if (n < 0 || n > GS_WRAP_SLOTS || (n && (!slots || !records || capacity < 1))) return gs_wrap_refuse();
  gs_wr.changes = 0;
  for (long k = 0; k < n * GS_WRAP_COLS; ++k) gs_wr.slots[k] = slots[k];
  for (long k = 0; k < n; ++k) {
    const double* s = gs_wr.slots + k * GS_WRAP_COLS;
    for (int j = 0; j < 2; ++j)
      if (!(s[j] >= 0.0 && s[j] < gs_nx) || !(s[3 + j] >= 0.0) || !isfinite(s[5 + j])) return gs_wrap_refuse();
    if (s[2] == 0.0) continue;
    if (!((s[2] == 1.0 || s[2] == 2.0) && s[7] >= 0.0 && s[7] < gs_np && s[8] >= -1.0 && s[8] < gs_nx &&
          s[9] > 0.0 && s[10] > 0.0 && s[11] > 0.0 && (s[2] == 1.0 || s[12] >= 2.0) &&
          (s[13] == 0.0 || s[13] == 1.0) &&
          ((s[14] == -1.0 && s[15] == -1.0) || (s[14] >= 0.0 && s[14] + 1.0 < gs_np && s[15] >= 0.0))))
      return gs_wrap_refuse();
    gs_wr.changes |= s[13] == 1.0 && gs_np <= GS_WRAP_NP;
  }
  gs_wr.n = (int)n;
  gs_wr.records = records;
  gs_wr.capacity = capacity;
  gs_wr.count = 0;
  return 0;
}

GS_EXPORT long gs_wrap_count(void) { return gs_wr.n ? gs_wr.count : 0; }

GS_EXPORT long gs_wrap_cols(void) { return GS_WRAP_COLS; }

/* A loop's start: the parameters it runs on. Where a slot may change its chart, this thread's
 * copy of p (gs_wrap_step writes the chart there); else p. */
GS_HIDDEN const double* gs_wrap_params(const double* p) {
  if (!gs_wr.n || !gs_wr.changes || !p) return p;
  for (int i = 0; i < gs_np; ++i) gs_wr.p[i] = p[i];
  return gs_wr.p;
}

static int gs_out_of(const double* x, const double* lo, const double* hi, int i) {
  return (lo && x[i] < lo[i]) || (hi && x[i] > hi[i]);
}

/* center + remainder(value - center, period): runtime/atlas.py's _wrapped. */
static double gs_wrapped(double value, double period, double center) {
  return period > 0.0 ? center + remainder(value - center, period) : value;
}

/* runtime/atlas.py's _turn: P e for chart 1, e for chart 0. */
static void gs_turn(int chart, const double* e, double* out) {
  if (chart) {
    out[0] = e[2];
    out[1] = e[0];
    out[2] = e[1];
  } else {
    out[0] = e[0];
    out[1] = e[1];
    out[2] = e[2];
  }
}

static double gs_dot3(const double* a, const double* b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

static void gs_cross3(const double* a, const double* b, double* c) {
  c[0] = a[1] * b[2] - a[2] * b[1];
  c[1] = a[2] * b[0] - a[0] * b[2];
  c[2] = a[0] * b[1] - a[1] * b[0];
}

static void gs_unit3(double* a) {
  const double r = sqrt(gs_dot3(a, a));
  for (int i = 0; i < 3; ++i) a[i] /= r;
}

static double gs_ipow(double x, int k) {
  double r = 1.0;
  for (int i = 0; i < k; ++i) r *= x;
  return r;
}

/* runtime/atlas.py's _frame: the direction d, the frame's unit S_u (x) and the outward unit
 * normal (nrm) of the slot s's surface at (u, v) of chart. */
static void gs_frame(const double* s, int chart, double u, double v, double* d, double* x, double* nrm) {
  const double cu = cos(u), su = sin(u), cv = cos(v), sv = sin(v);
  const double e0[3] = {cv * cu, cv * su, sv}, eu0[3] = {-cv * su, cv * cu, 0.0},
               ev0[3] = {-sv * cu, -sv * su, cv};
  double e_u[3], e_v[3], S_u[3], S_v[3];
  gs_turn(chart, e0, d);
  gs_turn(chart, eu0, e_u);
  gs_turn(chart, ev0, e_v);
  const double* a = s + 9;
  if (s[2] == 1.0) { /* linear: F(d) = diag(a) d */
    for (int i = 0; i < 3; ++i) {
      S_u[i] = a[i] * e_u[i];
      S_v[i] = a[i] * e_v[i];
    }
  } else { /* F(d) = rho(d) d, rho = (sum (d_i/a_i)^n)^(-1/n): DF w = rho w + d (grad rho . w) */
    const int k = (int)s[12];
    double sum = 0.0, grad[3];
    for (int i = 0; i < 3; ++i) sum += gs_ipow(d[i] / a[i], k);
    const double rho = pow(sum, -1.0 / k), g = -pow(sum, -1.0 / k - 1.0);
    for (int i = 0; i < 3; ++i) grad[i] = g * gs_ipow(d[i], k - 1) / gs_ipow(a[i], k);
    const double gu = gs_dot3(grad, e_u), gv = gs_dot3(grad, e_v);
    for (int i = 0; i < 3; ++i) {
      S_u[i] = rho * e_u[i] + d[i] * gu;
      S_v[i] = rho * e_v[i] + d[i] * gv;
    }
  }
  for (int i = 0; i < 3; ++i) x[i] = S_u[i];
  gs_unit3(x);
  gs_cross3(S_u, S_v, nrm);
  gs_unit3(nrm);
}

/* A step from y (at t) to y_end whose end left [lo, hi] (GS_ERR_BOUNDS), each slot with a
 * coordinate outside taken where runtime/atlas.py's `transition` takes it, on the step's start:
 *   - every one a wrap (the same chart, whole periods): y, y_end and also[0..n_also-1] (arrays
 *     holding the step's start or end: a dense output's base) moved alike, and 1 returned (the
 *     step kept);
 *   - one or more a change of chart (an atlas whose other chart covers the point better, where
 *     its slot allows it and p is this thread's copy, gs_wrap_params): y mapped (u, v, the
 *     frame angle psi by delta), the chart written in p, and 2 returned (the step not taken:
 *     the loop starts again from y at t);
 * each recorded. Else 0, nothing changed: a bound that is no period's, a chart's change the
 * slot leaves to Python, a second change of one slot at one time, or the records full. */
GS_HIDDEN int gs_wrap_step(gs_work* wk, double t, double* y, double* y_end, const double* p,
                           const double* lo, const double* hi, double** also, int n_also) {
  if (!gs_wr.n) return 0;
  const int n = gs_nx;
  double shift[n], moved[n], rec[GS_WRAP_SLOTS][GS_WRAP_REC];
  int which[GS_WRAP_SLOTS], m = 0, changes = 0;
  for (int i = 0; i < n; ++i) shift[i] = 0.0;
  for (int k = 0; k < gs_wr.n; ++k) {
    const double* s = gs_wr.slots + k * GS_WRAP_COLS;
    const int iu = (int)s[0], iv = (int)s[1];
    if (!gs_out_of(y_end, lo, hi, iu) && !gs_out_of(y_end, lo, hi, iv)) continue;
    const double u = y[iu], v = y[iv];
    double u1 = u, v1 = v, delta = 0.0;
    int chart = 0, to = 0;
    if (s[2] == 0.0) { /* a repeating chart: each repeating coordinate toward its middle */
      u1 = gs_wrapped(u, s[3], s[5]);
      v1 = gs_wrapped(v, s[4], s[6]);
    } else { /* an atlas: its longitude wrapped, unless the other chart covers the point better */
      if (!p) return 0;
      to = chart = (int)lround(p[(int)s[7]]);
      double d[3], x_old[3], nrm[3];
      gs_frame(s, chart, u, v, d, x_old, nrm);
      const double e[3] = {chart ? d[0] : d[1], chart ? d[1] : d[2], chart ? d[2] : d[0]}; /* P_other^T d */
      const double uo = atan2(e[1], e[0]), vo = asin(fmax(-1.0, fmin(1.0, e[2])));
      if (fabs(vo) >= fabs(v)) {
        u1 = remainder(u, 2.0 * M_PI);
      } else {
        if (s[13] != 1.0 || p != gs_wr.p) return 0; /* the change is Python's */
        if (s[14] >= 0.0 && gs_watch_turn((int)s[15], 0.0)) return 0; /* a slip it cannot turn */
        for (long r = gs_wr.count - 1; r >= 0 && gs_wr.records[r * GS_WRAP_REC] == t; --r)
          if (gs_wr.records[r * GS_WRAP_REC + 1] == k) return 0; /* back at once: Python names it */
        double d1[3], x_new[3], n1[3], y_old[3];
        to = 1 - chart;
        gs_frame(s, to, uo, vo, d1, x_new, n1);
        gs_cross3(nrm, x_old, y_old);
        delta = atan2(gs_dot3(x_new, y_old), gs_dot3(x_new, x_old));
        u1 = uo;
        v1 = vo;
        ++changes;
      }
    }
    if (u1 == u && v1 == v && to == chart) return 0;
    which[m] = k;
    const double r[GS_WRAP_REC] = {t, k, u, v, u1, v1, chart, to, delta};
    for (int j = 0; j < GS_WRAP_REC; ++j) rec[m][j] = r[j];
    ++m;
    if (to == chart) {
      shift[iu] = u1 - u;
      shift[iv] = v1 - v;
    }
  }
  if (!m || gs_wr.count + m > gs_wr.capacity) return 0;
  if (!changes) {
    for (int i = 0; i < n; ++i) moved[i] = y_end[i] + shift[i];
    if (gs_check(moved, lo, hi)) return 0; /* still outside: a bound that is no period's */
  }
  /* the step ends the watch left unwatched (watch.c's x_kept) are in the range before: watched
   * now; an event among them stops the loop there (at the bound, gs_watch_failed), as it was */
  if (gs_watch_settle(wk, p)) return 0;
  for (int j = 0; j < m; ++j) {
    double* r = gs_wr.records + gs_wr.count++ * GS_WRAP_REC;
    for (int c = 0; c < GS_WRAP_REC; ++c) r[c] = rec[j][c];
  }
  if (!changes) {
    for (int i = 0; i < n; ++i) {
      if (shift[i] == 0.0) continue;
      y[i] += shift[i];
      y_end[i] = moved[i];
      for (int a = 0; a < n_also; ++a) also[a][i] += shift[i];
    }
    return 1;
  }
  for (int j = 0; j < m; ++j) { /* the step's start in its new charts; the step is not taken */
    const double* s = gs_wr.slots + which[j] * GS_WRAP_COLS;
    y[(int)s[0]] = rec[j][4];
    y[(int)s[1]] = rec[j][5];
    if (rec[j][6] != rec[j][7]) {
      if (s[8] >= 0.0) y[(int)s[8]] += rec[j][8];
      gs_wr.p[(int)s[7]] = rec[j][7];
      if (s[14] >= 0.0) { /* a slide: its direction in the fingertip's frame turns with it */
        gs_turn2(gs_wr.p + (int)s[14], rec[j][8]);
        gs_watch_turn((int)s[15], rec[j][8]);
      }
    }
  }
  return 2;
}
