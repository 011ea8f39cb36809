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
