/* The all-pairs ray pass of Lennard-Jones with one type and no smooth terms (terrace_lj,
 * ray_all_pairs): a small cluster without a pair list, the talk's seven atoms, where energy
 * stepping makes about 2.4 ray evaluations per event (a scalar loop costs about 94 instructions
 * per pair). Called from src/potentials/lj_ray.inc.
 *
 * For s and every pair (i, j), i < nlocal, i < j < nall (0-based), with d = x_i - x_j + s (v_i - v_j)
 * and w = v_i - v_j, out = (V, dV/ds, d2V/ds2, virial) summed over the pairs, those with a
 * replicated atom (j >= nlocal) counting one half. Per pair, as the half list's lanes
 * (lj_ray_lanes.inc): inside the cutoff r2inv = 1/|d|^2, else 0; r6inv = r2inv^3;
 * fpair = r6inv (lj1 r6inv - lj2) r2inv; d2psi = (3.5 lj1 r6inv - 2 lj2) r6inv r2inv^2;
 * rho1 = 2 d.w; then V += r6inv (lj3 r6inv - lj4) - offset (inside), dV/ds += -fpair rho1 / 2,
 * d2V/ds2 += d2psi rho1^2 - fpair |w|^2, virial += fpair |d|^2.
 *
 * The positions along the ray and the velocities are first staged as six rows (x, y, z, vx, vy, vz
 * of every atom, the caller's scratch soa of 6 (nall + 4) doubles, the four past the end far and
 * still), so that atom i's row j = i+1, ... loads four neighbours per vector without a transpose;
 * lanes past the row's end count nothing: four pairs per AVX2 vector.
 *
 * Without AVX2 and FMA (a portable build) the same loops run scalar. The lanes' sums are added in
 * a fixed order: the results depend on nothing but the input. */
#include <math.h>
#include "../core/simd_rows.h"

enum { c_lj1, c_lj2, c_lj3, c_lj4, c_cutsq, c_offset };

/* x + s v and v of atoms 0 .. nall-1 as six rows of ld = nall + 4 doubles, the four past the end far
 * and still (finite, beyond any cutoff; masked anyway). With AVX2 four atoms per step, their
 * records transposed by rows_xyz4 (a last step of fewer than four reads the last atom again for the
 * missing ones; the pads then overwrite them). */
static void stage(int nall, const double *x, const double *v, double s, double *soa, int ld)
{
#if defined(__AVX2__) && defined(__FMA__)
    const __m256d vs = _mm256_set1_pd(s);
    for (int a = 0; a < nall; a += 4) {
        const double *px[4], *pv[4];
        for (int l = 0; l < 4; l++) {
            const int b = a + l < nall ? a + l : nall - 1;
            px[l] = x + 3 * b; pv[l] = v + 3 * b;
        }
        __m256d rx, ry, rz, ux, uy, uz;
        rows_xyz4(px, &rx, &ry, &rz);
        rows_xyz4(pv, &ux, &uy, &uz);
        _mm256_storeu_pd(soa + a, _mm256_fmadd_pd(vs, ux, rx));
        _mm256_storeu_pd(soa + ld + a, _mm256_fmadd_pd(vs, uy, ry));
        _mm256_storeu_pd(soa + 2 * ld + a, _mm256_fmadd_pd(vs, uz, rz));
        _mm256_storeu_pd(soa + 3 * ld + a, ux);
        _mm256_storeu_pd(soa + 4 * ld + a, uy);
        _mm256_storeu_pd(soa + 5 * ld + a, uz);
    }
    _mm256_storeu_pd(soa + nall, _mm256_set1_pd(1.0e100));
    for (int k = 1; k < 6; k++) _mm256_storeu_pd(soa + k * ld + nall, _mm256_setzero_pd());
#else
    for (int a = 0; a < nall; a++) {
        for (int k = 0; k < 3; k++) {
            soa[k * ld + a] = x[3 * a + k] + s * v[3 * a + k];
            soa[(k + 3) * ld + a] = v[3 * a + k];
        }
    }
    for (int a = nall; a < ld; a++) {
        soa[a] = 1.0e100;
        for (int k = 1; k < 6; k++) soa[k * ld + a] = 0.0;
    }
#endif
}

