/*
 * grasping_sym driver: stopping a C integration loop from outside (c/driver.c lists the files).
 *
 *   Ctrl-C   gs_sigint_begin() installs a SIGINT handler that only sets a flag, and
 *            remembers the one it replaced (CPython's); gs_sigint_end() puts that back and
 *            says whether SIGINT arrived. Call both from the main thread around a loop.
 *   time     gs_set_time_limit(s) gives this thread's next loops s seconds of wall time
 *            (0: none).
 *
 * The loops call gs_stop_requested() once per step and return GS_ERR_INTERRUPT when it is
 * non-zero; gs_stop_cause() then says why (1: SIGINT, 2: the time limit). A step costs
 * microseconds, so a loop stops within a few of them; the clock is read every 16th step.
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

static void gs_on_sigint(int sig) {
  (void)sig;
  gs_sigint_flag = 1;
}

static double gs_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

GS_EXPORT int gs_sigint_begin(void) {
  struct sigaction sa;
  memset(&sa, 0, sizeof sa);
  sa.sa_handler = gs_on_sigint;
  sigemptyset(&sa.sa_mask);
  gs_sigint_flag = 0;
  if (sigaction(SIGINT, &sa, &gs_previous) != 0) return -1;
  gs_installed = 1;
  return 0;
}

GS_EXPORT int gs_sigint_end(void) {
  if (gs_installed) {
    sigaction(SIGINT, &gs_previous, NULL);
    gs_installed = 0;
  }
  int hit = (int)gs_sigint_flag;
  gs_sigint_flag = 0;
  return hit;
}

GS_EXPORT void gs_set_time_limit(double seconds) {
  gs_deadline = seconds > 0.0 ? gs_now() + seconds : 0.0;
  gs_ticks = 0;
  gs_cause = 0;
}

GS_EXPORT int gs_stop_cause(void) { return gs_cause; }

GS_HIDDEN int gs_stop_requested(void) {
  if (gs_sigint_flag) return gs_cause = 1;
  if (gs_deadline > 0.0 && (++gs_ticks & 15u) == 0 && gs_now() > gs_deadline) return gs_cause = 2;
  return 0;
}
