/*
 * grasping_sym driver: a thin, fast C front end to CasADi-generated model code.
 *
 * The driver is a few C files (runtime/compiled.py: DRIVER_SOURCES) compiled next to
 * the CasADi-generated C file, each a separate translation unit of the same shared
 * library:
 *
 *   driver.c       this documentation; gs_info, gs_rhs, gs_rhs_batch, gs_outputs,
 *                  gs_outputs_batch, gs_con_info, gs_constraints
 *   project.c      gs_project (and gs_project_state, used by the integrators)
 *   rk4.c          gs_rk4
 *   radau5.c       gs_radau5 (radau5.h: its coefficients and tuning defaults;
 *                  jac.c: its Jacobian; lu.c: its real and complex LU)
 *   dopri5.c       gs_dopri5
 *   dop853.c       gs_dop853
 *   watch.c        gs_watch_witnesses, gs_watch_clear, gs_watch_result: witnesses watched along
 *                  gs_radau5 / gs_dopri5 / gs_dop853, which stop at their events
 *   stop.c         gs_stop_bind, gs_sigint_ensure, gs_set_time_limit, gs_stop_cause: Ctrl-C
 *                  (one handler for the process, runtime/interrupt.py) and a wall-time
 *                  limit stop the loops (GS_ERR_INTERRUPT)
 *   wrap.c         gs_wrap_set, gs_wrap_count, gs_wrap_cols: a contact's coordinates wrapped a period round
 *                  at the step inside gs_radau5 / gs_dopri5 / gs_dop853 (runtime/atlas.py)
 *   batch.c        gs_batch: many runs of gs_radau5 / gs_dopri5 / gs_dop853 / gs_rk4 in one
 *                  call, over a
 *                  pool of threads
 *   budget.c       gs_step_budget: a CasADi external that bounds a SUNDIALS run's steps in
 *                  total (gs_budget_begin, gs_budget_hit)
 *   gs_internal.h  what they share: the macro defaults and checks, error codes, GS_ST_*
 *                  indices, work arrays, the CasADi prototypes and the small helpers
 *   gs_driver.h    the gs_ prototypes used by pyfast.c, and the model's sizes
 *   lu_real.h      lu.c's real LU routines (included twice: any size, and unrolled)
 *
 * The model is read at run time: the library's link file (toolchain/objects.py: links_c),
 * compiled with the model's own C, defines hidden const ints for its sizes and features and
 * forwards fixed names to its functions, so that the driver's objects are compiled once per
 * set of work sizes (below) and serve models of any size and features:
 *
 *   gs_nx         number of states nx (>= 1)
 *   gs_np         number of parameters np (>= 0)
 *   gs_ny         number of outputs ny (0 without outputs)
 *   gs_out_time   1 when the outputs read the time (a last entry of p): only watch.c
 *                 calls them then, gs_info reports none and gs_outputs refuses
 *   gs_nc         number of constraints nc (>= 1 with constraints, else 0)
 *   gs_has_out, gs_has_jac, gs_has_con, gs_has_lanes
 *                 1 when the model has outputs, a compiled Jacobian, constraints, a
 *                 4-lane rhs; else 0, and the function below is a stub that fails
 *   gs_jac_nin, gs_jac_nout, gs_jac_block
 *                 the Jacobian's Function.n_in(), n_out() and the index of its output
 *                 d ode / d x (at most GS_SZ_ARG, GS_SZ_RES: checked by links_c)
 *
 * and the functions, under fixed names:
 *
 *   gs_model_rhs  the CasADi DAE right-hand side, inputs (t[1], x[nx], z[0], p[np], u[0]),
 *                 outputs (ode[nx], alg[0], quad[0], zero[0])
 *   gs_model_outputs   inputs (x[nx], p[np] or, with gs_out_time, p[np + 1]), output y[ny]
 *   gs_model_jac  CasADi's Function.jacobian() of the rhs: inputs (t, x, z, p, u, <nominal
 *                 outputs>...), outputs one block per (output, input) pair.  It is called
 *                 generically: all gs_jac_nin inputs are NULL except t (0), x (1) and p (3)
 *                 (CasADi reads a NULL input as zeros; the nominal outputs are structurally
 *                 unused), all gs_jac_nout results are NULL except block gs_jac_block =
 *                 d ode / d x (nx x nx), whose sparsity is read from
 *                 gs_model_jac_sparsity_out(gs_jac_block) (compressed column format [nrow,
 *                 ncol, colind[ncol+1], row[nnz]], or [nrow, ncol, 1] when dense) and
 *                 scattered into a dense matrix.  Without it gs_radau5 uses forward
 *                 differences of the rhs.
 *   gs_model_constraints  inputs (x[nx], p[np]), outputs C[nc] (position constraints, zero
 *                 on the motion), dC/dx (nc x nx), Cdot[nc] (d C / dt along the closed
 *                 loop), dCdot/dv (nc x nx: the speeds' columns of dCdot/dx, the others
 *                 unused); both Jacobians dense, column-major (CasADi's storage)
 *   gs_model_rhs_lanes  int f(const double* t, const double* const* x, const double* p,
 *                 double* const* xdot): the rhs at four (t[s], x[s]) at once (codegen/lanes.py),
 *                 bit-identical to four rhs calls; gs_radau5 evaluates its three stages with
 *                 one call
 *
 * The preprocessor macros passed with -D (the same for every file):
 *
 *   GS_SZ_ARG, GS_SZ_RES, GS_SZ_IW, GS_SZ_W
 *                 work sizes: at least the maximum over the model's functions of CasADi's
 *                 Function.sz_arg(), sz_res(), sz_iw(), sz_w() (objects.py rounds them up
 *                 to powers of two)                                  required
 *   GS_CASADI_INT integer type of CasADi's iw array       default long long int
 *                 (must match casadi_int of the generated file)
 *
 * Exported functions (all prefixed gs_, default visibility; helpers shared between the
 * files have hidden visibility):
 *
 *   int    gs_info(long* nx, long* np, long* ny);
 *   int    gs_rhs(const double* x, const double* p, double* xdot);
 *   int    gs_rhs_batch(long n, const double* X, const double* p, double* XDOT);
 *   int    gs_outputs(const double* x, const double* p, double* y);          (outputs)
 *   int    gs_outputs_batch(long n, const double* X, const double* p, double* Y); (outputs)
 *   long   gs_rk4(double t0, double h, long nsteps, long stride,
 *                 const double* x0, const double* p, const double* lo,
 *                 const double* hi, const int* proj_mask, double proj_tol, double* out,
 *                 double* stats, double* t_fail);
 *   long   gs_radau5(double t0, long n_out, const double* t_out, const double* x0,
 *                    const double* p, double rtol, double atol, double h0,
 *                    long max_steps, const double* lo, const double* hi,
 *                    const int* proj_mask, double proj_tol, double* out,
 *                    double* stats, double* t_fail);
 *   long   gs_dopri5(double t0, long n_out, const double* t_out, const double* x0,
 *                    const double* p, double rtol, double atol, double h0,
 *                    long max_steps, long nstiff, const double* lo, const double* hi,
 *                    const int* proj_mask, double proj_tol, double* out,
 *                    double* stats, double* t_fail);
 *   long   gs_dop853(...)  the arguments of gs_dopri5
 *   int    gs_con_info(long* nc);
 *   int    gs_constraints(const double* x, const double* p, double* C, double* JC,
 *                         double* Cd, double* JCd);                     (constraints)
 *   int    gs_project(double* x, const double* p, const int* mask, double tol,
 *                     double* stats);                                   (constraints)
 *
 * Tuning macros (optional, with defaults): GS_WORK_ON_STACK_MAX (gs_internal.h),
 * GS_PROJ_MAXIT (project.c), GS_RADAU_* (radau5.h), GS_DOPRI_* (dopri5.c).
 *
 * Return codes (GS_ERR_* in gs_internal.h): 0 (or a row count for gs_rk4 / gs_radau5 /
 * gs_dopri5) on success; GS_ERR_EVAL (-3) when the CasADi function reports an error;
 * see gs_rk4, gs_radau5, gs_dopri5 and gs_project for their codes; a function the model
 * lacks (gs_outputs without outputs, ...) returns GS_ERR_ARGS.
 *
 * Projection (proj_mask not NULL, needs constraints): after every accepted step (and, with
 * proj_tol > 0, at every dense-output time between steps; proj_tol < 0: the steps only, to
 * -proj_tol) the state is projected onto the constraints, see gs_project.  The stats array (GS_NSTATS doubles, see GS_ST_* in gs_internal.h)
 * counts the constraint evaluations and records the largest residuals found before
 * projecting.
 *
 * Thread safety: CasADi work arrays live on the stack of each exported call
 * (or in thread-local storage when they are large, see GS_WORK_ON_STACK_MAX),
 * so every gs_ function is reentrant and may be called from several threads
 * at once.  p may be NULL when gs_np == 0.
 */
