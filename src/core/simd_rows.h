/* Rows of doubles to and from SIMD registers without gather or scatter instructions, for the C
 * kernels that read the positions x(3, n) (or the records of another row length) of a list of
 * neighbours: the Lennard-Jones passes (potentials/lj_simd.c), the neighbour-list prune
 * (neighbor/prune_simd.c) and EAM's density gather (potentials/eam_simd.c).
 *
 * GCC's gathers and scatters (vgatherdpd, vscatterdpd) were slower on the machines measured
 * (doc/performance.md): here a row's doubles are loaded as 16-byte halves, two or four rows to a
 * register, and unpacked into one register per component, as GROMACS's nbnxm kernels load their
 * j-clusters. No byte outside a row's own doubles is read or written, so rows may end an array. */
#ifndef TERRACE_SIMD_ROWS_H
#define TERRACE_SIMD_ROWS_H
#if defined(__AVX2__)
#include <immintrin.h>

/* two 16-byte halves, p in the lower lane and q in the upper one */
static inline __m256d halves(const double *p, const double *q)
{
    return _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(p)), _mm_loadu_pd(q), 1);
}

/* four rows of three doubles as three four-wide vectors in lane order (8 loads, 4 inserts, 3
 * unpacks) */
static inline void rows_xyz4(const double *const *q, __m256d *vx, __m256d *vy, __m256d *vz)
{
    const __m256d a = halves(q[0], q[2]), b = halves(q[1], q[3]);
    const __m256d c = halves(q[0] + 1, q[2] + 1), d = halves(q[1] + 1, q[3] + 1);
    *vx = _mm256_unpacklo_pd(a, b);
    *vy = _mm256_unpackhi_pd(a, b);
    *vz = _mm256_unpackhi_pd(c, d);
}

/* one row as its (x, y) and (y, z) halves */
static inline void store_row(double *p, __m128d xy, __m128d yz)
{
    _mm_storeu_pd(p, xy);
    _mm_storeu_pd(p + 1, yz);
}

/* the inverse of rows_xyz4 (4 unpacks and 8 stores) */
static inline void store_rows4(double *const *q, __m256d vx, __m256d vy, __m256d vz)
{
    const __m256d e = _mm256_unpacklo_pd(vx, vy), o = _mm256_unpackhi_pd(vx, vy);     /* (x, y) */
    const __m256d e2 = _mm256_unpacklo_pd(vy, vz), o2 = _mm256_unpackhi_pd(vy, vz);   /* (y, z) */
    store_row(q[0], _mm256_castpd256_pd128(e), _mm256_castpd256_pd128(e2));
    store_row(q[1], _mm256_castpd256_pd128(o), _mm256_castpd256_pd128(o2));
    store_row(q[2], _mm256_extractf128_pd(e, 1), _mm256_extractf128_pd(e2, 1));
    store_row(q[3], _mm256_extractf128_pd(o, 1), _mm256_extractf128_pd(o2, 1));
}

/* the sum of a four-wide vector's lanes, ((0 + 1) + (2 + 3)) */
static inline double sum4(__m256d v)
{
    const __m128d lo = _mm256_castpd256_pd128(v), hi = _mm256_extractf128_pd(v, 1);
    const __m128d h = _mm_add_pd(_mm_unpacklo_pd(lo, hi), _mm_unpackhi_pd(lo, hi));
    return _mm_cvtsd_f64(_mm_add_sd(h, _mm_unpackhi_pd(h, h)));
}

/* the lanes below cnt (0 <= cnt <= 4) of four 32-bit lanes: all ones, the others zero (the mask of a
 * block's live lanes for _mm_maskload_epi32; widened by _mm256_cvtepi32_epi64 for _mm256_maskload_pd) */
static inline __m128i live4(int cnt)
{
    return _mm_cmpgt_epi32(_mm_set1_epi32(cnt), _mm_setr_epi32(0, 1, 2, 3));
}

