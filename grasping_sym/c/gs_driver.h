/*
 * grasping_sym driver interface: macro defaults and the gs_ functions of driver.c,
 * shared by driver.c and pyfast.c (the CPython fast-call front end).
 * The macros themselves are documented at the top of driver.c.
 */
#ifndef GS_DRIVER_H
#define GS_DRIVER_H

/* The model's sizes, read at run time: defined (hidden, const) by the library's link file,
 * which is compiled with the model's own C (toolchain/objects.py: links_c), so that one
 * build of the driver serves models of every size.  gs_ny is 0 without outputs, gs_nc 0
 * without constraints. */
extern __attribute__((visibility("hidden"))) const int gs_nx, gs_np, gs_ny, gs_nc;
/* 1 when the model's outputs read the time: they take p with one more last entry, t; the
 * driver then calls them only to watch witnesses (watch.c), and gs_outputs refuses. */
extern __attribute__((visibility("hidden"))) const int gs_out_time;
/* The model's features, read at run time too (the link file's): whether it has outputs, a
 * compiled Jacobian, constraints, a 4-lane rhs; the Jacobian's numbers of inputs and outputs
 * and the index of its block d ode / d x.  A function the model lacks is a stub there that
 * fails (its evaluation an error), never called: the driver asks these first, and its
 * exported functions refuse (GS_ERR_ARGS) what the model lacks.  So one build of the
 * driver serves models of every feature too. */
extern __attribute__((visibility("hidden"))) const int gs_has_out, gs_has_jac, gs_has_con,
    gs_has_lanes, gs_jac_nin, gs_jac_nout, gs_jac_block;

/* Length of the stats array of gs_rk4, gs_radau5, gs_dopri5 and gs_project. */
#define GS_NSTATS 16

int gs_rhs(const double* x, const double* p, double* xdot);
int gs_rhs_batch(long n, const double* X, const double* p, double* XDOT);
/* GS_ERR_ARGS without outputs (gs_has_out 0) or when they read the time */
int gs_outputs(const double* x, const double* p, double* y);
int gs_outputs_batch(long n, const double* X, const double* p, double* Y);
long gs_rk4(double t0, double h, long nsteps, long stride, const double* x0, const double* p,
            const double* lo, const double* hi, const int* proj_mask, double proj_tol,
            double* out, double* stats, double* t_fail);
long gs_radau5(double t0, long n_out, const double* t_out, const double* x0, const double* p,
               double rtol, double atol, double h0, long max_steps, const double* lo,
               const double* hi, const int* proj_mask, double proj_tol, double* out,
               double* stats, double* t_fail);
long gs_dopri5(double t0, long n_out, const double* t_out, const double* x0, const double* p,
               double rtol, double atol, double h0, long max_steps, long nstiff,
               const double* lo, const double* hi, const int* proj_mask, double proj_tol,
               double* out, double* stats, double* t_fail);
long gs_dop853(double t0, long n_out, const double* t_out, const double* x0, const double* p,
               double rtol, double atol, double h0, long max_steps, long nstiff,
               const double* lo, const double* hi, const int* proj_mask, double proj_tol,
               double* out, double* stats, double* t_fail);
int gs_con_info(long* nc);
/* GS_ERR_ARGS without constraints (gs_has_con 0) */
int gs_constraints(const double* x, const double* p, double* C, double* JC, double* Cd,
                   double* JCd);
int gs_project(double* x, const double* p, const int* mask, double tol, double* stats);

#endif /* GS_DRIVER_H */
