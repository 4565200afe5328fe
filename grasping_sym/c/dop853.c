/* grasping_sym driver: adaptive Dormand-Prince 8(5,3) with stiffness detection, gs_dop853. */
#include "gs_internal.h"

/* ========================================================================== */
/*  Dormand-Prince 8(5,3) with adaptive steps: gs_dop853                      */
/* ========================================================================== */
/*
 * Follows E. Hairer, S. P. Norsett, G. Wanner, "Solving Ordinary Differential Equations I:
 * Nonstiff Problems", 2nd ed., Springer 1993, Sec. II.5 and II.10, and their DOP853 code:
 * the explicit Runge-Kutta method of order 8 of Dormand and Prince (12 stages; the
 * derivative at the new point, needed anyway by the next step, is the 13th), its error
 * estimate built from embedded solutions of orders 5 and 3
 * (err = |e5|^2 / sqrt(|e5|^2 + 0.01 |e3|^2), scaled as DOP853 does), the step-size control
 * of DOP853 (exponent 1/8, safety 0.9, 1/3 <= h_new / h <= 6, no Lund stabilisation), the
 * continuous extension of order 7 (three more evaluations per step, made here only for a
 * step with an output time inside it) and DOP853's stiffness detection: h |lambda| is
 * estimated from the 12th stage and the new point, both at t + h, and a step whose estimate
 * exceeds 6.1 counts as stiff (15 of them, without 6 non-stiff steps in between, stop the
 * integration).  The coefficients are DOP853's (as SciPy's dop853_coefficients.py prints
 * them); the C code is our own.
 *
 * Against gs_dopri5 it spends twice the evaluations per step and takes far fewer steps at
 * tight tolerances; its stability region reaches about twice as far along the negative
 * real axis (6.1 against 3.3).
 */
#ifndef GS_DOP853_SAFE
#define GS_DOP853_SAFE 0.9
#endif
#ifndef GS_DOP853_FAC1
#define GS_DOP853_FAC1 0.333 /* h_new / h >= FAC1 */
#endif
#ifndef GS_DOP853_FAC2
#define GS_DOP853_FAC2 6.0 /* h_new / h <= FAC2 */
#endif
#ifndef GS_DOP853_STIFF_HLAMBDA
#define GS_DOP853_STIFF_HLAMBDA 6.1
#endif
#ifndef GS_DOP853_STIFF_COUNT
#define GS_DOP853_STIFF_COUNT 15
#endif
#ifndef GS_DOP853_NONSTIFF_RESET
#define GS_DOP853_NONSTIFF_RESET 6
#endif

