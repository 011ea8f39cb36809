/* Driver of scripts/bench/lj_pass_floor.sh: the fused LJ force pass of src/potentials/lj_simd.c
 * (terrace_lj_one_type, linked from a variant the script makes) timed alone on the argon job's
 * geometry: 864 atoms (fcc 6 x 6 x 6 cells, each atom displaced up to 0.3 A, seeded), box 34.6809 A,
 * periodic images as ghosts after the owned atoms, LJ 8.5 A, list cutoff 8.5 + 0.6 A (the deck's
 * pruned list). Half list (argument 0): owned pairs i < j and ghost pairs of the upper 13 of the 26
 * image shifts, each pair once; full list (argument 1): every partner of every owned atom.
 * Argument 2: the mixed-precision pass of src/potentials/lj_mixed_simd.c over the half list instead
 * (terrace_lj_mixed: each pass stages the positions and adds its single force records to f; the
 * list's offsets formed once, as the engine forms them once per list).
 * Prints the list length, its pairs within the cutoff and their share of the pass's lanes (eight per
 * block, sixteen in the mixed pass, whose last block of a row holds eight lanes where it has eight
 * pairs or fewer; with AVX2 and no AVX-512 four and eight, a last mixed block of four; an atom's last
 * block padded), and the pass's cost per pair of the half list (a full
 * list's pass does every pair twice): median and range of 7 batches of 400 passes.
 * Usage: lj_pass_floor_VARIANT 0|1|2 */
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include <time.h>
#include <stdint.h>

int terrace_lj_one_type(int nlocal, const double *x, double *f, const int *first, const int *neigh, double lj1,
                        double lj2, double lj3, double lj4, double cutsq, double offset, int want_energy,
                        double *atom_e, double *virial);
int terrace_row_offsets(int nlocal, int nrec, const int *first, const int *neigh, int wrapped, const int *origin,
                             int *ofirst, int32_t *offs);
int terrace_lj_mixed(int nlocal, int nall, const double *x, double *f, int32_t *q, float *ff, const int *first,
                     const int *ofirst, const int32_t *offs, const double *c, int want_energy, int wrapped,
                     const double *wrap, double *atom_e, double *virial);

static double now(void)
{
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + 1e-9 * t.tv_nsec;
}

static int cmp(const void *a, const void *b)
{
    double u = *(const double *)a, v = *(const double *)b;
    return (u > v) - (u < v);
}

