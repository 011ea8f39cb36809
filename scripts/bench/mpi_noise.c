/* How much a machine's ranks wait for each other, apart from any MD code: the price of one
 * synchronisation point per step on that machine.
 *
 *   mpicc -O2 -o mpi_noise scripts/bench/mpi_noise.c
 *   mpirun -np P [flags] ./mpi_noise [WORK_US [STEPS]]       (defaults 100 microseconds, 20000 steps)
 *
 * Every rank runs STEPS "steps" of a fixed compute kernel (a dependent chain of floating-point
 * operations calibrated on rank 0 to WORK_US microseconds) in five modes:
 *   work       the kernel alone (no MPI); per-step times on every rank give the machine's noise;
 *   +allreduce the kernel, then one MPI_Allreduce of one double (a list check, a thermostat sum);
 *   +halo      the kernel, then 6 MPI_Sendrecv of HALO_BYTES (default 24,000: 1,000 atoms' x) with
 *              the ranks +-1, +-2, +-4 (mod P), a stand-in for a halo exchange;
 *   allreduce  MPI_Allreduce alone (latency);
 *   halo       the 6 MPI_Sendrecv alone.
 * It prints the kernel's speed (iterations per microsecond, measured on rank 0 while every rank
 * measures its own: with all cores busy a turbo clock drops) and, per mode, the mean step time (the slowest rank's total over STEPS), and for "work" the
 * mean, 99th percentile and largest single step over all ranks. A step with a sync point costs at
 * least the slowest rank's kernel that step: the excess of "+allreduce" over "work" plus
 * "allreduce" is the machine's noise made visible by one sync point per step.
 */
#include <mpi.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static volatile double sink;

static double kernel(long n) {          /* a dependent chain: n iterations, no memory traffic */
    double a = 1.0000001, x = 0.5;
    for (long i = 0; i < n; i++) x = x * a + 1e-9;
    return x;
}

static int cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int main(int argc, char **argv) {
    MPI_Init(&argc, &argv);
    int rank, size;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Comm_size(MPI_COMM_WORLD, &size);
    double work_us = argc > 1 ? atof(argv[1]) : 100.0;
    long steps = argc > 2 ? atol(argv[2]) : 20000;
    const char *hb = getenv("HALO_BYTES");
    long halo = hb ? atol(hb) : 24000;
    if (work_us < 0 || steps < 10 || halo < 8) {
        if (rank == 0) fprintf(stderr, "mpi_noise: WORK_US >= 0, STEPS >= 10, HALO_BYTES >= 8\n");
        MPI_Abort(MPI_COMM_WORLD, 2);
    }
    /* calibrate on rank 0: iterations per microsecond */
    long n = 1000000;
    double t0 = MPI_Wtime(); sink = kernel(n); double t1 = MPI_Wtime();
    double per_us = n / ((t1 - t0) * 1e6);
    MPI_Bcast(&per_us, 1, MPI_DOUBLE, 0, MPI_COMM_WORLD);
    long iters = (long)(work_us * per_us);

    char *sbuf = malloc(halo), *rbuf = malloc(halo);
    double *st = malloc(sizeof(double) * steps);
    double *all = rank == 0 ? malloc(sizeof(double) * steps * size) : NULL;
    if (!sbuf || !rbuf || !st || (rank == 0 && !all)) MPI_Abort(MPI_COMM_WORLD, 3);
    memset(sbuf, 1, halo);
    const char *names[5] = {"work", "+allreduce", "+halo", "allreduce", "halo"};
    if (rank == 0)
        printf("mpi_noise: %d ranks, %ld steps, kernel %.1f us (%.1f iterations per us), halo %ld bytes x 6 per step\n",
               size, steps, work_us, per_us, halo);
    for (int mode = 0; mode < 5; mode++) {
        MPI_Barrier(MPI_COMM_WORLD);
        double start = MPI_Wtime();
        for (long s = 0; s < steps; s++) {
            double a = MPI_Wtime();
            if (mode <= 2) sink = kernel(iters);
            if (mode == 1 || mode == 3) {
                double in = a, out;
                MPI_Allreduce(&in, &out, 1, MPI_DOUBLE, MPI_MAX, MPI_COMM_WORLD);
            }
            if (mode == 2 || mode == 4) {
                for (int k = 1; k <= 4 && k < size; k *= 2)
                    for (int dir = -1; dir <= 1; dir += 2) {
                        int to = ((rank + dir * k) % size + size) % size, from = ((rank - dir * k) % size + size) % size;
                        MPI_Sendrecv(sbuf, (int)halo, MPI_BYTE, to, 7, rbuf, (int)halo, MPI_BYTE, from, 7,
                                     MPI_COMM_WORLD, MPI_STATUS_IGNORE);
                    }
            }
            st[s] = MPI_Wtime() - a;
        }
        double mine = MPI_Wtime() - start, slowest;
        MPI_Reduce(&mine, &slowest, 1, MPI_DOUBLE, MPI_MAX, 0, MPI_COMM_WORLD);
        if (mode == 0) {
            MPI_Gather(st, (int)steps, MPI_DOUBLE, all, (int)steps, MPI_DOUBLE, 0, MPI_COMM_WORLD);
            if (rank == 0) {
                long m = steps * size;
                double sum = 0;
                for (long i = 0; i < m; i++) sum += all[i];
                qsort(all, m, sizeof(double), cmp);
                printf("  %-11s %9.2f us per step (slowest rank); one rank's step: mean %.2f, p99 %.2f, max %.1f us\n",
                       names[mode], slowest / steps * 1e6, sum / m * 1e6, all[(long)(0.99 * (m - 1))] * 1e6,
                       all[m - 1] * 1e6);
            }
        } else if (rank == 0) {
            printf("  %-11s %9.2f us per step (slowest rank)\n", names[mode], slowest / steps * 1e6);
        }
    }
    free(sbuf); free(rbuf); free(st); free(all);
    MPI_Finalize();
    return 0;
}
