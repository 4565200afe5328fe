/*
 * grasping_sym driver: stopping a C integration loop from outside (c/driver.c lists the files).
 *
 *   Ctrl-C   One SIGINT handler for the whole process, whichever model libraries are loaded:
 *            runtime/interrupt.py binds every library, when it is loaded, to one flag and to
 *            one owner library's gs_sigint_ensure (gs_stop_bind). A loop's start calls the
 *            owner's gs_sigint_ensure, which looks at SIGINT's disposition (one sigaction
 *            call) and puts the owner's handler in front of it again when something replaced
 *            it (Python's signal.signal, a CasADi run, the user's own handler): the handler
 *            sets the flag and passes the signal on to the handler it found (Python's, which
 *            raises KeyboardInterrupt or calls the user's handler). A disposition of SIG_IGN
 *            (nohup, a background job, signal.signal(SIGINT, SIG_IGN)) or SIG_DFL is left
 *            alone: an ignored Ctrl-C stops nothing. Any thread may install and any thread
 *            may take the signal.
 *   time     gs_set_time_limit(s) gives this thread's next loops s seconds of wall time
 *            (0: none).
 *
 * A run clears the flag when it starts (runtime/interrupt.py's run_scope); a
 * loop calls gs_stop_reset() when it starts and gs_stop_requested() once per step, and
 * returns GS_ERR_INTERRUPT when that is non-zero; gs_stop_cause() then says why (1: SIGINT,
 * 2: the time limit). A step costs microseconds, so a loop stops within a few of them; the
 * clock is read every 16th step. gs_batch (batch.c) shares one Ctrl-C and one deadline
 * among its threads. A library that was never bound (gs_stop_bind) uses a flag of its own
 * and installs nothing.
 */
#define _XOPEN_SOURCE 700 /* sigaction, SA_SIGINFO, SA_RESTART, SA_ONSTACK */
#include <pthread.h>
#include <signal.h>
#include <string.h>
#include <time.h>

#include "gs_internal.h"

/* The flag the SIGINT handler sets, shared by every bound library (relaxed atomics: lock-free,
 * so safe in a signal handler, and read by every thread). */
static int gs_own_flag = 0;
static int* gs_flag = &gs_own_flag;
/* The owner's gs_sigint_ensure (NULL until bound: nothing is installed). */
static void (*gs_ensure)(void) = NULL;

/* The owner's state: the disposition its handler passes the signal on to. */
static struct sigaction gs_previous;
static pthread_mutex_t gs_install_lock = PTHREAD_MUTEX_INITIALIZER;

static _Thread_local double gs_deadline = 0.0;
static _Thread_local unsigned gs_ticks = 0;
static _Thread_local int gs_cause = 0;
/* Inside gs_batch (batch.c): the batch put the owner's handler in front once (gs_stop_batch_reset);
 * its runs' starts (on its threads) leave it. */
static _Thread_local int gs_in_batch = 0;

/* Note the signal, then pass it on to the disposition it was put in front of. */
static void gs_on_sigint(int sig, siginfo_t* info, void* context) {
  __atomic_store_n(gs_flag, 1, __ATOMIC_RELAXED);
  if (gs_previous.sa_flags & SA_SIGINFO) {
    if (gs_previous.sa_sigaction) gs_previous.sa_sigaction(sig, info, context);
  } else if (gs_previous.sa_handler != SIG_IGN && gs_previous.sa_handler != SIG_DFL &&
             gs_previous.sa_handler) {
    gs_previous.sa_handler(sig);
  }
}

static int gs_is_ours(const struct sigaction* sa) {
  return (sa->sa_flags & SA_SIGINFO) && sa->sa_sigaction == gs_on_sigint;
}

static int gs_is_function(const struct sigaction* sa) {
  if (sa->sa_flags & SA_SIGINFO) return sa->sa_sigaction != NULL;
  return sa->sa_handler != SIG_IGN && sa->sa_handler != SIG_DFL && sa->sa_handler != NULL;
}

/* Put this library's handler in front of SIGINT's disposition, unless it is there already or
 * the disposition is SIG_IGN or SIG_DFL (left alone). Returns 1 when the handler is in
 * place, 0 when the disposition was left alone, -1 when sigaction failed. */