#if !(defined(__AVX2__) && defined(__FMA__))
/* One pair's four terms added into acc (the scalar path). */
static inline void pair_terms(double rr, double dw, double ww, const double *c, double *acc)
{
    const int inside = rr < c[c_cutsq];
    const double r2inv = inside ? 1.0 / rr : 0.0;
    const double r6inv = r2inv * r2inv * r2inv;
    const double fpair = r6inv * (c[c_lj1] * r6inv - c[c_lj2]) * r2inv;
    const double d2psi = (3.5 * c[c_lj1] * r6inv - 2.0 * c[c_lj2]) * r6inv * r2inv * r2inv;
    const double rho1 = 2.0 * dw;
    acc[0] += r6inv * (c[c_lj3] * r6inv - c[c_lj4]) - (inside ? c[c_offset] : 0.0);
    acc[1] -= 0.5 * fpair * rho1;
    acc[2] += d2psi * rho1 * rho1 - fpair * ww;
    acc[3] += fpair * rr;
}
#else
/* The pass's constants, broadcast once. */
struct consts4 {
    __m256d lj1, lj2, lj3, lj4, cutsq, offset, c7h, two_lj2, half, two, inf;
    __m256i lane;
};

static inline struct consts4 consts4(const double *c)
{
    struct consts4 k;
    k.lj1 = _mm256_set1_pd(c[c_lj1]); k.lj2 = _mm256_set1_pd(c[c_lj2]); k.lj3 = _mm256_set1_pd(c[c_lj3]);
    k.lj4 = _mm256_set1_pd(c[c_lj4]); k.cutsq = _mm256_set1_pd(c[c_cutsq]); k.offset = _mm256_set1_pd(c[c_offset]);
    k.c7h = _mm256_set1_pd(3.5 * c[c_lj1]); k.two_lj2 = _mm256_set1_pd(2.0 * c[c_lj2]);
    k.half = _mm256_set1_pd(0.5); k.two = _mm256_set1_pd(2.0); k.inf = _mm256_set1_pd(INFINITY);
    k.lane = _mm256_set_epi64x(3, 2, 1, 0);
    return k;
}

/* The pairs (i, j), j in [lo, hi), four at a time, added into acc[0..3]. */
static inline __attribute__((always_inline)) void row4(const double *soa, int ld, int i, int lo, int hi,
                                                       const struct consts4 *k, __m256d *acc)
{
    const __m256d xi = _mm256_set1_pd(soa[i]), yi = _mm256_set1_pd(soa[ld + i]), zi = _mm256_set1_pd(soa[2 * ld + i]);
    const __m256d ui = _mm256_set1_pd(soa[3 * ld + i]), vi = _mm256_set1_pd(soa[4 * ld + i]);
    const __m256d wi = _mm256_set1_pd(soa[5 * ld + i]);
    for (int j = lo; j < hi; j += 4) {
        const __m256d dx = _mm256_sub_pd(xi, _mm256_loadu_pd(soa + j));
        const __m256d dy = _mm256_sub_pd(yi, _mm256_loadu_pd(soa + ld + j));
        const __m256d dz = _mm256_sub_pd(zi, _mm256_loadu_pd(soa + 2 * ld + j));
        const __m256d wx = _mm256_sub_pd(ui, _mm256_loadu_pd(soa + 3 * ld + j));
        const __m256d wy = _mm256_sub_pd(vi, _mm256_loadu_pd(soa + 4 * ld + j));
        const __m256d wz = _mm256_sub_pd(wi, _mm256_loadu_pd(soa + 5 * ld + j));
        const __m256d rr = _mm256_fmadd_pd(dz, dz, _mm256_fmadd_pd(dx, dx, _mm256_mul_pd(dy, dy)));
        const __m256d dw = _mm256_fmadd_pd(dz, wz, _mm256_fmadd_pd(dx, wx, _mm256_mul_pd(dy, wy)));
        const __m256d ww = _mm256_fmadd_pd(wz, wz, _mm256_fmadd_pd(wx, wx, _mm256_mul_pd(wy, wy)));
        /* inside: within the cutoff and before the row's end */
        const __m256d in_row = _mm256_castsi256_pd(_mm256_cmpgt_epi64(_mm256_set1_epi64x(hi - j), k->lane));
        const __m256d inside = _mm256_and_pd(in_row, _mm256_cmp_pd(rr, k->cutsq, _CMP_LT_OQ));
        const __m256d r2inv = _mm256_div_pd(_mm256_set1_pd(1.0), _mm256_blendv_pd(k->inf, rr, inside));
        const __m256d r4inv = _mm256_mul_pd(r2inv, r2inv);
        const __m256d r6inv = _mm256_mul_pd(r4inv, r2inv);
        const __m256d fpair = _mm256_mul_pd(_mm256_mul_pd(r6inv, _mm256_fmsub_pd(k->lj1, r6inv, k->lj2)), r2inv);
        const __m256d d2psi = _mm256_mul_pd(_mm256_mul_pd(_mm256_fmsub_pd(k->c7h, r6inv, k->two_lj2), r6inv), r4inv);
        const __m256d rho1 = _mm256_mul_pd(k->two, dw);
        const __m256d e = _mm256_sub_pd(_mm256_mul_pd(r6inv, _mm256_fmsub_pd(k->lj3, r6inv, k->lj4)),
                                        _mm256_and_pd(inside, k->offset));
        acc[0] = _mm256_add_pd(acc[0], e);
        acc[1] = _mm256_fnmadd_pd(_mm256_mul_pd(k->half, fpair), rho1, acc[1]);
        acc[2] = _mm256_add_pd(acc[2], _mm256_fmsub_pd(_mm256_mul_pd(d2psi, rho1), rho1, _mm256_mul_pd(fpair, ww)));
        /* (lanes outside: fpair 0 and rr finite, so 0) */
        acc[3] = _mm256_fmadd_pd(fpair, rr, acc[3]);
    }
}

