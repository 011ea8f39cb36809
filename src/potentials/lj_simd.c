/* The Lennard-Jones ray pass's gather (terrace_lj, ray_rows): for atom i and its neighbours
 * j = nbrs[0..nn-1] (1-based, as Fortran has them), from the records xv = (x + s v, v), six doubles
 * per atom, the three scalars of each pair: rr = |d|^2, dw = d.w, ww = |w|^2 with d = x_i - x_j and
 * w = v_i - v_j.
 *
 * Why C: the gather is the larger half of a ray evaluation, and as Fortran it is scalar (six loads,
 * six differences, nine products per pair: about 27 instructions). GCC vectorises it only with
 * gather instructions, which were slower on both machines. With AVX2 four neighbours are done at
 * once, as GROMACS's nbnxm kernels load their j-clusters: each record is loaded as three 16-byte
 * halves, two records per 32-byte register (the upper half inserted from memory), and one unpack
 * per component turns the four records into four-wide rows of x, y, z, vx, vy, vz (12 loads and 6
 * unpacks for 4 pairs); the differences and products then run four-wide, in the same order and with
 * the same fused multiply-adds as the scalar loop, so the results are the same bits. With AVX-512
 * eight at a time first (four records per 64-byte register, the same unpacks; the ray pass's Search
 * phase another 8-9 % cheaper than with four, phase_ab.sh on both liquids):
 *   rr = fma(dz, dz, fma(dx, dx, dy*dy)), dw = fma(dz, wz, fma(dx, wx, dy*wy)),
 *   ww = fma(wz, wz, fma(wx, wx, wy*wy)).
 * Without AVX2 and FMA (a portable build), or for the last nn mod 4 pairs, the scalar loop. */
#include <math.h>
#if defined(__AVX2__) && defined(__FMA__)
#include <immintrin.h>
#endif

static inline void one_pair(const double *a, const double *b, double *rr, double *dw, double *ww)
{
    double dx = a[0] - b[0], dy = a[1] - b[1], dz = a[2] - b[2];
    double wx = a[3] - b[3], wy = a[4] - b[4], wz = a[5] - b[5];
#if defined(__FMA__)
    *rr = fma(dz, dz, fma(dx, dx, dy * dy));
    *dw = fma(dz, wz, fma(dx, wx, dy * wy));
    *ww = fma(wz, wz, fma(wx, wx, wy * wy));
#else
    *rr = dx * dx + dy * dy + dz * dz;
    *dw = dx * wx + dy * wy + dz * wz;
    *ww = wx * wx + wy * wy + wz * wz;
#endif
}

#if defined(__AVX2__) && defined(__FMA__)
/* two 16-byte halves, p in the lower lane and q in the upper one */
static inline __m256d halves(const double *p, const double *q)
{
    return _mm256_insertf128_pd(_mm256_castpd128_pd256(_mm_loadu_pd(p)), _mm_loadu_pd(q), 1);
}
#if defined(__AVX512F__)
/* four 16-byte halves, p q r t in the four lanes */
static inline __m512d quarters(const double *p, const double *q, const double *r, const double *t)
{
    return _mm512_insertf64x4(_mm512_castpd256_pd512(halves(p, q)), halves(r, t), 1);
}
#endif
#endif

