/*
 * grasping_sym driver: a step budget for SUNDIALS runs (CVODES, IDAS through CasADi).
 *
 * SUNDIALS bounds its steps per output interval only (mxstep is reset by every CVode/IDASolve
 * call, one per output time), so a run with many outputs could take max_steps steps in each.
 * gs_step_budget is a CasADi external function, t -> 0, that runtime/integrators.py adds to
 * the right-hand side a SUNDIALS method integrates. It counts the distinct times it is called
 * at (one per step attempt: Newton iterations of a step share its time) and, once more than
 * the limit, fails: CasADi raises, SUNDIALS stops at once, and gs_budget_hit() says why.
 *
 *   gs_budget_begin(limit)   this thread's next run may attempt `limit` steps (0: no limit)
 *   gs_budget_count()        the step attempts counted since
 *   gs_budget_hit()          1 when the limit stopped the run, 2 when Ctrl-C or the wall-time
 *                            limit did (c/stop.c: gs_stop_cause() says which); then
 *                            gs_budget_last_t() is its time
 *
 * So a SUNDIALS run also stops on the C loops' wall-time limit (gs_set_time_limit), in any
 * thread, and on Ctrl-C where the library's SIGINT handler sees it.
 *
 * The state is thread-local: CasADi evaluates the function in the thread that calls the
 * integrator. jac_gs_step_budget is its derivative, structurally zero, so that CasADi's
 * Jacobian of the sum needs no finite differences.
 */
#include "gs_internal.h"

static _Thread_local long long gs_budget_limit = 0;
static _Thread_local long long gs_budget_n = 0;
static _Thread_local int gs_budget_started = 0;
static _Thread_local int gs_budget_stop = 0;
static _Thread_local double gs_budget_t = 0.0;

GS_EXPORT void gs_budget_begin(long long limit) {
  gs_budget_limit = limit > 0 ? limit : 0;
  gs_budget_n = 0;
  gs_budget_started = 0;
  gs_budget_stop = 0;
  gs_budget_t = 0.0;
  gs_stop_reset();
}

GS_EXPORT long long gs_budget_count(void) { return gs_budget_n; }
GS_EXPORT int gs_budget_hit(void) { return gs_budget_stop; }
GS_EXPORT double gs_budget_last_t(void) { return gs_budget_t; }

/* CasADi's external-function interface (the names CasADi looks up for "gs_step_budget"). */
static const GS_CASADI_INT gs_budget_scalar[5] = {1, 1, 0, 1, 0}; /* 1x1, dense */
static const GS_CASADI_INT gs_budget_zero[4] = {1, 1, 0, 0};      /* 1x1, no entry */

GS_EXPORT int gs_step_budget(const double** arg, double** res, GS_CASADI_INT* iw, double* w,
                             int mem) {
  (void)iw; (void)w; (void)mem;
  if (gs_budget_stop) return 1; /* stopped: every later call fails too, so SUNDIALS gives up */
  double t = (arg && arg[0]) ? arg[0][0] : 0.0;
  if (!gs_budget_started || t != gs_budget_t) {
    gs_budget_started = 1;
    gs_budget_t = t;
    gs_budget_n++;
  }
  if (gs_budget_limit > 0 && gs_budget_n > gs_budget_limit) {
    gs_budget_stop = 1;
    return 1;
  }
  if (gs_stop_requested()) {
    gs_budget_stop = 2;
    return 1;
  }
  if (res && res[0]) res[0][0] = 0.0;
  return 0;
}
GS_EXPORT GS_CASADI_INT gs_step_budget_n_in(void) { return 1; }
GS_EXPORT GS_CASADI_INT gs_step_budget_n_out(void) { return 1; }
GS_EXPORT const char* gs_step_budget_name_in(GS_CASADI_INT i) { return i == 0 ? "t" : 0; }
GS_EXPORT const char* gs_step_budget_name_out(GS_CASADI_INT i) { return i == 0 ? "zero" : 0; }
GS_EXPORT const GS_CASADI_INT* gs_step_budget_sparsity_in(GS_CASADI_INT i) {
  return i == 0 ? gs_budget_scalar : 0;
}
GS_EXPORT const GS_CASADI_INT* gs_step_budget_sparsity_out(GS_CASADI_INT i) {
  return i == 0 ? gs_budget_scalar : 0;
}
GS_EXPORT int gs_step_budget_work(GS_CASADI_INT* sz_arg, GS_CASADI_INT* sz_res,
                                  GS_CASADI_INT* sz_iw, GS_CASADI_INT* sz_w) {
  if (sz_arg) *sz_arg = 1;
  if (sz_res) *sz_res = 1;
  if (sz_iw) *sz_iw = 0;
  if (sz_w) *sz_w = 0;
  return 0;
}

/* Its Jacobian: inputs (t, the nominal output), output d zero / d t, structurally zero. */
GS_EXPORT int jac_gs_step_budget(const double** arg, double** res, GS_CASADI_INT* iw, double* w,
                                 int mem) {
  (void)arg; (void)res; (void)iw; (void)w; (void)mem;
  return 0;
}
GS_EXPORT GS_CASADI_INT jac_gs_step_budget_n_in(void) { return 2; }
GS_EXPORT GS_CASADI_INT jac_gs_step_budget_n_out(void) { return 1; }
GS_EXPORT const char* jac_gs_step_budget_name_in(GS_CASADI_INT i) {
  return i == 0 ? "t" : i == 1 ? "out_zero" : 0;
}
GS_EXPORT const char* jac_gs_step_budget_name_out(GS_CASADI_INT i) {
  return i == 0 ? "jac_zero_t" : 0;
}
GS_EXPORT const GS_CASADI_INT* jac_gs_step_budget_sparsity_in(GS_CASADI_INT i) {
  return (i == 0 || i == 1) ? gs_budget_scalar : 0;
}
GS_EXPORT const GS_CASADI_INT* jac_gs_step_budget_sparsity_out(GS_CASADI_INT i) {
  return i == 0 ? gs_budget_zero : 0;
}
GS_EXPORT int jac_gs_step_budget_work(GS_CASADI_INT* sz_arg, GS_CASADI_INT* sz_res,
                                      GS_CASADI_INT* sz_iw, GS_CASADI_INT* sz_w) {
  if (sz_arg) *sz_arg = 2;
  if (sz_res) *sz_res = 1;
  if (sz_iw) *sz_iw = 0;
  if (sz_w) *sz_w = 0;
  return 0;
}