int main(int argc, char **argv)
{
    const int full = argc > 1 && atoi(argv[1]) == 1, mixed = argc > 1 && atoi(argv[1]) == 2;
    const int nc = 6, n = 4 * nc * nc * nc;
    const double box = 34.6809019, a = box / nc, rc = 8.5, rl = 9.1;
    const double basis[4][3] = {{0, 0, 0}, {0.5, 0.5, 0}, {0.5, 0, 0.5}, {0, 0.5, 0.5}};
    double *x = malloc(sizeof(double) * 3 * 27 * n);
    int *shift = malloc(sizeof(int) * 27 * n);
    unsigned s = 12345u;
    int m = 0;
    for (int iz = 0; iz < nc; iz++)
        for (int iy = 0; iy < nc; iy++)
            for (int ix = 0; ix < nc; ix++)
                for (int q = 0; q < 4; q++) {
                    const int c[3] = {ix, iy, iz};
                    for (int d = 0; d < 3; d++) {
                        s = s * 1103515245u + 12345u;
                        x[3 * m + d] = (c[d] + basis[q][d]) * a + 0.6 * ((s >> 8) / 16777216.0 - 0.5);
                    }
                    shift[m++] = 13;
                }
    for (int sh = 0; sh < 27; sh++) {      /* the images within the list cutoff of the box */
        if (sh == 13) continue;
        const int o[3] = {sh % 3 - 1, (sh / 3) % 3 - 1, sh / 9 - 1};
        for (int i = 0; i < n; i++) {
            int inside = 1;
            double p[3];
            for (int d = 0; d < 3; d++) {
                p[d] = x[3 * i + d] + o[d] * box;
                if (p[d] < -rl || p[d] >= box + rl) inside = 0;
            }
            if (!inside) continue;
            for (int d = 0; d < 3; d++) x[3 * m + d] = p[d];
            shift[m++] = sh;
        }
    }
    int *first = malloc(sizeof(int) * (n + 1)), *neigh = malloc(sizeof(int) * 200 * n);
    long np = 0;
    for (int i = 0; i < n; i++) {
        first[i] = (int)np + 1;
        for (int j = 0; j < m; j++) {
            if (j == i) continue;
            if (!full && ((j < n && j < i) || (j >= n && shift[j] < 13))) continue;
            const double dx = x[3 * i] - x[3 * j], dy = x[3 * i + 1] - x[3 * j + 1], dz = x[3 * i + 2] - x[3 * j + 2];
            if (dx * dx + dy * dy + dz * dz < rl * rl) neigh[np++] = j + 1;
        }
    }
    first[n] = (int)np + 1;
#if defined(__AVX512F__)
    const int lanes = mixed ? 16 : 8;
#else   /* (AVX2: lj_pass4 and the mixed pass's rows of eight) */
    const int lanes = mixed ? 8 : 4;
#endif
    long blocks = 0, within = 0, lanes_used = 0;   /* the pass's blocks and lanes, its pairs within rc */
    for (int i = 0; i < n; i++) {
        const int nn = first[i + 1] - first[i];
        blocks += (nn + lanes - 1) / lanes;
        if (mixed && nn % lanes != 0 && nn % lanes <= lanes / 2) lanes_used -= lanes / 2;   /* its half-width last block */
        for (int k = first[i] - 1; k < first[i + 1] - 1; k++) {
            const int j = neigh[k] - 1;
            const double dx = x[3 * i] - x[3 * j], dy = x[3 * i + 1] - x[3 * j + 1], dz = x[3 * i + 2] - x[3 * j + 2];
            within += dx * dx + dy * dy + dz * dz < rc * rc;
        }
    }
    double *f = calloc(3 * (size_t)m, sizeof(double)), *ae = malloc(sizeof(double) * n), vir = 0;
    const double eps = 0.0103408116, s6 = pow(3.4, 6);
    const double lj1 = 48 * eps * s6 * s6, lj2 = 24 * eps * s6, lj3 = 4 * eps * s6 * s6, lj4 = 4 * eps * s6;
    int32_t *q = malloc(16 * ((size_t)m + 1)), *offs = malloc(sizeof(int32_t) * ((size_t)np + 16 * (size_t)n));
    float *ff = malloc(16 * ((size_t)m + 1));
    int *ofirst = malloc(sizeof(int) * (n + 1));
    const double cf[6] = {lj1, lj2, lj3, lj4, rc * rc, 0};
#define PASS() (mixed ? terrace_lj_mixed(n, m, x, f, q, ff, first, ofirst, offs, cf, 0, 0, NULL, ae, &vir) \
                      : terrace_lj_one_type(n, x, f, first, neigh, lj1, lj2, lj3, lj4, rc * rc, 0, 0, ae, &vir))
    if ((mixed && terrace_row_offsets(n, m, first, neigh, 0, NULL, ofirst, offs) < 0) || !PASS()) {
        fprintf(stderr, "lj_pass_floor: this build has no SIMD pass (AVX-512, or AVX2 with FMA)\n");
        return 2;
    }
    const int batches = 7, passes = 400;
    double t[7];
    for (int b = 0; b < batches; b++) {
        const double t0 = now();
        for (int r = 0; r < passes; r++)
            PASS();
        t[b] = (now() - t0) / passes / (full ? np / 2.0 : (double)np) * 1e9;
    }
    qsort(t, batches, sizeof(double), cmp);
    lanes_used += (long)lanes * blocks;
    printf("%-5s list, %6ld pairs (%ld within rc; %.2f of the %ld lanes of %ld blocks): "
           "%.3f ns per half-list pair [%.3f, %.3f]\n",
           full ? "full" : mixed ? "mixed" : "half", np, within, within / (double)lanes_used, lanes_used, blocks, t[3],
           t[0], t[6]);
    return 0;
}