#include "gs_internal.h"

/* The outputs are the caller's only when they do not read the time (gs_out_time: watch.c's). */
GS_EXPORT int gs_info(long* nx, long* np, long* ny) {
  const int out = gs_has_out && !gs_out_time;
  if (nx) *nx = gs_nx;
  if (np) *np = gs_np;
  if (ny) *ny = out ? gs_ny : -1;
  return out;
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
    int rc = gs_eval_rhs(wk, &t0, X + k * gs_nx, p, XDOT + k * gs_nx);
    if (rc) return rc;
  }
  return 0;
}

GS_EXPORT int gs_outputs(const double* x, const double* p, double* y) {
  GS_DECLARE_WORK(wk);
  if (!gs_has_out || gs_out_time) return GS_ERR_ARGS; /* none, or they would read p[np] */
  return gs_eval_out(wk, x, p, y);
}

GS_EXPORT int gs_outputs_batch(long n, const double* X, const double* p, double* Y) {
  GS_DECLARE_WORK(wk);
  if (n < 0 || !gs_has_out || gs_out_time) return GS_ERR_ARGS;
  for (long k = 0; k < n; ++k) {
    int rc = gs_eval_out(wk, X + k * gs_nx, p, Y + k * gs_ny);
    if (rc) return rc;
  }
  return 0;
}

