/* The mixed-precision cluster-pair kernel's inner pass (terrace_lj_cluster, cluster_pairs) with
 * AVX-512: the 16 atom pairs of a listed cluster pair are one 16-lane single-precision register
 * (lane l: slot l/4 of ci against slot l mod 4 of cj, 0-based), the j cluster's replicated record
 * xrep(16, 3, cj) three plain loads, its force record three loads and three stores, no shuffle.
 * The operations are the Fortran lane loop's (lj_cluster_lanes.inc), with fused multiply-adds
 * where GCC contracts that loop (r^2 = fma(dz, dz, fma(dy, dy, dx dx)) + mask; a + b c as fma); single
 * roundings still differ here and there, so the forces agree with the Fortran loop's to single
 * precision, not bit for bit (tests/regression/mixed_precision.sh bounds both against the double
 * kernel). GCC compiles the Fortran loop to 256-bit halves on this generation of Intel cores (its
 * preferred vector width), two passes per cluster pair and the i sums kept in memory; here one
 * 512-bit pass with the sums in registers: the argon job's Pair phase with the mixed kernel 0.84 of
 * the Fortran loop's (doc/performance.md).
 *
 * Arguments as cluster_pairs has them: ci and cjs 1-based cluster indices, prange the pairs
 * (first, first with a mask row, last; 1-based), masks(16, *) the mask rows, offs(3, *) the
 * centres' offsets, xrep and frep (16, 3, *), coeffs (lj1, lj2, lj3, lj4, cutsq, offset), far_i
 * the i side's empty slot (-far_slot of terrace_cluster_list); out: fi
 * (4, 3) the four i sums in double, ew (energy, virial) with want_energy (else 0). Returns 0
 * (nothing done: the Fortran loop runs) where this build has neither AVX-512 (AVX512F) nor AVX2
 * and FMA.
 *
 * With AVX2 and FMA but no AVX-512 (half8, both halves in one loop over the pairs): the same
 * operations on the two halves of the 16 lanes in 256-bit registers, slots 0 and 1 of ci in the
 * lower half and 2 and 3 in the upper one; the lanes outside the cutoff zeroed by an and with the
 * comparison's mask where AVX-512 has a masked division (the same zeros), the offset likewise.
 * GCC's code for the Fortran loop ran the argon slice's Pair phase 5.6 times as long on an AMD
 * EPYC (doc/performance.md). */
#if defined(__AVX512F__) || (defined(__AVX2__) && defined(__FMA__))
#include <immintrin.h>

/* the pass's results from its 16 lanes: lanes 4 s .. 4 s + 3 of a[d] hold slot s's i sum along d,
 * summed in double as (a + b) + (c + d); with want_energy the energy and virial lanes e and w
 * summed in double in lane order (ew: zero without) */
static void lane_sums(const float a[3][16], int want_energy, const float *e, const float *w, double *fi, double *ew)
{
    for (int d = 0; d < 3; d++)
        for (int s = 0; s < 4; s++)
            fi[4 * d + s] = ((double)a[d][4 * s] + (double)a[d][4 * s + 1])
                            + ((double)a[d][4 * s + 2] + (double)a[d][4 * s + 3]);
    ew[0] = 0; ew[1] = 0;
    if (want_energy)
        for (int l = 0; l < 16; l++) { ew[0] += (double)e[l]; ew[1] += (double)w[l]; }
}
#endif

#if defined(__AVX2__) && defined(__FMA__) && !defined(__AVX512F__)
/* one half of a cluster pair's 16 lanes (h = 0: lanes 0-7, slots 0 and 1 of ci; h = 1: lanes 8-15,
 * slots 2 and 3): its pair forces into the i sums (ax, ay, az) and cj's force record fj, and with
 * want_energy its energy and virial lanes (el, wl) */
