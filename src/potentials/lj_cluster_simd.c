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
 * (nothing done: the Fortran loop runs) where this build has no AVX-512 (AVX512F). */
#if defined(__AVX512F__)
#include <immintrin.h>
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
    /* the i sums: lanes 4 s .. 4 s + 3 hold slot s's, summed in double as (a + b) + (c + d) */
    float a[3][16];
    _mm512_storeu_ps(a[0], ax); _mm512_storeu_ps(a[1], ay); _mm512_storeu_ps(a[2], az);
    for (int d = 0; d < 3; d++)
        for (int s = 0; s < 4; s++)
            fi[4 * d + s] = ((double)a[d][4 * s] + (double)a[d][4 * s + 1])
                            + ((double)a[d][4 * s + 2] + (double)a[d][4 * s + 3]);
    ew[0] = 0; ew[1] = 0;
    if (want_energy) {
        float e[16], w[16];
        _mm512_storeu_ps(e, el); _mm512_storeu_ps(w, wl);
        for (int l = 0; l < 16; l++) { ew[0] += (double)e[l]; ew[1] += (double)w[l]; }
    }
    return 1;
#else
    (void)ci; (void)nmem; (void)prange; (void)cjs; (void)mask; (void)offs; (void)masks; (void)xrep; (void)frep;
    (void)coeffs; (void)far_i; (void)want_energy; (void)fi; (void)ew;
    return 0;
#endif
}
