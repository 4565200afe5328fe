/*
 * grasping_sym driver interface: macro defaults and the gs_ functions of driver.c,
 * shared by driver.c and pyfast.c (the CPython fast-call front end).
 * The macros themselves are documented at the top of driver.c.
 */
#ifndef GS_DRIVER_H
#define GS_DRIVER_H

#ifndef GS_HAS_OUT
#define GS_HAS_OUT 0
#endif
#ifndef GS_HAS_CON
#define GS_HAS_CON 0
#endif

/* The model's sizes, read at run time: defined (hidden, const) by the library's link file,
 * which is compiled with the model's own C (toolchain/objects.py: links_c), so that one
 * build of the driver serves models of every size.  gs_ny is 0 without outputs, gs_nc 0
 * without constraints. */
extern __attribute__((visibility("hidden"))) const int gs_nx, gs_np, gs_ny, gs_nc;
/* 1 when the model's outputs read the time: they take p with one more last entry, t; the
 * driver then calls them only to watch witnesses (watch.c), and gs_outputs refuses. */
extern __attribute__((visibility("hidden"))) const int gs_out_time;

/* Length of the stats array of gs_rk4, gs_radau5, gs_dopri5 and gs_project. */
#define GS_NSTATS 16

int gs_rhs(const double* x, const double* p, double* xdot);
int gs_rhs_batch(long n, const double* X, const double* p, double* XDOT);
#if GS_HAS_OUT
int gs_outputs(const double* x, const double* p, double* y);
int gs_outputs_batch(long n, const double* X, const double* p, double* Y);
#endif
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
#if GS_HAS_CON
int gs_constraints(const double* x, const double* p, double* C, double* JC, double* Cd,
                   double* JCd);
int gs_project(double* x, const double* p, const int* mask, double tol, double* stats);
#endif

#endif /* GS_DRIVER_H */