/* A CasADi-generated function fn of (x, p) -> y (one of the model's helpers, runtime/compiled.py
 * CompiledLibrary.rows) at the n rows of X (n x nx), the same p, into Y (n x ny); its work
 * arrays arg, res, iw, w sized by the caller from fn's own _work. 0, or GS_ERR_EVAL. */
typedef int (*gs_casadi_fn)(const double** arg, double** res, GS_CASADI_INT* iw, double* w, int mem);

GS_EXPORT int gs_rows(void* fn, long n, const double* X, long nx, const double* p, double* Y, long ny,
                      const double** arg, double** res, GS_CASADI_INT* iw, double* w) {
  if (!fn || n < 0 || nx < 1 || ny < 1) return GS_ERR_ARGS;
  const gs_casadi_fn f = (gs_casadi_fn)fn;
  for (long k = 0; k < n; ++k) {
    arg[0] = X + k * nx;
    arg[1] = p;
    res[0] = Y + k * ny;
    if (f(arg, res, iw, w, 0)) return GS_ERR_EVAL;
  }
  return 0;
}

GS_EXPORT int gs_con_info(long* nc) {
  if (nc) *nc = gs_has_con ? gs_nc : -1;
  return gs_has_con;
}

GS_EXPORT int gs_constraints(const double* x, const double* p, double* C, double* JC,
                             double* Cd, double* JCd) {
  GS_DECLARE_WORK(wk);
  if (!gs_has_con) return GS_ERR_ARGS;
  return gs_eval_con(wk, x, p, C, JC, Cd, JCd);
}