void terrace_ray_rows(int i, const double *xv, const int *nbrs, int nn, double *rr, double *dw, double *ww)
{
    const double *a = xv + 6 * (long)(i - 1);
    int k = 0;
#if defined(__AVX2__) && defined(__FMA__)
    const __m256d xi = _mm256_set1_pd(a[0]), yi = _mm256_set1_pd(a[1]), zi = _mm256_set1_pd(a[2]);
    const __m256d vxi = _mm256_set1_pd(a[3]), vyi = _mm256_set1_pd(a[4]), vzi = _mm256_set1_pd(a[5]);
#if defined(__AVX512F__)
    {
        const __m512d xi8 = _mm512_set1_pd(a[0]), yi8 = _mm512_set1_pd(a[1]), zi8 = _mm512_set1_pd(a[2]);
        const __m512d vxi8 = _mm512_set1_pd(a[3]), vyi8 = _mm512_set1_pd(a[4]), vzi8 = _mm512_set1_pd(a[5]);
        for (; k + 8 <= nn; k += 8) {
            const double *p[8];
            for (int l = 0; l < 8; l++) p[l] = xv + 6 * (long)(nbrs[k + l] - 1);
            __m512d r[6];
            for (int h = 0; h < 3; h++) {
                /* records 0 2 4 6 and 1 3 5 7: unpacked, the eight pairs in order */
                r[2 * h] = quarters(p[0] + 2 * h, p[2] + 2 * h, p[4] + 2 * h, p[6] + 2 * h);
                r[2 * h + 1] = quarters(p[1] + 2 * h, p[3] + 2 * h, p[5] + 2 * h, p[7] + 2 * h);
            }
            __m512d dx = _mm512_sub_pd(xi8, _mm512_unpacklo_pd(r[0], r[1]));
            __m512d dy = _mm512_sub_pd(yi8, _mm512_unpackhi_pd(r[0], r[1]));
            __m512d dz = _mm512_sub_pd(zi8, _mm512_unpacklo_pd(r[2], r[3]));
            __m512d wx = _mm512_sub_pd(vxi8, _mm512_unpackhi_pd(r[2], r[3]));
            __m512d wy = _mm512_sub_pd(vyi8, _mm512_unpacklo_pd(r[4], r[5]));
            __m512d wz = _mm512_sub_pd(vzi8, _mm512_unpackhi_pd(r[4], r[5]));
            _mm512_storeu_pd(rr + k, _mm512_fmadd_pd(dz, dz, _mm512_fmadd_pd(dx, dx, _mm512_mul_pd(dy, dy))));
            _mm512_storeu_pd(dw + k, _mm512_fmadd_pd(dz, wz, _mm512_fmadd_pd(dx, wx, _mm512_mul_pd(dy, wy))));
            _mm512_storeu_pd(ww + k, _mm512_fmadd_pd(wz, wz, _mm512_fmadd_pd(wx, wx, _mm512_mul_pd(wy, wy))));
        }
    }
#endif
    for (; k + 4 <= nn; k += 4) {
        const double *p0 = xv + 6 * (long)(nbrs[k] - 1), *p1 = xv + 6 * (long)(nbrs[k + 1] - 1);
        const double *p2 = xv + 6 * (long)(nbrs[k + 2] - 1), *p3 = xv + 6 * (long)(nbrs[k + 3] - 1);
        /* (x0 y0 | x2 y2), (x1 y1 | x3 y3): unpacked, (x0 x1 x2 x3) and (y0 y1 y2 y3) */
        __m256d r0 = halves(p0, p2), r1 = halves(p1, p3);
        __m256d r2 = halves(p0 + 2, p2 + 2), r3 = halves(p1 + 2, p3 + 2);
        __m256d r4 = halves(p0 + 4, p2 + 4), r5 = halves(p1 + 4, p3 + 4);
        __m256d dx = _mm256_sub_pd(xi, _mm256_unpacklo_pd(r0, r1));
        __m256d dy = _mm256_sub_pd(yi, _mm256_unpackhi_pd(r0, r1));
        __m256d dz = _mm256_sub_pd(zi, _mm256_unpacklo_pd(r2, r3));
        __m256d wx = _mm256_sub_pd(vxi, _mm256_unpackhi_pd(r2, r3));
        __m256d wy = _mm256_sub_pd(vyi, _mm256_unpacklo_pd(r4, r5));
        __m256d wz = _mm256_sub_pd(vzi, _mm256_unpackhi_pd(r4, r5));
        _mm256_storeu_pd(rr + k, _mm256_fmadd_pd(dz, dz, _mm256_fmadd_pd(dx, dx, _mm256_mul_pd(dy, dy))));
        _mm256_storeu_pd(dw + k, _mm256_fmadd_pd(dz, wz, _mm256_fmadd_pd(dx, wx, _mm256_mul_pd(dy, wy))));
        _mm256_storeu_pd(ww + k, _mm256_fmadd_pd(wz, wz, _mm256_fmadd_pd(wx, wx, _mm256_mul_pd(wy, wy))));
    }
#endif
    for (; k < nn; k++)
        one_pair(a, xv + 6 * (long)(nbrs[k] - 1), rr + k, dw + k, ww + k);
}