/* the lane sums ((0 + 1) + (2 + 3)) of a, b, c, d as one vector (a's sum in lane 0) */
static inline __m256d totals4(__m256d a, __m256d b, __m256d c, __m256d d)
{
    const __m256d ab = _mm256_hadd_pd(a, b), cd = _mm256_hadd_pd(c, d);     /* (a01 b01 a23 b23), (c01 d01 c23 d23) */
    return _mm256_add_pd(_mm256_permute2f128_pd(ab, cd, 0x20), _mm256_permute2f128_pd(ab, cd, 0x31));
}
#endif

void terrace_ray_all_pairs(int nlocal, int nall, const double *x, const double *v, double s, const double *c,
                           double *soa, double *out)
{
    const int ld = nall + 4;
    double local[4] = {0, 0, 0, 0}, ghost[4] = {0, 0, 0, 0};
    stage(nall, x, v, s, soa, ld);
#if defined(__AVX2__) && defined(__FMA__)
    const struct consts4 k4 = consts4(c);
    __m256d al[4], ag[4];
    for (int k = 0; k < 4; k++) al[k] = ag[k] = _mm256_setzero_pd();
    for (int i = 0; i < nlocal; i++) row4(soa, ld, i, i + 1, nlocal, &k4, al);
    if (nall > nlocal)
        for (int i = 0; i < nlocal; i++) row4(soa, ld, i, nlocal, nall, &k4, ag);
    _mm256_storeu_pd(local, totals4(al[0], al[1], al[2], al[3]));
    _mm256_storeu_pd(ghost, totals4(ag[0], ag[1], ag[2], ag[3]));
#else
    for (int i = 0; i < nlocal; i++) {
        for (int j = i + 1; j < nall; j++) {
            const double dx = soa[i] - soa[j], dy = soa[ld + i] - soa[ld + j], dz = soa[2 * ld + i] - soa[2 * ld + j];
            const double wx = soa[3 * ld + i] - soa[3 * ld + j], wy = soa[4 * ld + i] - soa[4 * ld + j];
            const double wz = soa[5 * ld + i] - soa[5 * ld + j];
            pair_terms(dx * dx + dy * dy + dz * dz, dx * wx + dy * wy + dz * wz, wx * wx + wy * wy + wz * wz, c,
                       j < nlocal ? local : ghost);
        }
    }
#endif
    for (int k = 0; k < 4; k++) out[k] = local[k] + 0.5 * ghost[k];
}