static inline __attribute__((always_inline)) void half8(const int want_energy, __m256 xi, __m256 yi, __m256 zi,
                                                        const float *o, const float *xj, float *fj, __m256 madd,
                                                        const float *coeffs, __m256 *ax, __m256 *ay, __m256 *az,
                                                        __m256 *el, __m256 *wl)
{
    const __m256 dx = _mm256_sub_ps(_mm256_sub_ps(xi, _mm256_set1_ps(o[0])), _mm256_loadu_ps(xj));
    const __m256 dy = _mm256_sub_ps(_mm256_sub_ps(yi, _mm256_set1_ps(o[1])), _mm256_loadu_ps(xj + 16));
    const __m256 dz = _mm256_sub_ps(_mm256_sub_ps(zi, _mm256_set1_ps(o[2])), _mm256_loadu_ps(xj + 32));
    const __m256 r2 = _mm256_add_ps(_mm256_fmadd_ps(dz, dz, _mm256_fmadd_ps(dy, dy, _mm256_mul_ps(dx, dx))), madd);
    const __m256 in = _mm256_cmp_ps(r2, _mm256_set1_ps(coeffs[4]), _CMP_LT_OQ);
    const __m256 r2i = _mm256_and_ps(in, _mm256_div_ps(_mm256_set1_ps(1.0f), r2));
    const __m256 r6 = _mm256_mul_ps(_mm256_mul_ps(r2i, r2i), r2i);
    const __m256 fp = _mm256_mul_ps(
        _mm256_mul_ps(r6, _mm256_fmsub_ps(r6, _mm256_set1_ps(coeffs[0]), _mm256_set1_ps(coeffs[1]))), r2i);
    *ax = _mm256_fmadd_ps(fp, dx, *ax); *ay = _mm256_fmadd_ps(fp, dy, *ay); *az = _mm256_fmadd_ps(fp, dz, *az);
    _mm256_storeu_ps(fj, _mm256_fnmadd_ps(fp, dx, _mm256_loadu_ps(fj)));
    _mm256_storeu_ps(fj + 16, _mm256_fnmadd_ps(fp, dy, _mm256_loadu_ps(fj + 16)));
    _mm256_storeu_ps(fj + 32, _mm256_fnmadd_ps(fp, dz, _mm256_loadu_ps(fj + 32)));
    if (want_energy) {
        *el = _mm256_fmadd_ps(r6, _mm256_fmsub_ps(r6, _mm256_set1_ps(coeffs[2]), _mm256_set1_ps(coeffs[3])), *el);
        *el = _mm256_sub_ps(*el, _mm256_and_ps(in, _mm256_set1_ps(coeffs[5])));   /* the offset inside the cutoff */
        *wl = _mm256_fmadd_ps(fp, r2, *wl);
    }
}
#endif

