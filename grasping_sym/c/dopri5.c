/* grasping_sym driver: adaptive Dormand-Prince 5(4) with stiffness detection, gs_dopri5. */
#include "gs_internal.h"

/* ========================================================================== */
/*  Dormand-Prince 5(4) with adaptive steps: gs_dopri5                        */
/* ========================================================================== */
/*
 * Follows E. Hairer, S. P. Norsett, G. Wanner, "Solving Ordinary Differential
 * Equations I: Nonstiff Problems", 2nd ed., Springer 1993, Sec. II.4-II.6, and their
 * DOPRI5 code: the Dormand-Prince pair (fifth-order solution, embedded fourth-order
 * error estimate, first stage of a step = last stage of the previous one), step-size
 * control with Lund stabilisation (beta = 0.04), the continuous extension of order 4 as
 * dense output (no extra evaluations), and DOPRI5's stiffness detection (Hairer &
 * Wanner, "Solving ODEs II", Sec. IV.2): h |lambda| is estimated from the last two
 * stages, both at t + h, as h |k7 - k6| / |y1 - y6|; a step whose estimate exceeds 3.25
 * (the stability boundary of the method on the negative real axis is 3.31) counts as
 * stiff, 6 non-stiff steps in a row reset the count, and 15 stiff steps stop the
 * integration.  The test runs on every nstiff-th accepted step and, once a stiff step
 * was seen, on every step.  The C code here is our own; the constants are those of the
 * reference.
 */
#ifndef GS_DOPRI_SAFE
#define GS_DOPRI_SAFE 0.9 /* safety factor of the step-size selection            */
#endif
#ifndef GS_DOPRI_FAC1
#define GS_DOPRI_FAC1 0.2 /* h_new / h >= FAC1                                    */
#endif
#ifndef GS_DOPRI_FAC2
#define GS_DOPRI_FAC2 10.0 /* h_new / h <= FAC2                                   */
#endif
#ifndef GS_DOPRI_BETA
#define GS_DOPRI_BETA 0.04 /* Lund stabilisation of the step-size controller       */
#endif
#ifndef GS_DOPRI_STIFF_HLAMBDA
#define GS_DOPRI_STIFF_HLAMBDA 3.25 /* a step is stiff when h |lambda| exceeds this   */
#endif
#ifndef GS_DOPRI_STIFF_COUNT
#define GS_DOPRI_STIFF_COUNT 15 /* this many stiff steps (no 6 non-stiff in between) stop */
#endif
#ifndef GS_DOPRI_NONSTIFF_RESET
#define GS_DOPRI_NONSTIFF_RESET 6
#endif

static const double gs_dp_c[5] = {1.0 / 5.0, 3.0 / 10.0, 4.0 / 5.0, 8.0 / 9.0, 1.0};
static const double gs_dp_a21 = 1.0 / 5.0;
static const double gs_dp_a3[2] = {3.0 / 40.0, 9.0 / 40.0};
static const double gs_dp_a4[3] = {44.0 / 45.0, -56.0 / 15.0, 32.0 / 9.0};
static const double gs_dp_a5[4] = {19372.0 / 6561.0, -25360.0 / 2187.0, 64448.0 / 6561.0,
                                   -212.0 / 729.0};
static const double gs_dp_a6[5] = {9017.0 / 3168.0, -355.0 / 33.0, 46732.0 / 5247.0,
                                   49.0 / 176.0, -5103.0 / 18656.0};
/* The solution (= stage 7, a72 = 0). */
static const double gs_dp_b[6] = {35.0 / 384.0, 0.0, 500.0 / 1113.0, 125.0 / 192.0,
                                  -2187.0 / 6784.0, 11.0 / 84.0};
/* Error estimate: fifth- minus fourth-order solution, weights of k1..k7. */
static const double gs_dp_e[7] = {71.0 / 57600.0, 0.0, -71.0 / 16695.0, 71.0 / 1920.0,
                                  -17253.0 / 339200.0, 22.0 / 525.0, -1.0 / 40.0};
/* Dense output: the fifth coefficient's weights of k1..k7. */
static const double gs_dp_d[7] = {-12715105075.0 / 11282082432.0, 0.0,
                                  87487479700.0 / 32700410799.0, -10690763975.0 / 1880347072.0,
                                  701980252875.0 / 199316789632.0, -1453857185.0 / 822651844.0,
                                  69997945.0 / 29380423.0};

