/* Positions as 16-byte fixed-point records (qx, qy, qz, 0) of 32-bit integers, and rows of them to
 * and from SIMD registers, for the mixed-precision Lennard-Jones pass (potentials/lj_mixed_simd.c)
 * and the prune of a list with wrapped images (neighbor/prune_simd.c). A record is addressed by its
 * byte offset, 16 (j - 1) for atom j (terrace_row_offsets). TERRACE_FIXED_ROWS is defined where the
 * build has AVX-512 (F, VL, DQ) and FMA (rows of 16 records); else TERRACE_FIXED_ROWS8 where it has
 * AVX2 and FMA (rows of 8 records); neither, and nothing else, otherwise. */
#ifndef TERRACE_FIXED_POINT_ROWS_H
#define TERRACE_FIXED_POINT_ROWS_H
#include <math.h>
#include <stdint.h>
#if defined(__AVX512F__) && defined(__AVX512VL__) && defined(__AVX512DQ__) && defined(__FMA__)
#include <immintrin.h>
#define TERRACE_FIXED_ROWS 1

/* Atoms held above which the byte offsets 16 j would not fit 32 bits (the passes decline). */
static const long terrace_fixed_max_atoms = (1L << 27) - 2;

/* n = 16 or 8 16-byte records (x, y, z, w) at base + off[l] (byte offsets), as rows of x, y and z
 * (lane l: record l; with n = 8 the upper eight lanes are left undefined): register m holds records
 * m, m + 4, m + 8, m + 12 in its four 128-bit lanes, and two unpacks transpose each lane's 4 x 4 block */
static inline __attribute__((always_inline)) void rows_n(const int n, const char *base, const int32_t *off,
                                                         __m512 *vx, __m512 *vy, __m512 *vz)
{
    __m512 a[4];
    for (int m = 0; m < 4; m++) {
        __m512 r = _mm512_broadcast_f32x4(_mm_loadu_ps((const float *)(base + off[m])));
        r = _mm512_mask_broadcast_f32x4(r, 0x00F0, _mm_loadu_ps((const float *)(base + off[m + 4])));
        if (n == 16) {
            r = _mm512_mask_broadcast_f32x4(r, 0x0F00, _mm_loadu_ps((const float *)(base + off[m + 8])));
            r = _mm512_mask_broadcast_f32x4(r, 0xF000, _mm_loadu_ps((const float *)(base + off[m + 12])));
        }
        a[m] = r;
    }
    const __m512d t0 = _mm512_castps_pd(_mm512_unpacklo_ps(a[0], a[1]));   /* x0 x1 y0 y1 */
    const __m512d t1 = _mm512_castps_pd(_mm512_unpackhi_ps(a[0], a[1]));   /* z0 z1 w0 w1 */
    const __m512d t2 = _mm512_castps_pd(_mm512_unpacklo_ps(a[2], a[3]));   /* x2 x3 y2 y3 */
    const __m512d t3 = _mm512_castps_pd(_mm512_unpackhi_ps(a[2], a[3]));   /* z2 z3 w2 w3 */
    *vx = _mm512_castpd_ps(_mm512_unpacklo_pd(t0, t2));
    *vy = _mm512_castpd_ps(_mm512_unpackhi_pd(t0, t2));
    *vz = _mm512_castpd_ps(_mm512_unpacklo_pd(t1, t3));
}

/* The records of the n owned atoms on the periodic grid of the box (wrap: lo(3), length(3)): q =
 * nint((x - lo) 2^32 / L) modulo 2^32 in each dimension, ff = 0 (unless ff is NULL), and q's pad
 * record after them
 * (the grid steps are L / 2^32). A difference of two such integers, wrapped to 32 bits, is
 * the separation of the nearest images (to within a step, L / 2^32: 8e-9 length units on the argon
 * job's box), so that the pairs of the list's periodic images are the pairs of their owners (the
 * engine's wrapped images, when the box is more than twice the list's cutoff in every dimension).
 * Positions up to a box length outside the box (between builds) are on the same grid. */
