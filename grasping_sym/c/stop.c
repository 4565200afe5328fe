/*
 * grasping_sym driver: stopping a C integration loop from outside (c/driver.c lists the files).
 *
 *   Ctrl-C   gs_sigint_install() (called once, from the main thread, when the library is
 *            loaded) puts a SIGINT handler in front of the process's (CPython's): it sets a
 *            flag and passes the signal on, so Python still raises KeyboardInterrupt.
 *   time     gs_set_time_limit(s) gives this thread's next loops s seconds of wall time
 *            (0: none).
 *
 * A loop calls gs_stop_reset() when it starts and gs_stop_requested() once per step, and
 * returns GS_ERR_INTERRUPT when that is non-zero; gs_stop_cause() then says why (1: SIGINT,
 * 2: the time limit). A step costs microseconds, so a loop stops within a few of them; the
 * clock is read every 16th step. Nothing is called per run from Python unless a time limit
 * is set. gs_batch (batch.c) shares one Ctrl-C and one deadline among its threads.
 */
#define _POSIX_C_SOURCE 200809L
#include <signal.h>
#include <string.h>
#include <time.h>

#include "gs_internal.h"

static volatile sig_atomic_t gs_sigint_flag = 0;
static struct sigaction gs_previous;
static int gs_installed = 0;
static _Thread_local double gs_deadline = 0.0;
static _Thread_local unsigned gs_ticks = 0;
static _Thread_local int gs_cause = 0;
/* Inside gs_batch (batch.c): a run's start must not clear a Ctrl-C that another thread's run
 * saw, so the batch clears the flag once and each run leaves it. */
static _Thread_local int gs_in_batch = 0;

/* Note the signal, then pass it on to the handler it replaced (CPython's, which makes the
 * interpreter raise KeyboardInterrupt when it next runs Python code). */
static void gs_on_sigint(int sig) {
  gs_sigint_flag = 1;
  if (gs_previous.sa_flags & SA_SIGINFO) {
    if (gs_previous.sa_sigaction) gs_previous.sa_sigaction(sig, NULL, NULL);
  } else if (gs_previous.sa_handler == SIG_DFL) {
    sigaction(SIGINT, &gs_previous, NULL);
    raise(sig);
  } else if (gs_previous.sa_handler != SIG_IGN && gs_previous.sa_handler) {
    gs_previous.sa_handler(sig);
  }
}

static double gs_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Install the SIGINT handler once (from the main thread, when the library is loaded). */
GS_EXPORT int gs_sigint_install(void) {
  if (gs_installed) return 0;
  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = gs_on_sigint;
  sigemptyset(&sa.sa_mask);
  if (sigaction(SIGINT, &sa, &gs_previous) != 0) return -1;
  gs_installed = 1;
  return 0;
}

GS_EXPORT void gs_set_time_limit(double seconds) {
  gs_deadline = seconds > 0.0 ? gs_now() + seconds : 0.0;
  gs_ticks = 0;
}

GS_EXPORT int gs_stop_cause(void) { return gs_cause; }

GS_HIDDEN void gs_stop_reset(void) {
  if (!gs_in_batch) gs_sigint_flag = 0;
  gs_cause = 0;
}

/* gs_batch: clear Ctrl-C once before its runs. */
GS_HIDDEN void gs_stop_batch_reset(void) { gs_sigint_flag = 0; }

/* gs_batch's threads: with `on`, this thread's runs belong to a batch whose wall-time limit
 * ends at the monotonic time `deadline` (0: none); without, they are single runs again. */
GS_HIDDEN void gs_stop_batch_thread(int on, double deadline) {
  gs_in_batch = on;
  gs_deadline = on ? deadline : 0.0;
  gs_ticks = 0;
}

GS_HIDDEN double gs_stop_now(void) { return gs_now(); }

/* Non-zero when Ctrl-C was pressed since the batch started (the batch stops its threads). */
GS_HIDDEN int gs_stop_sigint(void) { return gs_sigint_flag != 0; }

GS_HIDDEN int gs_stop_requested(void) {
  if (gs_sigint_flag) return gs_cause = 1;
  if (gs_deadline > 0.0 && (++gs_ticks & 15u) == 0 && gs_now() > gs_deadline) return gs_cause = 2;
  return 0;
}