/* AVX2's compressing store: the 32-bit lanes of j whose bit is set in keep (four bits, lane 0 the
 * lowest) moved to the front in their order by one byte shuffle looked up by keep, and all four
 * lanes stored at out (out needs room for four entries; those past the kept ones are overwritten
 * next); returns how many were kept */
static inline int store_kept4(int *out, __m128i j, int keep)
{
    static const unsigned char shuffle[16][16] = {
        {0}, {0, 1, 2, 3}, {4, 5, 6, 7}, {0, 1, 2, 3, 4, 5, 6, 7}, {8, 9, 10, 11}, {0, 1, 2, 3, 8, 9, 10, 11},
        {4, 5, 6, 7, 8, 9, 10, 11}, {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11}, {12, 13, 14, 15},
        {0, 1, 2, 3, 12, 13, 14, 15}, {4, 5, 6, 7, 12, 13, 14, 15}, {0, 1, 2, 3, 4, 5, 6, 7, 12, 13, 14, 15},
        {8, 9, 10, 11, 12, 13, 14, 15}, {0, 1, 2, 3, 8, 9, 10, 11, 12, 13, 14, 15},
        {4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15}, {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15}};
    _mm_storeu_si128((__m128i *)out, _mm_shuffle_epi8(j, _mm_loadu_si128((const __m128i *)shuffle[keep])));
    return __builtin_popcount(keep);
}

/* the separations d = c - x_j of up to four neighbours nb[0..cnt-1] (1-based indices into x(3, *))
 * from the centre c, one vector per component (the lanes from cnt on: a row 1e100 away), and the
 * neighbours' indices (lanes from cnt on: zero) */
static inline __attribute__((always_inline)) __m128i separations4(const double *x, const int *nb, int cnt, __m256d cx,
                                                                  __m256d cy, __m256d cz, __m256d *dx, __m256d *dy,
                                                                  __m256d *dz)
{
    static const double far_row[3] = {1.0e100, 1.0e100, 1.0e100};
    const double *q[4];
    for (int l = 0; l < 4; l++) q[l] = l < cnt ? x + (3 * (long)nb[l] - 3) : far_row;
    rows_xyz4(q, dx, dy, dz);
    *dx = _mm256_sub_pd(cx, *dx);
    *dy = _mm256_sub_pd(cy, *dy);
    *dz = _mm256_sub_pd(cz, *dz);
    return cnt == 4 ? _mm_loadu_si128((const __m128i *)nb) : _mm_maskload_epi32(nb, live4(cnt));
}

/* store_kept4 for four doubles: the lanes of v whose bit is set in keep moved to the front in order
 * (one permute of 32-bit halves looked up by keep) and all four stored at out (room for four) */
static inline int store_kept4d(double *out, __m256d v, int keep)
{
    static const int halves_of[16][8] = {
        {0, 0, 0, 0, 0, 0, 0, 0}, {0, 1, 0, 0, 0, 0, 0, 0}, {2, 3, 0, 0, 0, 0, 0, 0}, {0, 1, 2, 3, 0, 0, 0, 0},
        {4, 5, 0, 0, 0, 0, 0, 0}, {0, 1, 4, 5, 0, 0, 0, 0}, {2, 3, 4, 5, 0, 0, 0, 0}, {0, 1, 2, 3, 4, 5, 0, 0},
        {6, 7, 0, 0, 0, 0, 0, 0}, {0, 1, 6, 7, 0, 0, 0, 0}, {2, 3, 6, 7, 0, 0, 0, 0}, {0, 1, 2, 3, 6, 7, 0, 0},
        {4, 5, 6, 7, 0, 0, 0, 0}, {0, 1, 4, 5, 6, 7, 0, 0}, {2, 3, 4, 5, 6, 7, 0, 0}, {0, 1, 2, 3, 4, 5, 6, 7}};
    const __m256i p = _mm256_loadu_si256((const __m256i *)halves_of[keep]);
    _mm256_storeu_pd(out, _mm256_castps_pd(_mm256_permutevar8x32_ps(_mm256_castpd_ps(v), p)));
    return __builtin_popcount(keep);
}

