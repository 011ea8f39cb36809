/* Start-up of a run launched without mpirun (terrace_mpi_env.f90): Open MPI then starts as a
 * "singleton". By default a singleton spawns a helper daemon and probes the UCX transport, which
 * costs about 0.3 s on a workstation, longer than a small run itself. A singleton talks to no one,
 * so before MPI_Init this sets two Open MPI defaults: no daemon (ess_singleton_isolated) and the
 * plain point-to-point layer (pml ob1). Both are set only when no launcher has started the process
 * (no mpirun, PMIx or PMI variables in the environment) and only where the user has not set them:
 * a value in the environment always wins. Other MPI libraries ignore OMPI_MCA_ variables.
 *
 * Isolated singletons all get the same job family, hence the same session directory under the
 * temporary directory; two running at once (a parameter scan, tests run in parallel) would share
 * it, and the files MPI-IO keeps there for an output (named after the output) would collide. So an
 * isolated singleton gets a session directory base of its own, $TMPDIR/terrace-ompi.<pid> (Open MPI
 * creates it and empties it at MPI_Finalize; it is removed at exit, with anything left in it). */
#define _XOPEN_SOURCE 700
#include <ftw.h>
#include <stdio.h>
#include <stdlib.h>
#include <unistd.h>

static char session_base[4096];

static int launched_by_a_launcher(void)
{
    static const char *const markers[] = {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK",
                                          "PMI_SIZE", "PMI_FD"};
    for (size_t i = 0; i < sizeof markers / sizeof markers[0]; ++i)
        if (getenv(markers[i]) != NULL) return 1;
    return 0;
}

static int remove_entry(const char *path, const struct stat *sb, int flag, struct FTW *ftw)
{
    (void)sb; (void)flag; (void)ftw;
    remove(path);
    return 0;
}

/* The base and what Open MPI left in it (it empties it at MPI_Finalize; a run that stops on an
 * error may not get there): at exit, and before an _exit that skips MPI_Finalize (errors.f90). */
void terrace_remove_session_base(void)
{
    if (session_base[0] != '\0') nftw(session_base, remove_entry, 16, FTW_DEPTH | FTW_PHYS);
}

void terrace_prepare_singleton(void)
{
    if (launched_by_a_launcher()) return;
    if (getenv("OMPI_MCA_ess_singleton_isolated") == NULL) {
        setenv("OMPI_MCA_ess_singleton_isolated", "1", 0);
        if (getenv("OMPI_MCA_orte_tmpdir_base") == NULL) {
            const char *tmp = getenv("TMPDIR");
            if (tmp == NULL || tmp[0] == '\0') tmp = "/tmp";
            int n = snprintf(session_base, sizeof session_base, "%s/terrace-ompi.%ld", tmp, (long)getpid());
            if (n > 0 && (size_t)n < sizeof session_base) {
                setenv("OMPI_MCA_orte_tmpdir_base", session_base, 0);
                atexit(terrace_remove_session_base);
            } else {
                session_base[0] = '\0';
            }
        }
    }
    setenv("OMPI_MCA_pml", "ob1", 0);
}
