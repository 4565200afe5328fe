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
 *            v's state columns; kind 0 a repeating chart, 1 an atlas's longitude; u's and v's
 *            periods, 0 where it does not repeat, and their domains' middles; the chart
 *            parameter's index, -1 for none) and write each wrap to records (GS_WRAP_REC
 *            doubles: the step's start time, the slot, u and v there before and after), at
 *            most capacity of them (past that the loop stops at the bound, as without);
 *            n = 0 clears.
 *   gs_wrap_count()   the records written since gs_wrap_set.
 */
#include <math.h>

#include "gs_internal.h"

#define GS_WRAP_SLOTS 16
#define GS_WRAP_COLS 8
#define GS_WRAP_REC 6

static _Thread_local struct {
  int n;
  double slots[GS_WRAP_SLOTS * GS_WRAP_COLS];
  double* records;
  long capacity, count;
} gs_wr;

GS_EXPORT int gs_wrap_set(long n, const double* slots, double* records, long capacity) {
  if (n < 0 || n > GS_WRAP_SLOTS || (n && (!slots || !records || capacity < 1))) {
    gs_wr.n = 0;
    return GS_ERR_ARGS;
  }
  for (long k = 0; k < n * GS_WRAP_COLS; ++k) gs_wr.slots[k] = slots[k];
  for (long k = 0; k < n; ++k) {
    const double* s = gs_wr.slots + k * GS_WRAP_COLS;
    for (int j = 0; j < 2; ++j)
      if (!(s[j] >= 0.0 && s[j] < gs_nx) || !(s[3 + j] >= 0.0) || !isfinite(s[5 + j])) {
        gs_wr.n = 0;
        return GS_ERR_ARGS;
      }
    if (!(s[2] == 0.0 || (s[2] == 1.0 && s[7] >= 0.0 && s[7] < gs_np))) {
      gs_wr.n = 0;
      return GS_ERR_ARGS;
    }
  }
  gs_wr.n = (int)n;
  gs_wr.records = records;
  gs_wr.capacity = capacity;
  gs_wr.count = 0;
  return 0;
}

GS_EXPORT long gs_wrap_count(void) { return gs_wr.n ? gs_wr.count : 0; }

static int gs_out_of(const double* x, const double* lo, const double* hi, int i) {
  return (lo && x[i] < lo[i]) || (hi && x[i] > hi[i]);
}

/* center + remainder(value - center, period): runtime/atlas.py's _wrapped. */
static double gs_wrapped(double value, double period, double center) {
  return period > 0.0 ? center + remainder(value - center, period) : value;
}

/* A step from y (at t) to y_end whose end left [lo, hi] (GS_ERR_BOUNDS): when every component
 * outside is a slot's coordinate that `transition` would wrap in its chart, y, y_end and
 * also[0..n_also-1] (arrays holding the step's start or end: a dense output's base) are moved
 * by the same whole periods, the wrap recorded, and 1 returned; else 0 and nothing changed. */
GS_HIDDEN int gs_wrap_step(gs_work* wk, double t, double* y, double* y_end, const double* p,
                           const double* lo, const double* hi, double** also, int n_also) {
  if (!gs_wr.n) return 0;
  const int n = gs_nx;
  double shift[n], moved[n];
  int which[GS_WRAP_SLOTS], m = 0;
  for (int i = 0; i < n; ++i) shift[i] = 0.0;
  for (int k = 0; k < gs_wr.n; ++k) {
    const double* s = gs_wr.slots + k * GS_WRAP_COLS;
    const int iu = (int)s[0], iv = (int)s[1];
    if (!gs_out_of(y_end, lo, hi, iu) && !gs_out_of(y_end, lo, hi, iv)) continue;
    const double u = y[iu], v = y[iv];
    double u1 = u, v1 = v;
    if (s[2] == 0.0) { /* a repeating chart: each repeating coordinate toward its middle */
      u1 = gs_wrapped(u, s[3], s[5]);
      v1 = gs_wrapped(v, s[4], s[6]);
    } else { /* an atlas: its longitude, unless the other chart covers the point better */
      if (!p) return 0;
      const int chart = (int)lround(p[(int)s[7]]);
      const double e3 = chart ? cos(v) * sin(u) : cos(v) * cos(u); /* the other's sin(v') */
      if (fabs(asin(fmax(-1.0, fmin(1.0, e3)))) < fabs(v)) return 0;
      u1 = remainder(u, 2.0 * M_PI);
    }
    if (u1 == u && v1 == v) return 0;
    shift[iu] = u1 - u;
    shift[iv] = v1 - v;
    which[m++] = k;
  }
  if (!m || gs_wr.count + m > gs_wr.capacity) return 0;
  for (int i = 0; i < n; ++i) moved[i] = y_end[i] + shift[i];
  if (gs_check(moved, lo, hi)) return 0; /* still outside: a bound that is no period's */
  /* the step ends the watch left unwatched (watch.c's x_kept) are in the range before: watched
   * now; an event among them stops the loop there (at the bound, gs_watch_failed), unwrapped */
  if (gs_watch_settle(wk, p)) return 0;
  for (int j = 0; j < m; ++j) {
    const double* s = gs_wr.slots + which[j] * GS_WRAP_COLS;
    const int iu = (int)s[0], iv = (int)s[1];
    double* r = gs_wr.records + gs_wr.count++ * GS_WRAP_REC;
    r[0] = t;
    r[1] = which[j];
    r[2] = y[iu];
    r[3] = y[iv];
    r[4] = y[iu] + shift[iu];
    r[5] = y[iv] + shift[iv];
  }
  for (int i = 0; i < n; ++i) {
    if (shift[i] == 0.0) continue;
    y[i] += shift[i];
    y_end[i] = moved[i];
    for (int a = 0; a < n_also; ++a) also[a][i] += shift[i];
  }
  return 1;
}