/*
 * Adaptive Dormand-Prince 5(4) integration of x' = f(t, x, p), see the comment above.
 *
 * Arguments as gs_radau5, and
 *   nstiff      run the stiffness test on every nstiff-th accepted step (DOPRI5's NSTIFF,
 *               Hairer's default 1000); <= 0: never (max_steps then bounds the work)
 *   t_out       the outputs between steps come from the continuous extension of order 4
 *               (continuous; a state at a step end is the step's); with proj_mask and
 *               proj_tol > 0 they are projected onto the constraints, like the step ends.
 *   stats       as gs_radau5 ([3], [4], [5] stay 0), and [13] the last estimate of
 *               h |lambda|, [14] the number of stiffness tests above 3.25.
 * Error estimate: weights atol + rtol max(|x_old|, |x_new|), RMS norm (as gs_radau5);
 * rtol is raised to 100 eps if smaller.
 *
 * Returns n_out on success; on failure the rows, *t_fail and the codes of gs_radau5, and
 *   GS_ERR_STEP      (-5)  the step size fell below 10 ulp(t) (repeated error-test
 *                          failures, or a right-hand side non-finite inside the steps),
 *   GS_ERR_STIFF     (-8)  the problem is stiff: *t_fail and row r are the start of the
 *                          step on which the stiffness test fired for the 15th time.
 */
/* The continuous extension of the step just accepted (d: 5 rows of n, see below). */
typedef struct {
  const double* d;
  double told, hsol;
} gs_dopri_dense;

static void gs_dopri_interp(const void* ctx, double t, double* x) {
  const gs_dopri_dense* c = (const gs_dopri_dense*)ctx;
  const int n = gs_nx;
  const double* d = c->d;
  const double s = (t - c->told) / c->hsol, s1 = 1.0 - s;
  for (int i = 0; i < n; ++i)
    x[i] = d[i] + s * (d[n + i] + s1 * (d[2 * n + i] + s * (d[3 * n + i] + s1 * d[4 * n + i])));
}