int terrace_lj_cluster_pairs(int ci, int nmem, const int *prange, const int *cjs, const int *mask, const float *offs,
                             const float *masks, const float *xrep, float *frep, const float *coeffs, float far_i,
                             int want_energy, double *fi, double *ew)
{
#if defined(__AVX512F__)
    /* ci's slots spread over the lanes (i0 i0 i0 i0 i1 ...), empty slots at far_i (-far_slot) */
    const __m512i spread = _mm512_set_epi32(3, 3, 3, 3, 2, 2, 2, 2, 1, 1, 1, 1, 0, 0, 0, 0);
    const __mmask16 empty = (__mmask16)(0xffffu << (4 * (nmem < 4 ? nmem : 4)));
    const float *xc = xrep + 48 * (long)(ci - 1);
    const __m512 far = _mm512_set1_ps(far_i);
    const __m512 xi = _mm512_mask_mov_ps(_mm512_permutexvar_ps(spread, _mm512_loadu_ps(xc)), empty, far);
    const __m512 yi = _mm512_mask_mov_ps(_mm512_permutexvar_ps(spread, _mm512_loadu_ps(xc + 16)), empty, far);
    const __m512 zi = _mm512_mask_mov_ps(_mm512_permutexvar_ps(spread, _mm512_loadu_ps(xc + 32)), empty, far);
    const __m512 lj1 = _mm512_set1_ps(coeffs[0]), lj2 = _mm512_set1_ps(coeffs[1]);
    const __m512 lj3 = _mm512_set1_ps(coeffs[2]), lj4 = _mm512_set1_ps(coeffs[3]);
    const __m512 cutsq = _mm512_set1_ps(coeffs[4]), offset = _mm512_set1_ps(coeffs[5]);
    const __m512 one = _mm512_set1_ps(1.0f), zero = _mm512_setzero_ps();
    __m512 ax = zero, ay = zero, az = zero, el = zero, wl = zero, madd = zero;
    for (int p = prange[0] - 1; p < prange[2]; p++) {
        const long cj = cjs[p] - 1;
        if (p >= prange[1] - 1) madd = _mm512_loadu_ps(masks + 16 * (long)(mask[p] - 1));
        const float *xj = xrep + 48 * cj;
        float *fj = frep + 48 * cj;
        const float *o = offs + 3 * (long)p;
        const __m512 dx = _mm512_sub_ps(_mm512_sub_ps(xi, _mm512_set1_ps(o[0])), _mm512_loadu_ps(xj));
        const __m512 dy = _mm512_sub_ps(_mm512_sub_ps(yi, _mm512_set1_ps(o[1])), _mm512_loadu_ps(xj + 16));
        const __m512 dz = _mm512_sub_ps(_mm512_sub_ps(zi, _mm512_set1_ps(o[2])), _mm512_loadu_ps(xj + 32));
        const __m512 r2 = _mm512_add_ps(_mm512_fmadd_ps(dz, dz, _mm512_fmadd_ps(dy, dy, _mm512_mul_ps(dx, dx))), madd);
        const __mmask16 in = _mm512_cmp_ps_mask(r2, cutsq, _CMP_LT_OQ);
        const __m512 r2i = _mm512_maskz_div_ps(in, one, r2);
        const __m512 r6 = _mm512_mul_ps(_mm512_mul_ps(r2i, r2i), r2i);
        const __m512 fp = _mm512_mul_ps(_mm512_mul_ps(r6, _mm512_fmsub_ps(r6, lj1, lj2)), r2i);
        ax = _mm512_fmadd_ps(fp, dx, ax); ay = _mm512_fmadd_ps(fp, dy, ay); az = _mm512_fmadd_ps(fp, dz, az);
        _mm512_storeu_ps(fj, _mm512_fnmadd_ps(fp, dx, _mm512_loadu_ps(fj)));
        _mm512_storeu_ps(fj + 16, _mm512_fnmadd_ps(fp, dy, _mm512_loadu_ps(fj + 16)));
        _mm512_storeu_ps(fj + 32, _mm512_fnmadd_ps(fp, dz, _mm512_loadu_ps(fj + 32)));
        if (want_energy) {
            el = _mm512_fmadd_ps(r6, _mm512_fmsub_ps(r6, lj3, lj4), el);
            el = _mm512_mask_sub_ps(el, in, el, offset);     /* the offset inside the cutoff */
            wl = _mm512_fmadd_ps(fp, r2, wl);
        }
    }
    float a[3][16], e[16], w[16];
    _mm512_storeu_ps(a[0], ax); _mm512_storeu_ps(a[1], ay); _mm512_storeu_ps(a[2], az);
    _mm512_storeu_ps(e, el); _mm512_storeu_ps(w, wl);
    lane_sums(a, want_energy, e, w, fi, ew);
    return 1;
#elif defined(__AVX2__) && defined(__FMA__)
    /* ci's slots spread over the lanes of the two halves (i0 x4 i1 x4 | i2 x4 i3 x4), the lanes of
     * empty slots (lane >= 4 nmem) at far_i */
    const float *xc = xrep + 48 * (long)(ci - 1);
    const __m256 far = _mm256_set1_ps(far_i), zero = _mm256_setzero_ps();
    const __m256i filled = _mm256_set1_epi32(4 * (nmem < 4 ? nmem : 4));
    const __m256i spread0 = _mm256_setr_epi32(0, 0, 0, 0, 1, 1, 1, 1), spread1 = _mm256_setr_epi32(2, 2, 2, 2, 3, 3, 3, 3);
    const __m256 empty0 = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_setr_epi32(1, 2, 3, 4, 5, 6, 7, 8), filled));
    const __m256 empty1 = _mm256_castsi256_ps(_mm256_cmpgt_epi32(_mm256_setr_epi32(9, 10, 11, 12, 13, 14, 15, 16), filled));
    const __m256 x = _mm256_loadu_ps(xc), y = _mm256_loadu_ps(xc + 16), z = _mm256_loadu_ps(xc + 32);
    const __m256 xi0 = _mm256_blendv_ps(_mm256_permutevar8x32_ps(x, spread0), far, empty0);
    const __m256 yi0 = _mm256_blendv_ps(_mm256_permutevar8x32_ps(y, spread0), far, empty0);
    const __m256 zi0 = _mm256_blendv_ps(_mm256_permutevar8x32_ps(z, spread0), far, empty0);
    const __m256 xi1 = _mm256_blendv_ps(_mm256_permutevar8x32_ps(x, spread1), far, empty1);
    const __m256 yi1 = _mm256_blendv_ps(_mm256_permutevar8x32_ps(y, spread1), far, empty1);
    const __m256 zi1 = _mm256_blendv_ps(_mm256_permutevar8x32_ps(z, spread1), far, empty1);
    __m256 ax0 = zero, ay0 = zero, az0 = zero, el0 = zero, wl0 = zero, madd0 = zero;
    __m256 ax1 = zero, ay1 = zero, az1 = zero, el1 = zero, wl1 = zero, madd1 = zero;
    for (int p = prange[0] - 1; p < prange[2]; p++) {
        const long cj = cjs[p] - 1;
        if (p >= prange[1] - 1) {
            const float *m = masks + 16 * (long)(mask[p] - 1);
            madd0 = _mm256_loadu_ps(m); madd1 = _mm256_loadu_ps(m + 8);
        }
        const float *o = offs + 3 * (long)p;
        half8(want_energy, xi0, yi0, zi0, o, xrep + 48 * cj, frep + 48 * cj, madd0, coeffs, &ax0, &ay0, &az0, &el0, &wl0);
        half8(want_energy, xi1, yi1, zi1, o, xrep + 48 * cj + 8, frep + 48 * cj + 8, madd1, coeffs, &ax1, &ay1, &az1,
              &el1, &wl1);
    }
    float a[3][16], e[16], w[16];
    _mm256_storeu_ps(a[0], ax0); _mm256_storeu_ps(a[1], ay0); _mm256_storeu_ps(a[2], az0);
    _mm256_storeu_ps(a[0] + 8, ax1); _mm256_storeu_ps(a[1] + 8, ay1); _mm256_storeu_ps(a[2] + 8, az1);
    _mm256_storeu_ps(e, el0); _mm256_storeu_ps(w, wl0); _mm256_storeu_ps(e + 8, el1); _mm256_storeu_ps(w + 8, wl1);
    lane_sums(a, want_energy, e, w, fi, ew);
    return 1;
#else
    (void)ci; (void)nmem; (void)prange; (void)cjs; (void)mask; (void)offs; (void)masks; (void)xrep; (void)frep;
    (void)coeffs; (void)far_i; (void)want_energy; (void)fi; (void)ew;
    return 0;
#endif
}