static inline void stage_periodic(int n, const double *x, const double *wrap, int32_t *q, float *ff)
{
    double s[3];
    for (int c = 0; c < 3; c++) s[c] = ldexp(1.0, 32) / wrap[3 + c];
    const __m512d vlo = _mm512_setr_pd(wrap[0], wrap[1], wrap[2], 0, wrap[0], wrap[1], wrap[2], 0);
    const __m512d vs = _mm512_setr_pd(s[0], s[1], s[2], 0, s[0], s[1], s[2], 0);
    const __m256 zero = _mm256_setzero_ps();
    const __m512i spread = _mm512_setr_epi64(0, 1, 2, 0, 3, 4, 5, 0);
    long i = 0;
    for (; i + 2 <= n; i += 2) {
        const __m512d v = _mm512_maskz_permutexvar_pd(0x77, spread, _mm512_maskz_loadu_pd(0x3F, x + 3 * i));
        /* rounded to the nearest 64-bit integer, its low 32 bits kept (the modulo) */
        _mm256_storeu_si256((__m256i *)(q + 4 * i), _mm512_cvtepi64_epi32(_mm512_cvtpd_epi64(
                                                        _mm512_mul_pd(_mm512_sub_pd(v, vlo), vs))));
        if (ff) _mm256_storeu_ps(ff + 4 * i, zero);
    }
    for (; i < n; i++) {
        for (int c = 0; c < 3; c++) q[4 * i + c] = (int32_t)(uint32_t)(uint64_t)llrint((x[3 * i + c] - wrap[c]) * s[c]);
        q[4 * i + 3] = 0;
        if (ff)
            for (int c = 0; c < 4; c++) ff[4 * i + c] = 0;
    }
    for (int c = 0; c < 4; c++) q[4 * (long)n + c] = 0;
}


#elif defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#define TERRACE_FIXED_ROWS8 1

/* Atoms held above which the byte offsets 16 j would not fit 32 bits (the passes decline). */
static const long terrace_fixed_max_atoms = (1L << 27) - 2;

/* n = 8 or 4 16-byte records (x, y, z, w) at base + off[l] (byte offsets), as rows of x, y and z
 * (lane l: record l; with n = 4 the upper four lanes are zero): register m holds records m and
 * m + 4 in its two 128-bit lanes, and two unpacks transpose each lane's 4 x 4 block */
static inline __attribute__((always_inline)) void rows8(const int n, const char *base, const int32_t *off,
                                                        __m256 *vx, __m256 *vy, __m256 *vz)
{
    __m256 a[4];
    for (int m = 0; m < 4; m++) {
        const __m128 lo = _mm_loadu_ps((const float *)(base + off[m]));
        a[m] = _mm256_insertf128_ps(_mm256_castps128_ps256(lo),
                                    n == 8 ? _mm_loadu_ps((const float *)(base + off[m + 4])) : _mm_setzero_ps(), 1);
    }
    const __m256d t0 = _mm256_castps_pd(_mm256_unpacklo_ps(a[0], a[1]));   /* x0 x1 y0 y1 */
    const __m256d t1 = _mm256_castps_pd(_mm256_unpackhi_ps(a[0], a[1]));   /* z0 z1 w0 w1 */
    const __m256d t2 = _mm256_castps_pd(_mm256_unpacklo_ps(a[2], a[3]));   /* x2 x3 y2 y3 */
    const __m256d t3 = _mm256_castps_pd(_mm256_unpackhi_ps(a[2], a[3]));   /* z2 z3 w2 w3 */
    *vx = _mm256_castpd_ps(_mm256_unpacklo_pd(t0, t2));
    *vy = _mm256_castpd_ps(_mm256_unpackhi_pd(t0, t2));
    *vz = _mm256_castpd_ps(_mm256_unpacklo_pd(t1, t3));
}

/* The records of the n owned atoms on the periodic grid of the box, as the AVX-512 stage_periodic
 * above (q = nint((x - lo) 2^32 / L) modulo 2^32, ff = 0 unless NULL, the pad record after them),
 * one atom at a time: the rounding by adding 1.5 2^52 in the same operation as the product (the
 * sum's low 32 bits are the nearest integer modulo 2^32, ties to even, for |value| < 2^51) */
static inline void stage_periodic(int n, const double *x, const double *wrap, int32_t *q, float *ff)
{
    const double magic = 6755399441055744.0;   /* 1.5 2^52 */
    double s[3];
    for (int c = 0; c < 3; c++) s[c] = ldexp(1.0, 32) / wrap[3 + c];
    for (long i = 0; i < n; i++) {
        for (int c = 0; c < 3; c++) {
            const double v = __builtin_fma(x[3 * i + c] - wrap[c], s[c], magic);   /* (one rounding) */
            int64_t b;
            __builtin_memcpy(&b, &v, 8);
            q[4 * i + c] = (int32_t)(uint32_t)(uint64_t)b;
        }
        q[4 * i + 3] = 0;
        if (ff)
            for (int c = 0; c < 4; c++) ff[4 * i + c] = 0;
    }
    for (int c = 0; c < 4; c++) q[4 * (long)n + c] = 0;
}
#endif
#endif