#if defined(__AVX512F__)
/* four 16-byte halves, p q r t in the four lanes */
static inline __m512d quarters(const double *p, const double *q, const double *r, const double *t)
{
    return _mm512_insertf64x4(_mm512_castpd256_pd512(halves(p, q)), halves(r, t), 1);
}

/* eight rows of three doubles (x, y, z at q[l]) as three eight-wide vectors in lane order l: (x, y)
 * and (y, z) of each row as 16-byte halves, four rows to a register, unpacked (16 loads, 12
 * inserts, 3 unpacks where three gathers load 24 doubles) */
static inline void rows_xyz(const double *const *q, __m512d *vx, __m512d *vy, __m512d *vz)
{
    const __m512d a = quarters(q[0], q[2], q[4], q[6]), b = quarters(q[1], q[3], q[5], q[7]);
    const __m512d c = quarters(q[0] + 1, q[2] + 1, q[4] + 1, q[6] + 1);
    const __m512d d = quarters(q[1] + 1, q[3] + 1, q[5] + 1, q[7] + 1);
    *vx = _mm512_unpacklo_pd(a, b);
    *vy = _mm512_unpackhi_pd(a, b);
    *vz = _mm512_unpackhi_pd(c, d);
}

/* the inverse of rows_xyz: lane l of (vx, vy, vz) stored to row q[l] (4 unpacks and 16 stores
 * where three scatters store 24 doubles) */
static inline void store_rows(double *const *q, __m512d vx, __m512d vy, __m512d vz)
{
    const __m512d e = _mm512_unpacklo_pd(vx, vy), o = _mm512_unpackhi_pd(vx, vy);     /* (x, y) */
    const __m512d e2 = _mm512_unpacklo_pd(vy, vz), o2 = _mm512_unpackhi_pd(vy, vz);   /* (y, z) */
    store_row(q[0], _mm512_castpd512_pd128(e), _mm512_castpd512_pd128(e2));
    store_row(q[1], _mm512_castpd512_pd128(o), _mm512_castpd512_pd128(o2));
    store_row(q[2], _mm512_extractf64x2_pd(e, 1), _mm512_extractf64x2_pd(e2, 1));
    store_row(q[3], _mm512_extractf64x2_pd(o, 1), _mm512_extractf64x2_pd(o2, 1));
    store_row(q[4], _mm512_extractf64x2_pd(e, 2), _mm512_extractf64x2_pd(e2, 2));
    store_row(q[5], _mm512_extractf64x2_pd(o, 2), _mm512_extractf64x2_pd(o2, 2));
    store_row(q[6], _mm512_extractf64x2_pd(e, 3), _mm512_extractf64x2_pd(e2, 3));
    store_row(q[7], _mm512_extractf64x2_pd(o, 3), _mm512_extractf64x2_pd(o2, 3));
}


/* the rows of eight neighbours nb[0..cnt-1] (1-based indices into x(3, *)); the lanes from cnt
 * on read pad */
static inline void neighbour_rows(const double *x, const int *nb, int cnt, const double *pad, const double **q)
{
    for (int l = 0; l < 8; l++) q[l] = l < cnt ? x + 3 * (long)(nb[l] - 1) : pad;
}

/* the separations d = c - x_j of the eight neighbours nb[0..cnt-1] from the centre c, one vector per
 * component (the lanes from cnt on: from the row pad) */
static inline void separations(const double *x, const int *nb, int cnt, const double *pad, __m512d cx, __m512d cy,
                               __m512d cz, __m512d *dx, __m512d *dy, __m512d *dz)
{
    const double *q[8];
    neighbour_rows(x, nb, cnt, pad, q);
    rows_xyz(q, dx, dy, dz);
    *dx = _mm512_sub_pd(cx, *dx);
    *dy = _mm512_sub_pd(cy, *dy);
    *dz = _mm512_sub_pd(cz, *dz);
}
#endif
#endif
#endif
