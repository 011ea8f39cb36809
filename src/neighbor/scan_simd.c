/* The neighbour-list build's candidate scan (terrace_neighbor_list, scan) with AVX-512: for the
 * candidates k1..k2 (1-based) of the shared rows cx, cy, cz, cj, those within the cutoff of
 * (xi, yi, zi) and, when above, also above it in (z, y, x) order, appended to out (their atom
 * indices cj, in candidate order); returns how many. Eight candidates at a time: the distance test
 * and the order test as masks, the passing indices written by one compressing store, where the
 * Fortran scan computes 0/1 flags in one pass and compacts them in a second, a scalar loop whose
 * count carries from one candidate to the next (half of the scan's time, perf). With AVX2 four
 * candidates at a time, the compression a byte shuffle (core/simd_rows.h, store_kept4: out needs
 * room for 4 entries past those kept). Returns -1 (nothing done: the Fortran scan runs) where this
 * build has neither AVX-512 (AVX512F, AVX512VL) nor AVX2. */
#include "../core/simd_rows.h"
#if defined(__AVX512F__) && defined(__AVX512VL__)
#include <immintrin.h>
#endif

int terrace_scan_compress(double xi, double yi, double zi, const double *cx, const double *cy, const double *cz,
                          const int *cj, int k1, int k2, double cutsq, int above, int *out)
{
#if defined(__AVX512F__) && defined(__AVX512VL__)
    const __m512d x0 = _mm512_set1_pd(xi), y0 = _mm512_set1_pd(yi), z0 = _mm512_set1_pd(zi);
    const __m512d cs = _mm512_set1_pd(cutsq), zero = _mm512_setzero_pd();
    int n = 0;
    for (int k = k1 - 1; k < k2; k += 8) {
        const int cnt = k2 - k < 8 ? k2 - k : 8;
        const __mmask8 live = (__mmask8)((1u << cnt) - 1u);
        /* as the Fortran scan: above, d = c - x_i; else d = x_i - c (the same squares) */
        __m512d dx = _mm512_sub_pd(_mm512_maskz_loadu_pd(live, cx + k), x0);
        __m512d dy = _mm512_sub_pd(_mm512_maskz_loadu_pd(live, cy + k), y0);
        __m512d dz = _mm512_sub_pd(_mm512_maskz_loadu_pd(live, cz + k), z0);
        __m512d rsq = _mm512_add_pd(_mm512_add_pd(_mm512_mul_pd(dx, dx), _mm512_mul_pd(dy, dy)), _mm512_mul_pd(dz, dz));
        __mmask8 keep = _mm512_mask_cmp_pd_mask(live, rsq, cs, _CMP_LT_OQ);
        if (above) {
            __mmask8 zp = _mm512_cmp_pd_mask(dz, zero, _CMP_GT_OQ), ze = _mm512_cmp_pd_mask(dz, zero, _CMP_EQ_OQ);
            __mmask8 yp = _mm512_cmp_pd_mask(dy, zero, _CMP_GT_OQ), ye = _mm512_cmp_pd_mask(dy, zero, _CMP_EQ_OQ);
            __mmask8 xp = _mm512_cmp_pd_mask(dx, zero, _CMP_GT_OQ);
            keep &= zp | (ze & (yp | (ye & xp)));
        }
        _mm256_mask_compressstoreu_epi32(out + n, keep, _mm256_maskz_loadu_epi32(live, cj + k));
        n += __builtin_popcount(keep);
    }
    return n;
#elif defined(__AVX2__)
    const __m256d x0 = _mm256_set1_pd(xi), y0 = _mm256_set1_pd(yi), z0 = _mm256_set1_pd(zi);
    const __m256d cs = _mm256_set1_pd(cutsq), zero = _mm256_setzero_pd();
    int n = 0;
    for (int k = k1 - 1; k < k2; k += 4) {
        const int cnt = k2 - k < 4 ? k2 - k : 4;
        __m256d cxk, cyk, czk;
        __m128i j;
        if (cnt == 4) {
            cxk = _mm256_loadu_pd(cx + k); cyk = _mm256_loadu_pd(cy + k); czk = _mm256_loadu_pd(cz + k);
            j = _mm_loadu_si128((const __m128i *)(cj + k));
        } else {   /* (the rows may end here: masked loads, the dead lanes zero and dropped below) */
            const __m128i live = live4(cnt);
            const __m256i live64 = _mm256_cvtepi32_epi64(live);
            cxk = _mm256_maskload_pd(cx + k, live64); cyk = _mm256_maskload_pd(cy + k, live64);
            czk = _mm256_maskload_pd(cz + k, live64);
            j = _mm_maskload_epi32(cj + k, live);
        }
        const __m256d dx = _mm256_sub_pd(cxk, x0), dy = _mm256_sub_pd(cyk, y0), dz = _mm256_sub_pd(czk, z0);
        const __m256d rsq = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)), _mm256_mul_pd(dz, dz));
        __m256d keep = _mm256_cmp_pd(rsq, cs, _CMP_LT_OQ);
        if (above) {
            const __m256d zp = _mm256_cmp_pd(dz, zero, _CMP_GT_OQ), ze = _mm256_cmp_pd(dz, zero, _CMP_EQ_OQ);
            const __m256d yp = _mm256_cmp_pd(dy, zero, _CMP_GT_OQ), ye = _mm256_cmp_pd(dy, zero, _CMP_EQ_OQ);
            const __m256d xp = _mm256_cmp_pd(dx, zero, _CMP_GT_OQ);
            keep = _mm256_and_pd(keep, _mm256_or_pd(zp, _mm256_and_pd(ze, _mm256_or_pd(yp, _mm256_and_pd(ye, xp)))));
        }
        n += store_kept4(out + n, j, _mm256_movemask_pd(keep) & ((1 << cnt) - 1));
    }
    return n;
#else
    (void)xi; (void)yi; (void)zi; (void)cx; (void)cy; (void)cz; (void)cj; (void)k1; (void)k2; (void)cutsq;
    (void)above; (void)out;
    return -1;
#endif
}
