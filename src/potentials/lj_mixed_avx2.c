/* The row pass of the mixed-precision Lennard-Jones force over the half atom list with AVX2 and
 * FMA (no AVX-512), called from terrace_lj_mixed (lj_mixed_simd.c), which stages the fixed-point
 * records, forms the constants and adds the force records to f: the AVX-512 pass's method (stated
 * there) eight pairs per block in 256-bit registers instead of sixteen. The differences:
 *
 * - a block's records are loaded two to a register (core/fixed_point_rows.h, rows8) and stored
 *   back the same way (store8); a row's last block of four pairs or fewer loads and stores four;
 * - 1/r^2 by a single-precision division (correctly rounded; AVX2's reciprocal has 12 bits);
 * - the lanes outside the cutoff (and the padding lanes, which read the pad record) zeroed by an
 *   and with the comparison's mask.
 *
 * The rows' offsets have the AVX-512 pass's layout (terrace_row_offsets: rows padded to 16
 * entries), read eight at a time. */
#include <math.h>
#include <stdint.h>
#include "../core/fixed_point_rows.h"
#include "../core/simd_rows.h"
#if defined(TERRACE_FIXED_ROWS8)

/* the inverse of rows8: lane l < n of (vx, vy, vz) stored to the record at base + off[l] as (x, y, z, 0) */
static inline __attribute__((always_inline)) void store8(const int n, char *base, const int32_t *off, __m256 vx,
                                                         __m256 vy, __m256 vz)
{
    const __m256 zero = _mm256_setzero_ps();
    const __m256d u0 = _mm256_castps_pd(_mm256_unpacklo_ps(vx, vy));     /* x0 y0 x1 y1 */
    const __m256d u1 = _mm256_castps_pd(_mm256_unpackhi_ps(vx, vy));     /* x2 y2 x3 y3 */
    const __m256d v0 = _mm256_castps_pd(_mm256_unpacklo_ps(vz, zero));   /* z0 0 z1 0 */
    const __m256d v1 = _mm256_castps_pd(_mm256_unpackhi_ps(vz, zero));   /* z2 0 z3 0 */
    const __m256 b[4] = {_mm256_castpd_ps(_mm256_unpacklo_pd(u0, v0)), _mm256_castpd_ps(_mm256_unpackhi_pd(u0, v0)),
                         _mm256_castpd_ps(_mm256_unpacklo_pd(u1, v1)), _mm256_castpd_ps(_mm256_unpackhi_pd(u1, v1))};
    for (int m = 0; m < 4; m++) {   /* b[m], 128-bit lane L: record 4 L + m */
        _mm_storeu_ps((float *)(base + off[m]), _mm256_castps256_ps128(b[m]));
        if (n == 8) _mm_storeu_ps((float *)(base + off[m + 4]), _mm256_extractf128_ps(b[m], 1));
    }
}

/* the coefficients and constants of the pass */
struct pass_consts8 {
    __m256 c1, c2, c3, c4, cs, co, ux, uy, uz, uxl, uyl, uzl, one;
};

/* the separation along one dimension: the integer difference converted to single, times the grid
 * step u (split: u + ul, where the step is not a power of two) */
static inline __attribute__((always_inline)) __m256 separation8(const int split, __m256i qi, __m256 qj, __m256 u,
                                                                __m256 ul)
{
    const __m256 c = _mm256_cvtepi32_ps(_mm256_sub_epi32(qi, _mm256_castps_si256(qj)));
    return split ? _mm256_fmadd_ps(c, ul, _mm256_mul_ps(c, u)) : _mm256_mul_ps(c, u);
}

/* One block of a row: the cnt (<= n) neighbours at byte offsets off of atom i (xi, yi, zi): their
 * pair forces into i's sums and, subtracted, into their records; with want_energy the pair
 * energies and virials into se and sw. n = 8, or 4 for a row's last block of four pairs or fewer. */
static inline __attribute__((always_inline)) void pair_block8(const int n, const int split, int cnt, const char *qb,
                                                              char *fb, const int32_t *off, __m256i xi, __m256i yi,
                                                              __m256i zi, const struct pass_consts8 *k_,
                                                              int want_energy, __m256 *sx, __m256 *sy, __m256 *sz,
                                                              __m256 *se, __m256 *sw)
{
    const __m256 live = _mm256_castsi256_ps(
        _mm256_cmpgt_epi32(_mm256_set1_epi32(cnt), _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7)));
    __m256 qx, qy, qz, gx, gy, gz;
    rows8(n, qb, off, &qx, &qy, &qz);
    rows8(n, fb, off, &gx, &gy, &gz);
    const __m256 dx = separation8(split, xi, qx, k_->ux, k_->uxl);
    const __m256 dy = separation8(split, yi, qy, k_->uy, k_->uyl);
    const __m256 dz = separation8(split, zi, qz, k_->uz, k_->uzl);
    const __m256 rsq = _mm256_fmadd_ps(dz, dz, _mm256_fmadd_ps(dx, dx, _mm256_mul_ps(dy, dy)));
    const __m256 in = _mm256_and_ps(live, _mm256_cmp_ps(rsq, k_->cs, _CMP_LT_OQ));
    const __m256 r2inv = _mm256_and_ps(in, _mm256_div_ps(k_->one, rsq));   /* (1/0 = inf outside: zeroed) */
    const __m256 r6inv = _mm256_mul_ps(_mm256_mul_ps(r2inv, r2inv), r2inv);
    const __m256 fpair = _mm256_mul_ps(_mm256_mul_ps(r6inv, _mm256_fmsub_ps(k_->c1, r6inv, k_->c2)), r2inv);
    if (want_energy) {
        const __m256 e = _mm256_mul_ps(r6inv, _mm256_fmsub_ps(k_->c3, r6inv, k_->c4));
        *se = _mm256_add_ps(*se, _mm256_sub_ps(e, _mm256_and_ps(in, k_->co)));   /* the offset inside the cutoff */
        *sw = _mm256_fmadd_ps(rsq, fpair, *sw);
    }
    const __m256 fx = _mm256_mul_ps(dx, fpair), fy = _mm256_mul_ps(dy, fpair), fz = _mm256_mul_ps(dz, fpair);
    *sx = _mm256_add_ps(*sx, fx); *sy = _mm256_add_ps(*sy, fy); *sz = _mm256_add_ps(*sz, fz);
    store8(n, fb, off, _mm256_sub_ps(gx, fx), _mm256_sub_ps(gy, fy), _mm256_sub_ps(gz, fz));
}