GS_EXPORT long gs_dopri5(double t0, long n_out, const double* t_out, const double* x0,
                         const double* p, double rtol, double atol, double h0, long max_steps,
                         long nstiff, const double* lo, const double* hi, const int* proj_mask,
                         double proj_tol, double* out, double* stats, double* t_fail) {
  const int n = gs_nx;
  GS_DECLARE_WORK(wk);
  double y[n], y1[n], ys[n], ysti[n], scale[n], dense[5][n];
  double k1[n], k2[n], k3[n], k4[n], k5[n], k6[n], k7[n];
  double st[GS_NSTATS] = {0};
  long row = 0;
  int rc = 0, reject = 0, last = 0, iasti = 0, nonsti = 0;
  double t = t0, told = t0, hsol = 0.0, h, facold = 1e-4;
  const double t_end = t_out ? t_out[n_out > 0 ? n_out - 1 : 0] : t0;
  const double expo1 = 0.2 - GS_DOPRI_BETA * 0.75;

  if (!gs_adaptive_args_ok(t0, n_out, t_out, x0, out, max_steps, rtol, atol, h0, proj_mask,
                           proj_tol))
    return GS_ERR_ARGS;
  const int proj_rows = proj_mask && proj_tol > 0.0; /* gs_proj_args_ok */
  proj_tol = fabs(proj_tol);
  gs_stop_reset();
  p = gs_wrap_params(p); /* a chart that changes in the loop is written there (wrap.c) */
  if (rtol < 100.0 * GS_EPS) rtol = 100.0 * GS_EPS;
  const double interval = t_end - t0;

  if ((rc = gs_adaptive_begin(t0, n_out, t_out, x0, lo, hi, y, y1, out, &row))) goto fail;
  if (row == n_out) goto done;
  if (gs_watching() && (rc = gs_watch_begin(wk, t0, y, p, t_out[n_out - 1]))) goto fail;

  if ((rc = gs_start_rhs(wk, t, y, p, k1, st, y1))) goto fail;
  if (h0 > 0.0)
    h = fmin(h0, interval);
  else if ((rc = gs_initial_step(wk, t0, y, k1, p, rtol, atol, interval, 4, 100.0, st, &h)))
    goto fail;

  while (1) { /* one attempted step per pass */
    if (st[GS_ST_STEPS] >= (double)max_steps) {
      rc = GS_ERR_MAXSTEPS;
      goto fail;
    }
    if (gs_stop_requested()) {
      rc = GS_ERR_INTERRUPT;
      goto fail;
    }
    if (!(h >= 10.0 * fabs(nextafter(t, INFINITY) - t))) {
      rc = GS_ERR_STEP;
      goto fail;
    }
    if (t + 1.01 * h >= t_end) {
      h = t_end - t;
      last = 1;
    }
    /* Stages 2..7; stage 7 is the fifth-order solution y1, evaluated for the next step. */
    double ts = t + gs_dp_c[0] * h;
    for (int i = 0; i < n; ++i) ys[i] = y[i] + h * gs_dp_a21 * k1[i];
    if ((rc = gs_eval_rhs(wk, &ts, ys, p, k2))) goto fail;
    ts = t + gs_dp_c[1] * h;
    for (int i = 0; i < n; ++i) ys[i] = y[i] + h * (gs_dp_a3[0] * k1[i] + gs_dp_a3[1] * k2[i]);
    if ((rc = gs_eval_rhs(wk, &ts, ys, p, k3))) goto fail;
    ts = t + gs_dp_c[2] * h;
    for (int i = 0; i < n; ++i)
      ys[i] = y[i] + h * (gs_dp_a4[0] * k1[i] + gs_dp_a4[1] * k2[i] + gs_dp_a4[2] * k3[i]);
    if ((rc = gs_eval_rhs(wk, &ts, ys, p, k4))) goto fail;
    ts = t + gs_dp_c[3] * h;
    for (int i = 0; i < n; ++i)
      ys[i] = y[i] + h * (gs_dp_a5[0] * k1[i] + gs_dp_a5[1] * k2[i] + gs_dp_a5[2] * k3[i] +
                          gs_dp_a5[3] * k4[i]);
    if ((rc = gs_eval_rhs(wk, &ts, ys, p, k5))) goto fail;
    const double tph = last ? t_end : t + h;
    for (int i = 0; i < n; ++i)
      ysti[i] = y[i] + h * (gs_dp_a6[0] * k1[i] + gs_dp_a6[1] * k2[i] + gs_dp_a6[2] * k3[i] +
                            gs_dp_a6[3] * k4[i] + gs_dp_a6[4] * k5[i]);
    if ((rc = gs_eval_rhs(wk, &tph, ysti, p, k6))) goto fail;
    for (int i = 0; i < n; ++i)
      y1[i] = y[i] + h * (gs_dp_b[0] * k1[i] + gs_dp_b[2] * k3[i] + gs_dp_b[3] * k4[i] +
                          gs_dp_b[4] * k5[i] + gs_dp_b[5] * k6[i]);
    if ((rc = gs_eval_rhs(wk, &tph, y1, p, k7))) goto fail;
    st[GS_ST_RHS] += 6;

    /* Error estimate (ys reused) and the new step size, FAC1 <= h_new / h <= FAC2. */
    for (int i = 0; i < n; ++i) {
      ys[i] = h * (gs_dp_e[0] * k1[i] + gs_dp_e[2] * k3[i] + gs_dp_e[3] * k4[i] +
                   gs_dp_e[4] * k5[i] + gs_dp_e[5] * k6[i] + gs_dp_e[6] * k7[i]);
      scale[i] = atol + fmax(fabs(y[i]), fabs(y1[i])) * rtol;
    }
    const double err = gs_rms(ys, scale, n);
    if (!isfinite(err)) { /* a stage left the region where f is finite: shrink */
      h *= GS_DOPRI_FAC1;
      reject = 1;
      last = 0;
      st[GS_ST_REJECTED] += 1;
      continue;
    }
    const double fac11 = pow(err, expo1);
    const double fac = fmax(1.0 / GS_DOPRI_FAC2,
                            fmin(1.0 / GS_DOPRI_FAC1,
                                 fac11 / pow(facold, GS_DOPRI_BETA) / GS_DOPRI_SAFE));
    double hnew = h / fac;
    if (!(err <= 1.0)) { /* rejected */
      h /= fmin(1.0 / GS_DOPRI_FAC1, fac11 / GS_DOPRI_SAFE);
      reject = 1;
      last = 0;
      st[GS_ST_REJECTED] += 1;
      continue;
    }

    /* Accepted. */
    facold = fmax(err, 1e-4);
    st[GS_ST_STEPS] += 1;
    if (nstiff > 0 && (((long)st[GS_ST_STEPS]) % nstiff == 0 || iasti > 0)) {
      double stnum = 0.0, stden = 0.0;
      for (int i = 0; i < n; ++i) {
        stnum += (k7[i] - k6[i]) * (k7[i] - k6[i]);
        stden += (y1[i] - ysti[i]) * (y1[i] - ysti[i]);
      }
      if (stden > 0.0) st[GS_ST_HLAMBDA] = h * sqrt(stnum / stden);
      if (st[GS_ST_HLAMBDA] > GS_DOPRI_STIFF_HLAMBDA) {
        nonsti = 0;
        st[GS_ST_STIFF] += 1;
        if (++iasti == GS_DOPRI_STIFF_COUNT) {
          rc = GS_ERR_STIFF;
          goto fail;
        }
      } else if (++nonsti == GS_DOPRI_NONSTIFF_RESET) {
        iasti = 0;
      }
    }
    /* Continuous extension of the unprojected step:
     * y(t_old + s h) = d0 + s (d1 + (1-s) (d2 + s (d3 + (1-s) d4))). */
    for (int i = 0; i < n; ++i) {
      const double ydiff = y1[i] - y[i], bspl = h * k1[i] - ydiff;
      dense[0][i] = y[i];
      dense[1][i] = ydiff;
      dense[2][i] = bspl;
      dense[3][i] = ydiff - h * k7[i] - bspl;
      dense[4][i] = h * (gs_dp_d[0] * k1[i] + gs_dp_d[2] * k3[i] + gs_dp_d[3] * k4[i] +
                         gs_dp_d[4] * k5[i] + gs_dp_d[5] * k6[i] + gs_dp_d[6] * k7[i]);
    }
    if ((rc = gs_check(y1, lo, hi))) {
      double* base[1] = {dense[0]};
      const int w = rc == GS_ERR_BOUNDS ? gs_wrap_step(wk, t, y, y1, p, lo, hi, base, 1) : 0;
      if (!w) goto fail;
      rc = 0; /* 1: a contact's coordinate a period round (wrap.c): dense[1..4] are differences */
      if (w == 2) { /* a chart's change: y mapped at t; the step not taken, the loop anew */
        st[GS_ST_STEPS] -= 1;
        st[GS_ST_REJECTED] += 1;
        if ((rc = gs_start_rhs(wk, t, y, p, k1, st, y1))) goto fail;
        last = 0;
        reject = 0;
        facold = 1e-4;
        continue;
      }
    }
    {
      int changed = 0;
      GS_PROJECT_STEP(y1, &changed);
      if (changed) { /* the next step starts from f at the projected state */
        if ((rc = gs_eval_rhs(wk, &tph, y1, p, k7))) goto fail;
        st[GS_ST_RHS] += 1;
      }
    }
    for (int i = 0; i < n; ++i)
      if (!isfinite(k7[i])) {
        rc = GS_ERR_NONFINITE;
        goto fail;
      }
    told = t;
    hsol = h;
    t = tph;
    st[GS_ST_HLAST] = h;
    for (int i = 0; i < n; ++i) {
      y[i] = y1[i];
      k1[i] = k7[i];
    }
    int event = 0;
    double t_ev = t;
    if (gs_watching()) {
      const gs_dopri_dense dn = {&dense[0][0], told, hsol};
      event = gs_watch_step(wk, told, t, y, p, gs_dopri_interp, &dn, &t_ev, ys);
      if (event < 0) {
        rc = event;
        goto fail;
      }
      while (event == 2 && row > 0 && t_out[row - 1] >= t_ev) --row; /* an earlier step's */
    }
    while (row < n_out && (event ? t_out[row] < t_ev : t_out[row] <= t)) {
      double* o = out + row * n;
      if (t_out[row] == t) {
        for (int i = 0; i < n; ++i) o[i] = y[i];
      } else {
        const double s = (t_out[row] - told) / hsol, s1 = 1.0 - s;
        for (int i = 0; i < n; ++i)
          o[i] = dense[0][i] +
                 s * (dense[1][i] + s1 * (dense[2][i] + s * (dense[3][i] + s1 * dense[4][i])));
        if (proj_rows && (rc = gs_project_state(wk, o, p, proj_mask, proj_tol, st, NULL))) {
          for (int i = 0; i < n; ++i) y1[i] = o[i];
          goto fail;
        }
      }
      ++row;
    }
    if (event) { /* stop at the event: its state, and its step's start (gs_adaptive_end) */
      for (int i = 0; i < n; ++i) {
        y[i] = ys[i];
        y1[i] = dense[0][i];
      }
      if (event == 2) gs_watch_event_start(y1);
      t = t_ev;
      rc = GS_EVENT;
      goto fail;
    }
    if (last) break;
    hnew = fmin(hnew, interval);
    if (reject) hnew = fmin(hnew, h);
    reject = 0;
    h = hnew;
  }

done:
  return gs_adaptive_end(n_out, row, t, st, stats, t_fail, out, y, y1);

fail:
  rc = gs_watch_failed(wk, rc, p, t_out, &row, &t, y, y1); /* an event left unwatched first */
  return gs_adaptive_end(rc, row, t, st, stats, t_fail, out, y, y1);
}
