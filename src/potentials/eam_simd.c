/* The EAM density passes' gather (terrace_eam, gather_inside) with AVX-512: of the nn partners
 * neigh[0..nn-1] (1-based atom indices, as Fortran has them) of the atom at (xi, yi, zi), those
 * inside the cutoff (r^2 < cutsq) appended to cj and their squared distances to pp, in list order;
 * returns how many. Eight partners at a time: their positions loaded as rows (core/simd_rows.h), the
 * squared distances as the Fortran loop forms them (d = x_i - x_j, fma(dz, dz, fma(dx, dx, dy dy)):
 * the same bits), the cutoff test as a mask, and the kept indices and distances written by
 * compressing stores (vpcompressd, vcompresspd). The Fortran loop is scalar: three loads, a
 * compaction whose count carries from one partner to the next (a fifth of an EAM run, perf).
 * With AVX2 and FMA four partners at a time, the compressing stores a shuffle and a permute looked
 * up by the mask (core/simd_rows.h: store_kept4, store_kept4d; cj and pp need room for 4 entries
 * past those kept). Returns -1 (nothing done: the Fortran loop runs) where this build has neither
 * AVX-512 (AVX512F, AVX512VL) nor AVX2, each with FMA. */
#include "../core/simd_rows.h"

int terrace_eam_gather_inside(double xi, double yi, double zi, const double *x, const int *neigh, int nn, double cutsq,
                              int *cj, double *pp)
{
#if defined(__AVX512F__) && defined(__AVX512VL__) && defined(__FMA__)
    const __m512d x0 = _mm512_set1_pd(xi), y0 = _mm512_set1_pd(yi), z0 = _mm512_set1_pd(zi);
    const __m512d cs = _mm512_set1_pd(cutsq);
    int n = 0;
    for (int k = 0; k < nn; k += 8) {
        const int cnt = nn - k < 8 ? nn - k : 8;
        const __mmask8 live = (__mmask8)((1u << cnt) - 1u);
        const __m256i jj = _mm256_maskz_loadu_epi32(live, neigh + k);
        __m512d dx, dy, dz;
        separations(x, neigh + k, cnt, x, x0, y0, z0, &dx, &dy, &dz);  /* (the padding lanes: masked off) */
        const __m512d rsq = _mm512_fmadd_pd(dz, dz, _mm512_fmadd_pd(dx, dx, _mm512_mul_pd(dy, dy)));
        const __mmask8 keep = _mm512_mask_cmp_pd_mask(live, rsq, cs, _CMP_LT_OQ);
        _mm256_mask_compressstoreu_epi32(cj + n, keep, jj);
        _mm512_mask_compressstoreu_pd(pp + n, keep, rsq);
        n += __builtin_popcount(keep);
    }
    return n;
#elif defined(__AVX2__) && defined(__FMA__)
    const __m256d x0 = _mm256_set1_pd(xi), y0 = _mm256_set1_pd(yi), z0 = _mm256_set1_pd(zi);
    const __m256d cs = _mm256_set1_pd(cutsq);
    int n = 0;
    for (int k = 0; k < nn; k += 4) {
        __m256d dx, dy, dz;
        const __m128i jj = nn - k >= 4 ? separations4(x, neigh + k, 4, x0, y0, z0, &dx, &dy, &dz)   /* (whole: no selects) */
                                       : separations4(x, neigh + k, nn - k, x0, y0, z0, &dx, &dy, &dz);
        const __m256d rsq = _mm256_fmadd_pd(dz, dz, _mm256_fmadd_pd(dx, dx, _mm256_mul_pd(dy, dy)));
        const int keep = _mm256_movemask_pd(_mm256_cmp_pd(rsq, cs, _CMP_LT_OQ));   /* (padding: 1e100 away) */
        store_kept4d(pp + n, rsq, keep);
        n += store_kept4(cj + n, jj, keep);
    }
    return n;
#else
    (void)xi; (void)yi; (void)zi; (void)x; (void)neigh; (void)nn; (void)cutsq; (void)cj; (void)pp;
    return -1;
#endif
}