/* the sums of the lanes of x, y, z and e, as (x, y, z, e): two horizontal adds, then the halves */
static inline __m128 sums4_8(__m256 x, __m256 y, __m256 z, __m256 e)
{
    const __m256 t = _mm256_hadd_ps(_mm256_hadd_ps(x, y), _mm256_hadd_ps(z, e));
    return _mm_add_ps(_mm256_castps256_ps128(t), _mm256_extractf128_ps(t, 1));
}

/* the sum of an eight-single vector's lanes, in double */
static inline double sum_double8(__m256 v)
{
    return sum4(_mm256_add_pd(_mm256_cvtps_pd(_mm256_castps256_ps128(v)), _mm256_cvtps_pd(_mm256_extractf128_ps(v, 1))));
}

/* the row loop of the pass (split: the grid steps in two parts, separation8) */
static inline __attribute__((always_inline)) void rows_pass8(const int split, int nlocal, const int32_t *q, char *fb,
                                                             const int *first, const int *ofirst, const int32_t *offs,
                                                             const struct pass_consts8 *k_, int want_energy,
                                                             double escale, double *atom_e, double *w)
{
    const __m256 zero = _mm256_setzero_ps();
    const char *qb = (const char *)q;
    for (int i = 0; i < nlocal; i++) {
        const int nn = first[i + 1] - first[i];
        const int32_t *a = q + 4 * (long)i;
        const __m256i xi = _mm256_set1_epi32(a[0]), yi = _mm256_set1_epi32(a[1]), zi = _mm256_set1_epi32(a[2]);
        __m256 sx = zero, sy = zero, sz = zero, se = zero, sw = zero;
        for (int k = 0; k < nn; k += 8) {
            const int cnt = nn - k < 8 ? nn - k : 8;
            const int32_t *off = offs + ofirst[i] + k;
            if (cnt <= 4)   /* a row's last block of four pairs or fewer: half the loads and stores */
                pair_block8(4, split, cnt, qb, fb, off, xi, yi, zi, k_, want_energy, &sx, &sy, &sz, &se, &sw);
            else
                pair_block8(8, split, cnt, qb, fb, off, xi, yi, zi, k_, want_energy, &sx, &sy, &sz, &se, &sw);
        }
        /* (fx, fy, fz, e) of atom i: the force added to its own record (terrace_lj_mixed adds it to f) */
        const __m128 t = sums4_8(sx, sy, sz, se);
        float *fr = (float *)(fb + 16 * (long)i);
        _mm_storeu_ps(fr, _mm_add_ps(_mm_loadu_ps(fr), _mm_blend_ps(t, _mm_setzero_ps(), 8)));
        if (want_energy) {
            atom_e[i] = escale * (double)_mm_cvtss_f32(_mm_permute_ps(t, 0xFF));
            *w += escale * sum_double8(sw);
        }
    }
}

/* the row pass: k = (lj1, lj2, lj3, lj4, cutsq, offset, ux, uy, uz, uxl, uyl, uzl) in single, as
 * terrace_lj_mixed forms them (split: the grid steps in two parts); escale, atom_e and w as there */
void terrace_lj_mixed_rows8(int split, int nlocal, const int32_t *q, float *ff, const int *first, const int *ofirst,
                            const int32_t *offs, const float *k, int want_energy, double escale, double *atom_e,
                            double *w)
{
    const struct pass_consts8 kv = {
        _mm256_set1_ps(k[0]), _mm256_set1_ps(k[1]), _mm256_set1_ps(k[2]), _mm256_set1_ps(k[3]),
        _mm256_set1_ps(k[4]), _mm256_set1_ps(k[5]), _mm256_set1_ps(k[6]), _mm256_set1_ps(k[7]),
        _mm256_set1_ps(k[8]), _mm256_set1_ps(k[9]), _mm256_set1_ps(k[10]), _mm256_set1_ps(k[11]), _mm256_set1_ps(1.0f)};
    if (split)
        rows_pass8(1, nlocal, q, (char *)ff, first, ofirst, offs, &kv, want_energy, escale, atom_e, w);
    else
        rows_pass8(0, nlocal, q, (char *)ff, first, ofirst, offs, &kv, want_energy, escale, atom_e, w);
}
#else
/* (not in this build: lj_mixed_simd.c does not call it) */
typedef int terrace_lj_mixed_avx2_unused;
#endif
