/* The prune of a neighbour list (terrace_neighbor_list, keep_within) with AVX-512: of the
 * neighbours nb[k1..k2] (1-based, Fortran's indices into x(3, *)) of atom (xi, yi, zi), those
 * within cutsq of it, appended to out in their order; returns how many. Eight neighbours at a
 * time: their positions loaded as rows (core/simd_rows.h), the distance test as a mask, the passing indices written by one
 * compressing store, where the Fortran loop carries the count from one neighbour to the next.
 * Returns -1 (nothing done: the Fortran loop runs) where this build has no AVX-512 (AVX512F,
 * AVX512VL). */
#include "../core/simd_rows.h"

int terrace_prune_compress(double xi, double yi, double zi, const double *x, const int *nb, int k1, int k2,
                           double cutsq, int *out)
{
#if defined(__AVX512F__) && defined(__AVX512VL__)
    const __m512d x0 = _mm512_set1_pd(xi), y0 = _mm512_set1_pd(yi), z0 = _mm512_set1_pd(zi);
    const __m512d cs = _mm512_set1_pd(cutsq);
    int n = 0;
    for (int k = k1 - 1; k < k2; k += 8) {
        const int cnt = k2 - k < 8 ? k2 - k : 8;
        const __mmask8 live = (__mmask8)((1u << cnt) - 1u);
        const __m256i j = _mm256_maskz_loadu_epi32(live, nb + k);
        __m512d dx, dy, dz;
        separations(x, nb + k, cnt, x, x0, y0, z0, &dx, &dy, &dz);     /* (the padding lanes: masked off) */
        __m512d rsq = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)), _mm512_mul_pd(dz, dz));
        __mmask8 keep = _mm512_mask_cmp_pd_mask(live, rsq, cs, _CMP_LT_OQ);
        _mm256_mask_compressstoreu_epi32(out + n, keep, j);
        n += __builtin_popcount(keep);
    }
    return n;
#else
    (void)xi; (void)yi; (void)zi; (void)x; (void)nb; (void)k1; (void)k2; (void)cutsq; (void)out;
    return -1;
#endif
}
