/* Start-up of a run launched without mpirun (terrace_mpi_env.f90): Open MPI then starts as a
 * "singleton". By default a singleton spawns a helper daemon and probes the UCX transport, which
 * costs about 0.3 s on a workstation, longer than a small run itself. A singleton talks to no one,
 * so before MPI_Init this sets two Open MPI defaults: no daemon (ess_singleton_isolated) and the
 * plain point-to-point layer (pml ob1). Both are set only when no launcher has started the process
 * (no mpirun, PMIx or PMI variables in the environment) and only where the user has not set them:
 * a value in the environment always wins. Other MPI libraries ignore OMPI_MCA_ variables. */
#include <stdlib.h>

static int launched_by_a_launcher(void)
{
    static const char *const markers[] = {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK",
                                          "PMI_SIZE", "PMI_FD"};
    for (size_t i = 0; i < sizeof markers / sizeof markers[0]; ++i)
        if (getenv(markers[i]) != NULL) return 1;
    return 0;
}

void terrace_prepare_singleton(void)
{
    if (launched_by_a_launcher()) return;
    setenv("OMPI_MCA_ess_singleton_isolated", "1", 0);
    setenv("OMPI_MCA_pml", "ob1", 0);
}
