/* Signal handlers for stop_request (src/run/stop_request.f90). A handler may only do
 * async-signal-safe things, so it records the signal number in a flag and returns; the run
 * loops read the flag at points where every rank can agree to stop (docs/output.md,
 * "Stopping a run"). C because Fortran cannot write a signal handler portably. */
#include <signal.h>
#include <string.h>

static volatile sig_atomic_t stop_signal_number = 0;

static void record_stop_signal(int signal_number) { stop_signal_number = signal_number; }

/* SIGTERM and SIGINT set the flag. SA_RESETHAND puts the default action back after the
 * first one, so a second Ctrl-C (or a scheduler's second SIGTERM) ends the run at once.
 * SA_RESTART: writes in progress are not cut short by EINTR. SIGXFSZ is ignored so that a
 * file-size limit (ulimit -f) makes write() fail with EFBIG, which the writers report
 * naming the file, instead of killing the process with a core dump. Returns 0 on success. */
int ricochet_install_stop_handlers(void) {
  struct sigaction action;
  memset(&action, 0, sizeof action);
  action.sa_handler = record_stop_signal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESETHAND | SA_RESTART;
  if (sigaction(SIGTERM, &action, NULL) != 0) return 1;
  if (sigaction(SIGINT, &action, NULL) != 0) return 1;
  if (signal(SIGXFSZ, SIG_IGN) == SIG_ERR) return 1;
  return 0;
}

/* The number of the stop signal received (0: none yet). */
int ricochet_stop_signal(void) { return (int)stop_signal_number; }

/* Ends the process at once with `code`, skipping atexit handlers and MPI_Finalize: after a
 * failed write HDF5 1.10 keeps the file it could not close and crashes (SIGSEGV) closing it
 * again in its own clean-up at MPI_Finalize. Used only on the way out after an I/O error,
 * once the error line is written and flushed. */
#include <unistd.h>
void ricochet_exit_now(int code) { _exit(code); }
