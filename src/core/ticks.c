/* A cheap clock for the per-phase timers (terrace_timers.f90). The phases of an event-driven run
 * are switched several times per event, a million times a second on a small system, and a call of
 * MPI_Wtime (clock_gettime behind a wrapper) costs 30-40 ns, a fifth of such an event. Where the
 * processor has an invariant time-stamp counter (CPUID 0x80000007, EDX bit 8: the counter runs at
 * a constant rate in every power state), the timers read it directly (about 10 ns); elsewhere
 * they read CLOCK_MONOTONIC in nanoseconds. Either way the timers convert ticks to seconds with
 * the rate measured over the run against the wall clock, so no frequency is assumed. */
#define _POSIX_C_SOURCE 199309L
#include <stdint.h>
#include <time.h>
#if defined(__x86_64__) || defined(__i386__)
#include <cpuid.h>
#include <x86intrin.h>
#define TERRACE_HAVE_TSC 1
#endif

static int use_tsc = -1; /* -1: not decided yet */

static int invariant_tsc(void)
{
#ifdef TERRACE_HAVE_TSC
    unsigned int a, b, c, d;
    if (__get_cpuid_max(0x80000000u, 0) < 0x80000007u) return 0;
    __cpuid(0x80000007u, a, b, c, d);
    return (d >> 8) & 1u;
#else
    return 0;
#endif
}

int64_t terrace_ticks(void)
{
    if (use_tsc < 0) use_tsc = invariant_tsc();
#ifdef TERRACE_HAVE_TSC
    if (use_tsc) return (int64_t)__rdtsc();
#endif
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (int64_t)t.tv_sec * 1000000000 + t.tv_nsec;
}