GS_EXPORT int gs_sigint_ensure_status(void) {
  struct sigaction current;
  if (sigaction(SIGINT, NULL, &current) != 0) return -1;
  if (gs_is_ours(&current)) return 1;
  if (!gs_is_function(&current)) return 0;
  pthread_mutex_lock(&gs_install_lock);
  int status = 1;
  if (sigaction(SIGINT, NULL, &current) != 0) {
    status = -1;
  } else if (gs_is_function(&current) && !gs_is_ours(&current)) {
    struct sigaction sa, replaced;
    memset(&sa, 0, sizeof sa);
    sa.sa_sigaction = gs_on_sigint;
    sa.sa_flags = SA_SIGINFO | (current.sa_flags & (SA_RESTART | SA_ONSTACK));
    sigemptyset(&sa.sa_mask);
    gs_previous = current; /* our handler is not in place: no signal reads this meanwhile */
    if (sigaction(SIGINT, &sa, &replaced) != 0) {
      status = -1;
    } else if (!gs_is_ours(&replaced) && memcmp(&replaced, &current, sizeof current) != 0) {
      gs_previous = replaced; /* changed between the two calls: pass on to what we replaced */
    }
  } else if (!gs_is_ours(&current)) {
    status = 0;
  }
  pthread_mutex_unlock(&gs_install_lock);
  return status;
}

GS_EXPORT void gs_sigint_ensure(void) { (void)gs_sigint_ensure_status(); }

/* Share `flag` and the owner's `ensure` (gs_sigint_ensure of the library that owns SIGINT,
 * possibly this one). runtime/interrupt.py calls it once, when the library is loaded. */
GS_EXPORT void gs_stop_bind(int* flag, void (*ensure)(void)) {
  if (flag) gs_flag = flag;
  gs_ensure = ensure;
}

/* 1 when Ctrl-C was seen since the run started (the shared flag). */
GS_EXPORT int gs_stop_flag(void) { return __atomic_load_n(gs_flag, __ATOMIC_RELAXED); }

static double gs_now(void) {
  struct timespec ts;
  clock_gettime(CLOCK_MONOTONIC, &ts);
  return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

GS_EXPORT void gs_set_time_limit(double seconds) {
  gs_deadline = seconds > 0.0 ? gs_now() + seconds : 0.0;
  gs_ticks = 0;
}

GS_EXPORT int gs_stop_cause(void) { return gs_cause; }

/* A loop's start: the owner's handler put back in front. The flag is not cleared here: a run
 * clears it when it starts (runtime/interrupt.py's run_scope, for simulate and simulate_many;
 * a loop called outside any run, c_loops.stoppable), and a run of many loops (contact modes,
 * charts, an inputs table's knots, batches restarted at knots) reads it before each. Cleared at every loop's start, a Ctrl-C that came while
 * Python ran between two loops (under a handler of the user's that returns), or while another
 * thread's run was between its loops, was lost. */
GS_HIDDEN void gs_stop_reset(void) {
  if (!gs_in_batch && gs_ensure) gs_ensure();
  gs_cause = 0;
}

/* gs_batch's start: the owner's handler put back in front (the flag left, as gs_stop_reset). */
GS_HIDDEN void gs_stop_batch_reset(void) {
  if (gs_ensure) gs_ensure();
}

/* gs_batch's threads: with `on`, this thread's runs belong to a batch whose wall-time limit
 * ends at the monotonic time `deadline` (0: none); without, they are single runs again. */
GS_HIDDEN void gs_stop_batch_thread(int on, double deadline) {
  gs_in_batch = on;
  gs_deadline = on ? deadline : 0.0;
  gs_ticks = 0;
}

GS_HIDDEN double gs_stop_now(void) { return gs_now(); }

/* Non-zero when Ctrl-C was pressed since the batch started (the batch stops its threads). */
GS_HIDDEN int gs_stop_sigint(void) { return __atomic_load_n(gs_flag, __ATOMIC_RELAXED) != 0; }

GS_HIDDEN int gs_stop_requested(void) {
  if (__atomic_load_n(gs_flag, __ATOMIC_RELAXED)) return gs_cause = 1;
  if (gs_deadline > 0.0 && (++gs_ticks & 15u) == 0 && gs_now() > gs_deadline) return gs_cause = 2;
  return 0;
}
