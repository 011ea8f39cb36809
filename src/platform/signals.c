/* Batch-job signals: SIGTERM and SIGUSR1 (what schedulers send before they kill a job) only set a
 * flag; the run polls it at safe points (terrace_signals.f90) and every rank stops together with a
 * checkpoint. Nothing else happens inside the handler (async-signal safety). */
#include <signal.h>
#include <string.h>

static volatile sig_atomic_t terrace_signal_flag = 0;

static void terrace_on_signal(int sig) { terrace_signal_flag = sig; }

/* Install the handler for SIGTERM and SIGUSR1. Returns 0 on success. */
int terrace_install_stop_handlers(void)
{
    struct sigaction sa;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = terrace_on_signal;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = SA_RESTART;
    if (sigaction(SIGTERM, &sa, NULL) != 0) return 1;
    if (sigaction(SIGUSR1, &sa, NULL) != 0) return 1;
    return 0;
}

/* The last stop signal received (0: none). */
int terrace_stop_signal(void) { return (int)terrace_signal_flag; }

/* Signal numbers, for the messages. */
int terrace_sigterm_number(void) { return SIGTERM; }
int terrace_sigusr1_number(void) { return SIGUSR1; }

/* Watchdog: alarm() with a handler that writes a prepared message,
 * removes the registered temporary files (terrace_cleanup_signal_safe, unlink only) and ends the
 * process with _exit(status). Used where a library call may never return: a parallel HDF5 write
 * that failed on this rank while the others wait in a collective inside HDF5 (mpirun then ends
 * the other ranks), and the analyser opening a damaged HDF5 file (HDF5 can spin on a damaged
 * global heap). Only async-signal-safe calls in the handler. */
#include <unistd.h>

void terrace_cleanup_signal_safe(void);

static char terrace_watchdog_msg[4096];
static size_t terrace_watchdog_len = 0;
static int terrace_watchdog_status = 1;

static void terrace_on_alarm(int sig)
{
    (void)sig;
    if (terrace_watchdog_len > 0) {
        ssize_t w = write(2, terrace_watchdog_msg, terrace_watchdog_len);
        (void)w;
    }
    terrace_cleanup_signal_safe();
    _exit(terrace_watchdog_status);
}

/* Arm: after `seconds`, print msg (len bytes, a newline is added) and exit with `status`.
 * Re-arming replaces the previous alarm. Returns 0 on success. */
int terrace_watchdog_arm(int seconds, const char *msg, int len, int status)
{
    struct sigaction sa;
    if (len < 0) len = 0;
    if ((size_t)len > sizeof terrace_watchdog_msg - 2) len = (int)sizeof terrace_watchdog_msg - 2;
    alarm(0);
    memcpy(terrace_watchdog_msg, msg, (size_t)len);
    terrace_watchdog_msg[len] = '\n';
    terrace_watchdog_len = len > 0 ? (size_t)len + 1 : 0;
    terrace_watchdog_status = status;
    memset(&sa, 0, sizeof sa);
    sa.sa_handler = terrace_on_alarm;
    sigemptyset(&sa.sa_mask);
    sa.sa_flags = 0;
    if (sigaction(SIGALRM, &sa, NULL) != 0) return 1;
    alarm((unsigned)seconds);
    return 0;
}

/* Disarm (the guarded call returned). */
void terrace_watchdog_disarm(void) { alarm(0); }

/* Test hook (TERRACE_TEST_STALL_RANK, terrace_hdf5_io): this process stops inside a write as a
 * process stuck in the kernel or on a file system that does not answer would, for `seconds`
 * (the watchdog of this or of another rank ends the job first). With block_alarm, SIGALRM is
 * ignored from then on (process-wide: blocking it in this thread alone would not do, MPI's own
 * threads would take it): this rank's watchdog cannot report, as when the rank cannot run at
 * all, so another rank must. Signals that interrupt the sleep do not end the stall. */
#include <time.h>

void terrace_test_stall(int seconds, int block_alarm)
{
    struct timespec left;
    if (block_alarm) signal(SIGALRM, SIG_IGN);
    left.tv_sec = seconds;
    left.tv_nsec = 0;
    while (nanosleep(&left, &left) != 0) {
    }
}