/* Stage times c_s, s = 0..15 (12 stages, the new point's derivative, 3 for dense output). */
static const double gs_d8_c[16] = {0.0, 0.05260015195876773, 0.0789002279381516, 0.1183503419072274, 0.2816496580927726, 0.3333333333333333, 0.25, 0.3076923076923077, 0.6512820512820513, 0.6, 0.8571428571428571, 1.0, 1.0, 0.1, 0.2, 0.7777777777777778};
/* Stage coefficients a_sj, j < s (row s of the lower triangle), s = 1..15. */
static const double gs_d8_a[16][15] = {
  {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
  {0.05260015195876773, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
  {0.0197250569845379, 0.0591751709536137, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
  {0.02958758547680685, 0.0, 0.08876275643042054, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
  {0.2413651341592667, 0.0, -0.8845494793282861, 0.924834003261792, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
  {0.037037037037037035, 0.0, 0.0, 0.17082860872947386, 0.12546768756682242, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
  {0.037109375, 0.0, 0.0, 0.17025221101954405, 0.06021653898045596, -0.017578125, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
  {0.03709200011850479, 0.0, 0.0, 0.17038392571223998, 0.10726203044637328, -0.015319437748624402, 0.008273789163814023, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
  {0.6241109587160757, 0.0, 0.0, -3.3608926294469414, -0.868219346841726, 27.59209969944671, 20.154067550477894, -43.48988418106996, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
  {0.47766253643826434, 0.0, 0.0, -2.4881146199716677, -0.590290826836843, 21.230051448181193, 15.279233632882423, -33.28821096898486, -0.020331201708508627, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0},
  {-0.9371424300859873, 0.0, 0.0, 5.186372428844064, 1.0914373489967295, -8.149787010746927, -18.52006565999696, 22.739487099350505, 2.4936055526796523, -3.0467644718982196, 0.0, 0.0, 0.0, 0.0, 0.0},
  {2.273310147516538, 0.0, 0.0, -10.53449546673725, -2.0008720582248625, -17.9589318631188, 27.94888452941996, -2.8589982771350235, -8.87285693353063, 12.360567175794303, 0.6433927460157636, 0.0, 0.0, 0.0, 0.0},
  {0.054293734116568765, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003, -5.801203960010585, 0.3111643669578199, -0.1521609496625161, 0.20136540080403034, 0.04471061572777259, 0.0, 0.0, 0.0},
  {0.056167502283047954, 0.0, 0.0, 0.0, 0.0, 0.0, 0.25350021021662483, -0.2462390374708025, -0.12419142326381637, 0.15329179827876568, 0.00820105229563469, 0.007567897660545699, -0.008298, 0.0, 0.0},
  {0.03183464816350214, 0.0, 0.0, 0.0, 0.0, 0.028300909672366776, 0.053541988307438566, -0.05492374857139099, 0.0, 0.0, -0.00010834732869724932, 0.0003825710908356584, -0.00034046500868740456, 0.1413124436746325, 0.0},
  {-0.42889630158379194, 0.0, 0.0, 0.0, 0.0, -4.697621415361164, 7.683421196062599, 4.06898981839711, 0.3567271874552811, 0.0, 0.0, 0.0, -0.0013990241651590145, 2.9475147891527724, -9.15095847217987},
};
/* The eighth-order solution's weights b_j, j = 0..11. */
static const double gs_d8_b[12] = {0.054293734116568765, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003, -5.801203960010585, 0.3111643669578199, -0.1521609496625161, 0.20136540080403034, 0.04471061572777259};
/* Error estimates of orders 5 and 3: weights of k_0..k_11. */
static const double gs_d8_e5[12] = {0.01312004499419488, 0.0, 0.0, 0.0, 0.0, -1.2251564463762044, -0.4957589496572502, 1.6643771824549864, -0.35032884874997366, 0.3341791187130175, 0.08192320648511571, -0.022355307863886294};
static const double gs_d8_e3[12] = {-0.18980075407240762, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003, -5.801203960010585, -0.4226823213237919, -0.1521609496625161, 0.20136540080403034, 0.02265179219836082};
/* Dense output: the four highest coefficients' weights of k_0..k_15. */
static const double gs_d8_d[4][16] = {
  {-8.428938276109013, 0.0, 0.0, 0.0, 0.0, 0.5667149535193777, -3.0689499459498917, 2.38466765651207, 2.117034582445028, -0.871391583777973, 2.2404374302607883, 0.6315787787694688, -0.08899033645133331, 18.148505520854727, -9.194632392478356, -4.436036387594894},
  {10.427508642579134, 0.0, 0.0, 0.0, 0.0, 242.28349177525817, 165.20045171727028, -374.5467547226902, -22.113666853125306, 7.733432668472264, -30.674084731089398, -9.332130526430229, 15.697238121770845, -31.139403219565178, -9.35292435884448, 35.81684148639408},
  {19.985053242002433, 0.0, 0.0, 0.0, 0.0, -387.0373087493518, -189.17813819516758, 527.8081592054236, -11.57390253995963, 6.8812326946963, -1.0006050966910838, 0.7777137798053443, -2.778205752353508, -60.19669523126412, 84.32040550667716, 11.99229113618279},
  {-25.69393346270375, 0.0, 0.0, 0.0, 0.0, -154.18974869023643, -231.5293791760455, 357.6391179106141, 93.40532418362432, -37.45832313645163, 104.0996495089623, 29.8402934266605, -43.53345659001114, 96.32455395918828, -39.17726167561544, -149.72683625798564},
};

/* ys = y + h sum_{j < s} a_sj k_j */
static inline void gs_d8_stage(int s, double h, const double* y, const int n, double k[][n],
                               double* ys) {
  for (int i = 0; i < n; ++i) ys[i] = 0.0;
  for (int j = 0; j < s; ++j) {
    const double a = gs_d8_a[s][j];
    if (a == 0.0) continue;
    for (int i = 0; i < n; ++i) ys[i] += a * k[j][i];
  }
  for (int i = 0; i < n; ++i) ys[i] = y[i] + h * ys[i];
}

/*
 * Adaptive Dormand-Prince 8(5,3) integration of x' = f(t, x, p), see the comment above.
 *
 * Arguments, outputs and return codes as gs_dopri5 (the outputs between steps come from the
 * continuous extension of order 7; stats [13] the last estimate of h |lambda|, [14] the
 * number of stiffness tests above 6.1).
 */
/* The continuous extension's coefficients (7 rows of n, into d) of the step of size h from
 * (t, y) to y1 (unprojected), its stages k[0 .. 12] (k[12] at the unprojected y1): three more
 * stages (into k[13 .. 15], scratch ys). Returns 0 or an evaluation's error code. */
static int gs_dop853_dense_make(gs_work* wk, double t, double h, const double* y, const double* y1,
                                const double* p, double (*k)[gs_nx], double* ys, double* d) {
  const int n = gs_nx;
  int rc;
  for (int s = 13; s < 16; ++s) {
    const double ts = t + gs_d8_c[s] * h;
    gs_d8_stage(s, h, y, n, k, ys);
    if ((rc = gs_eval_rhs(wk, &ts, ys, p, k[s]))) return rc;
  }
  for (int i = 0; i < n; ++i) {
    const double dy = y1[i] - y[i], bspl = h * k[0][i] - dy;
    d[i] = dy;
    d[n + i] = bspl;
    d[2 * n + i] = dy - h * k[12][i] - bspl;
    for (int r = 0; r < 4; ++r) {
      double acc = 0.0;
      for (int j = 0; j < 16; ++j) acc += gs_d8_d[r][j] * k[j][i];
      d[(3 + r) * n + i] = h * acc;
    }
  }
  return 0;
}

/* The continuous extension of the step just accepted: its start y0 and d (7 rows of n).
 * For the watch alone (no output row inside the step) d is made at the first point asked
 * for (lazy: the unprojected end y1u and its stage k12u kept, the step's stages in k), its
 * error code in rc; a point at the step's start is y0 itself. */
typedef struct {
  const double* y0;
  double* d;
  double told, hsol;
  int ready, rc;
  gs_work* wk;
  const double *p, *y1u, *k12u;
  double *k, *ys, *st; /* k: the step's 16 stages, row by row (double[16][n]) */
} gs_dop853_dense;

static void gs_dop853_interp(const void* ctx, double t, double* x) {
  gs_dop853_dense* c = (gs_dop853_dense*)ctx;
  const int n = gs_nx;
  const double* y = c->y0;
  if (t == c->told) {
    for (int i = 0; i < n; ++i) x[i] = y[i];
    return;
  }
  if (!c->ready) { /* the stages at the unprojected end: k[12] as the step left it */
    double(*k)[n] = (double(*)[n])c->k;
    double k12[n];
    for (int i = 0; i < n; ++i) {
      k12[i] = k[12][i];
      k[12][i] = c->k12u[i];
    }
    c->rc = gs_dop853_dense_make(c->wk, c->told, c->hsol, y, c->y1u, c->p, k, c->ys, c->d);
    for (int i = 0; i < n; ++i) k[12][i] = k12[i];
    c->st[GS_ST_RHS] += 3;
    c->ready = 1;
  }
  if (c->rc) { /* an evaluation failed: a NaN state, which every witness takes as past it */
    for (int i = 0; i < n; ++i) x[i] = NAN;
    return;
  }
  const double* d = c->d;
  const double s = (t - c->told) / c->hsol, s1 = 1.0 - s;
  for (int i = 0; i < n; ++i)
    x[i] = y[i] + s * (d[i] + s1 * (d[n + i] + s * (d[2 * n + i] + s1 * (d[3 * n + i] + s * (
           d[4 * n + i] + s1 * (d[5 * n + i] + s * d[6 * n + i]))))));
}

GS_EXPORT long gs_dop853(double t0, long n_out, const double* t_out, const double* x0,
                         const double* p, double rtol, double atol, double h0, long max_steps,
                         long nstiff, const double* lo, const double* hi, const int* proj_mask,
                         double proj_tol, double* out, double* stats, double* t_fail) {
  const int n = gs_nx;
  GS_DECLARE_WORK(wk);
  double y[n], y1[n], ys[n], ystiff[n], scale[n], dense[7][n], y1u[n], k12u[n], ylazy[n];
  double k[16][n];
  double st[GS_NSTATS] = {0};
  long row = 0;
  int rc = 0, reject = 0, last = 0, iasti = 0, nonsti = 0;
  double t = t0, h;
  const double t_end = t_out ? t_out[n_out > 0 ? n_out - 1 : 0] : t0;
  const double expo1 = 1.0 / 8.0;

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

  if ((rc = gs_start_rhs(wk, t, y, p, k[0], st, y1))) goto fail;
  if (h0 > 0.0)
    h = fmin(h0, interval);
  else if ((rc = gs_initial_step(wk, t0, y, k[0], p, rtol, atol, interval, 7, 100.0, st, &h)))
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
    const double tph = last ? t_end : t + h;
    /* Stages 1..11; stage 11 is at t + h (its state kept for the stiffness test). */
    for (int s = 1; s < 12; ++s) {
      const double ts = s == 11 ? tph : t + gs_d8_c[s] * h;
      gs_d8_stage(s, h, y, n, k, s == 11 ? ystiff : ys);
      if ((rc = gs_eval_rhs(wk, &ts, s == 11 ? ystiff : ys, p, k[s]))) goto fail;
    }
    st[GS_ST_RHS] += 11;
    /* The eighth-order solution and the error estimate. */
    double err5 = 0.0, err3 = 0.0;
    for (int i = 0; i < n; ++i) {
      double b = 0.0, e5 = 0.0, e3 = 0.0;
      for (int j = 0; j < 12; ++j) {
        b += gs_d8_b[j] * k[j][i];
        e5 += gs_d8_e5[j] * k[j][i];
        e3 += gs_d8_e3[j] * k[j][i];
      }
      y1[i] = y[i] + h * b;
      scale[i] = atol + fmax(fabs(y[i]), fabs(y1[i])) * rtol;
      e5 /= scale[i];
      e3 /= scale[i];
      err5 += e5 * e5;
      err3 += e3 * e3;
    }
    double deno = err5 + 0.01 * err3;
    if (deno <= 0.0) deno = 1.0;
    const double err = fabs(h) * err5 * sqrt(1.0 / (n * deno));
    if (!isfinite(err)) { /* a stage left the region where f is finite: shrink */
      h *= GS_DOP853_FAC1;
      reject = 1;
      last = 0;
      st[GS_ST_REJECTED] += 1;
      continue;
    }
    const double fac11 = pow(err, expo1);
    const double fac = fmax(1.0 / GS_DOP853_FAC2, fmin(1.0 / GS_DOP853_FAC1, fac11 / GS_DOP853_SAFE));
    double hnew = h / fac;
    if (!(err <= 1.0)) { /* rejected */
      h /= fmin(1.0 / GS_DOP853_FAC1, fac11 / GS_DOP853_SAFE);
      reject = 1;
      last = 0;
      st[GS_ST_REJECTED] += 1;
      continue;
    }

    /* Accepted: the derivative at the new point (the next step's first stage). */
    st[GS_ST_STEPS] += 1;
    if ((rc = gs_eval_rhs(wk, &tph, y1, p, k[12]))) goto fail;
    st[GS_ST_RHS] += 1;
    if (nstiff > 0 && (((long)st[GS_ST_STEPS]) % nstiff == 0 || iasti > 0)) {
      double stnum = 0.0, stden = 0.0;
      for (int i = 0; i < n; ++i) {
        stnum += (k[12][i] - k[11][i]) * (k[12][i] - k[11][i]);
        stden += (y1[i] - ystiff[i]) * (y1[i] - ystiff[i]);
      }
      if (stden > 0.0) st[GS_ST_HLAMBDA] = h * sqrt(stnum / stden);
      if (st[GS_ST_HLAMBDA] > GS_DOP853_STIFF_HLAMBDA) {
        nonsti = 0;
        st[GS_ST_STIFF] += 1;
        if (++iasti == GS_DOP853_STIFF_COUNT) {
          rc = GS_ERR_STIFF;
          goto fail;
        }
      } else if (++nonsti == GS_DOP853_NONSTIFF_RESET) {
        iasti = 0;
      }
    }
    /* Continuous extension of the unprojected step, made now when an output lies inside it:
     * three more stages, then y(t + s h) = y + s (d0 + (1-s) (d1 + s (d2 + (1-s) (d3 +
     * s (d4 + (1-s) (d5 + s d6)))))). For the watch alone, made at its first point inside
     * the step (gs_dop853_interp): the unprojected end and its stage kept for it. */
    const int inside = row < n_out && t_out[row] < tph;
    if (inside) {
      if ((rc = gs_dop853_dense_make(wk, t, h, y, y1, p, k, ys, &dense[0][0]))) goto fail;
      st[GS_ST_RHS] += 3;
    } else if (gs_watching()) {
      for (int i = 0; i < n; ++i) {
        y1u[i] = y1[i];
        k12u[i] = k[12][i];
      }
    }
    if ((rc = gs_check(y1, lo, hi))) {
      double* kept[1] = {y1u}; /* the lazy extension's end, when kept */
      const int w = rc == GS_ERR_BOUNDS ? gs_wrap_step(wk, t, y, y1, p, lo, hi, kept, !inside && gs_watching()) : 0;
      if (!w) goto fail;
      rc = 0; /* 1: a contact's coordinate a period round (wrap.c): dense[] are differences */
      if (w == 2) { /* a chart's change: y mapped at t; the step not taken, the loop anew */
        st[GS_ST_STEPS] -= 1;
        st[GS_ST_REJECTED] += 1;
        if ((rc = gs_start_rhs(wk, t, y, p, k[0], st, y1))) goto fail;
        last = 0;
        reject = 0;
        continue;
      }
    }
    {
      int changed = 0;
      GS_PROJECT_STEP(y1, &changed);
      if (changed) { /* the next step starts from f at the projected state */
        if ((rc = gs_eval_rhs(wk, &tph, y1, p, k[12]))) goto fail;
        st[GS_ST_RHS] += 1;
      }
    }
    for (int i = 0; i < n; ++i)
      if (!isfinite(k[12][i])) {
        rc = GS_ERR_NONFINITE;
        goto fail;
      }
    const double told = t, hsol = h;
    t = tph;
    st[GS_ST_HLAST] = h;
    int event = 0;
    double t_ev = t;
    if (gs_watching()) {
      gs_dop853_dense dn = {y, &dense[0][0], told, hsol, inside, 0, wk, p, y1u, k12u, &k[0][0], ylazy, st};
      event = gs_watch_step(wk, told, t, y1, p, gs_dop853_interp, &dn, &t_ev, ys);
      if (event >= 0 && dn.rc) event = dn.rc; /* the lazy extension's evaluation failed */
      if (event < 0) {
        rc = event;
        goto fail;
      }
      while (event == 2 && row > 0 && t_out[row - 1] >= t_ev) --row; /* an earlier step's */
    }
    while (row < n_out && (event ? t_out[row] < t_ev : t_out[row] <= t)) {
      double* o = out + row * n;
      if (t_out[row] == t) {
        for (int i = 0; i < n; ++i) o[i] = y1[i];
      } else {
        const double s = (t_out[row] - told) / hsol, s1 = 1.0 - s;
        for (int i = 0; i < n; ++i)
          o[i] = y[i] + s * (dense[0][i] + s1 * (dense[1][i] + s * (dense[2][i] + s1 * (
                 dense[3][i] + s * (dense[4][i] + s1 * (dense[5][i] + s * dense[6][i]))))));
        if (proj_rows && (rc = gs_project_state(wk, o, p, proj_mask, proj_tol, st, NULL))) {
          for (int i = 0; i < n; ++i) y1[i] = o[i];
          goto fail;
        }
      }
      ++row;
    }
    if (event) { /* stop at the event: its state, and its step's start (gs_adaptive_end) */
      for (int i = 0; i < n; ++i) {
        y1[i] = y[i];
        y[i] = ys[i];
      }
      if (event == 2) gs_watch_event_start(y1);
      t = t_ev;
      rc = GS_EVENT;
      goto fail;
    }
    for (int i = 0; i < n; ++i) {
      y[i] = y1[i];
      k[0][i] = k[12][i];
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
