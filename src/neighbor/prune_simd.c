/* The prune of a neighbour list (terrace_neighbor_list, keep_within): of the neighbours
 * nb[k1..k2] (1-based, Fortran's indices into x(3, *)) of atom (xi, yi, zi), those within cutsq of
 * it, appended to out in their order; returns how many. Their positions loaded as rows
 * (core/simd_rows.h), the distance test as a mask, the passing indices written by one compressing
 * store, where the Fortran loop carries the count from one neighbour to the next. With AVX-512
 * (AVX512F, AVX512VL) eight neighbours at a time; with AVX2 four, the compression a byte shuffle
 * looked up by the four-bit mask, its store four indices whole (out needs room for 4 entries past
 * the pairs kept). Returns -1 (nothing done: the Fortran loop runs) where this build has neither. */
#include "../core/simd_rows.h"
#include "../core/fixed_point_rows.h"

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
#elif defined(__AVX2__)
    const __m256d x0 = _mm256_set1_pd(xi), y0 = _mm256_set1_pd(yi), z0 = _mm256_set1_pd(zi);
    const __m256d cs = _mm256_set1_pd(cutsq);
    int n = 0;
    for (int k = k1 - 1; k < k2; k += 4) {
        __m256d dx, dy, dz;
        const __m128i j = k2 - k >= 4 ? separations4(x, nb + k, 4, x0, y0, z0, &dx, &dy, &dz)   /* (whole: no selects) */
                                      : separations4(x, nb + k, k2 - k, x0, y0, z0, &dx, &dy, &dz);
        const __m256d rsq = _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(dx, dx), _mm256_mul_pd(dy, dy)), _mm256_mul_pd(dz, dz));
        /* (the padding lanes lie 1e100 away) */
        n += store_kept4(out + n, j, _mm256_movemask_pd(_mm256_cmp_pd(rsq, cs, _CMP_LT_OQ)));
    }
    return n;
#else
    (void)xi; (void)yi; (void)zi; (void)x; (void)nb; (void)k1; (void)k2; (void)cutsq; (void)out;
    return -1;
#endif
}

/* The rows' byte offsets of the half list first, neigh (1-based) for a pass over fixed-point
 * records (core/fixed_point_rows.h: the mixed-precision Lennard-Jones pass, terrace_prune_wrapped): row i (0-based) at
 * offs[ofirst[i] .. ofirst[i + 1] - 1], 16 (r - 1) per neighbour j, r = j or, with wrapped images
 * (wrapped != 0), its owner origin[j - 1] (1-based), and 16 nrec (the pad record) up to a multiple
 * of 16 entries; nrec the records the pass stages (nall, or nlocal with wrapped images); offs must
 * have room for first[nlocal] - 1 + 15 nlocal entries. Returns the entries written, or -1 (nothing
 * done) where the build has no SIMD pass over such records (AVX-512, or AVX2: one entry at a time). */
int terrace_row_offsets(int nlocal, int nrec, const int *first, const int *neigh, int wrapped, const int *origin,
                             int *ofirst, int32_t *offs)
{
#if defined(TERRACE_FIXED_ROWS)
    if (nrec >= terrace_fixed_max_atoms) return -1;
    /* sixteen neighbours at a time (the owners gathered with wrapped images); the row's last block
     * under a mask, its empty lanes the pad record's offset */
    const __m512i one = _mm512_set1_epi32(1), pad = _mm512_set1_epi32(16 * nrec);
    int o = 0;
    for (int i = 0; i < nlocal; i++) {
        ofirst[i] = o;
        const int k0 = first[i] - 1, nn = first[i + 1] - first[i];
        for (int k = 0; k < nn; k += 16) {
            const __mmask16 m = nn - k >= 16 ? (__mmask16)0xFFFF : (__mmask16)((1u << (nn - k)) - 1u);
            __m512i j = _mm512_sub_epi32(_mm512_maskz_loadu_epi32(m, neigh + k0 + k), one);
            if (wrapped) j = _mm512_sub_epi32(_mm512_mask_i32gather_epi32(one, m, j, origin, 4), one);
            _mm512_storeu_si512(offs + o + k, _mm512_mask_blend_epi32(m, pad, _mm512_slli_epi32(j, 4)));
        }
        o += (nn + 15) / 16 * 16;
    }
    ofirst[nlocal] = o;
    return o;
#elif defined(TERRACE_FIXED_ROWS8)
    if (nrec >= terrace_fixed_max_atoms) return -1;
    int o = 0;   /* (rows padded to 16 entries as above: one layout for both passes) */
    for (int i = 0; i < nlocal; i++) {
        ofirst[i] = o;
        const int k0 = first[i] - 1, nn = first[i + 1] - first[i], padded = (nn + 15) / 16 * 16;
        for (int k = 0; k < nn; k++) {
            const int j = neigh[k0 + k] - 1;
            offs[o + k] = 16 * (wrapped ? origin[j] - 1 : j);
        }
        for (int k = nn; k < padded; k++) offs[o + k] = 16 * nrec;
        o += padded;
    }
    ofirst[nlocal] = o;
    return o;
#else
    (void)nlocal; (void)nrec; (void)first; (void)neigh; (void)wrapped; (void)origin; (void)ofirst; (void)offs;
    return -1;
#endif
}


/* The prune of a list with wrapped images (terrace_neighbor_list, nl_prune): the positions x of the
 * nlocal owned atoms staged on the periodic grid of the box wrap = (lo(3), length(3)) into q (4,
 * nlocal + 1), and of each row of the outer list (first, neigh 1-based; ofirst, offs its rows'
 * byte offsets of the owners' records, terrace_row_offsets) the neighbours within cutsq of the atom
 * at their nearest images, in their order, written as a list (first_in, neigh_in: 1-based, the
 * outer list's indices) and as its byte offsets (ofirst_in, offs_in, rows padded to 16 entries with
 * the pad record's, as terrace_row_offsets forms them): the prune and the mixed pass's offsets in
 * one pass, sixteen pairs at a time in single precision (the test is kept a millionth wide: a pair
 * at the cutoff is kept). neigh_in needs room for 16 entries past the pairs kept, offs_in for 16
 * past its last padded row. With AVX2 the same, eight pairs at a time, each half compressed by
 * store_kept4 (core/simd_rows.h). Returns the pairs kept, or -1 (nothing done) without either. */
int terrace_prune_wrapped(int nlocal, const double *x, const double *wrap, int32_t *q, const int *first,
                          const int *neigh, const int *ofirst, const int32_t *offs, double cutsq, int *first_in,
                          int *neigh_in, int *ofirst_in, int32_t *offs_in)
{
#if defined(TERRACE_FIXED_ROWS)
    stage_periodic(nlocal, x, wrap, q, (float *)0);
    const __m512 ux = _mm512_set1_ps((float)(wrap[3] * ldexp(1.0, -32)));
    const __m512 uy = _mm512_set1_ps((float)(wrap[4] * ldexp(1.0, -32)));
    const __m512 uz = _mm512_set1_ps((float)(wrap[5] * ldexp(1.0, -32)));
    const __m512 cs = _mm512_set1_ps((float)(cutsq * (1 + 1e-6)));
    const __m512i pad = _mm512_set1_epi32(16 * nlocal);
    const char *qb = (const char *)q;
    int n = 0, o = 0;
    first_in[0] = 1;
    for (int i = 0; i < nlocal; i++) {
        ofirst_in[i] = o;
        const int k0 = first[i] - 1, nn = first[i + 1] - first[i];
        const int32_t *a = q + 4 * (long)i;
        const __m512i xi = _mm512_set1_epi32(a[0]), yi = _mm512_set1_epi32(a[1]), zi = _mm512_set1_epi32(a[2]);
        const int o0 = o;
        for (int k = 0; k < nn; k += 16) {
            const __mmask16 live = nn - k >= 16 ? (__mmask16)0xFFFF : (__mmask16)((1u << (nn - k)) - 1u);
            const int32_t *off = offs + ofirst[i] + k;
            __m512 qx, qy, qz;
            rows_n(16, qb, off, &qx, &qy, &qz);   /* (the padding lanes read the pad record, masked) */
            const __m512 dx = _mm512_mul_ps(_mm512_cvtepi32_ps(_mm512_sub_epi32(xi, _mm512_castps_si512(qx))), ux);
            const __m512 dy = _mm512_mul_ps(_mm512_cvtepi32_ps(_mm512_sub_epi32(yi, _mm512_castps_si512(qy))), uy);
            const __m512 dz = _mm512_mul_ps(_mm512_cvtepi32_ps(_mm512_sub_epi32(zi, _mm512_castps_si512(qz))), uz);
            const __m512 rsq = _mm512_fmadd_ps(dz, dz, _mm512_fmadd_ps(dx, dx, _mm512_mul_ps(dy, dy)));
            const __mmask16 keep = _mm512_mask_cmp_ps_mask(live, rsq, cs, _CMP_LT_OQ);
            /* compressed in registers and stored whole (a compressing store to memory is microcoded
             * on Intel cores): the lanes past the kept ones are overwritten next */
            _mm512_storeu_si512(neigh_in + n, _mm512_maskz_compress_epi32(keep, _mm512_maskz_loadu_epi32(live, neigh + k0 + k)));
            _mm512_storeu_si512(offs_in + o, _mm512_maskz_compress_epi32(keep, _mm512_loadu_si512(off)));
            const int kept = __builtin_popcount(keep);
            n += kept;
            o += kept;
        }
        const int padded = o0 + (o - o0 + 15) / 16 * 16;
        if (padded > o) _mm512_storeu_si512(offs_in + o, pad);   /* (room: the outer rows' padding) */
        o = padded;
        first_in[i + 1] = n + 1;
    }
    ofirst_in[nlocal] = o;
    return n;
#elif defined(TERRACE_FIXED_ROWS8)
    stage_periodic(nlocal, x, wrap, q, (float *)0);
    const __m256 ux = _mm256_set1_ps((float)(wrap[3] * ldexp(1.0, -32)));
    const __m256 uy = _mm256_set1_ps((float)(wrap[4] * ldexp(1.0, -32)));
    const __m256 uz = _mm256_set1_ps((float)(wrap[5] * ldexp(1.0, -32)));
    const __m256 cs = _mm256_set1_ps((float)(cutsq * (1 + 1e-6)));
    const __m256i pad = _mm256_set1_epi32(16 * nlocal), lane = _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7);
    const char *qb = (const char *)q;
    int n = 0, o = 0;
    first_in[0] = 1;
    for (int i = 0; i < nlocal; i++) {
        ofirst_in[i] = o;
        const int k0 = first[i] - 1, nn = first[i + 1] - first[i];
        const int32_t *a = q + 4 * (long)i;
        const __m256i xi = _mm256_set1_epi32(a[0]), yi = _mm256_set1_epi32(a[1]), zi = _mm256_set1_epi32(a[2]);
        const int o0 = o;
        for (int k = 0; k < nn; k += 8) {   /* (the outer rows are padded to 16 offsets: eight to read) */
            const __m256i live = _mm256_cmpgt_epi32(_mm256_set1_epi32(nn - k), lane);
            const int32_t *off = offs + ofirst[i] + k;
            __m256 qx, qy, qz;
            rows8(8, qb, off, &qx, &qy, &qz);   /* (the padding lanes read the pad record, masked) */
            const __m256 dx = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_sub_epi32(xi, _mm256_castps_si256(qx))), ux);
            const __m256 dy = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_sub_epi32(yi, _mm256_castps_si256(qy))), uy);
            const __m256 dz = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_sub_epi32(zi, _mm256_castps_si256(qz))), uz);
            const __m256 rsq = _mm256_fmadd_ps(dz, dz, _mm256_fmadd_ps(dx, dx, _mm256_mul_ps(dy, dy)));
            const int keep = _mm256_movemask_ps(_mm256_and_ps(_mm256_castsi256_ps(live), _mm256_cmp_ps(rsq, cs, _CMP_LT_OQ)));
            const __m256i j = _mm256_maskload_epi32(neigh + k0 + k, live), r = _mm256_loadu_si256((const __m256i *)off);
            n += store_kept4(neigh_in + n, _mm256_castsi256_si128(j), keep & 15);
            n += store_kept4(neigh_in + n, _mm256_extracti128_si256(j, 1), keep >> 4);
            o += store_kept4(offs_in + o, _mm256_castsi256_si128(r), keep & 15);
            o += store_kept4(offs_in + o, _mm256_extracti128_si256(r, 1), keep >> 4);
        }
        const int padded = o0 + (o - o0 + 15) / 16 * 16;
        if (padded > o) {   /* (room: the outer rows' padding) */
            _mm256_storeu_si256((__m256i *)(offs_in + o), pad);
            _mm256_storeu_si256((__m256i *)(offs_in + o + 8), pad);
        }
        o = padded;
        first_in[i + 1] = n + 1;
    }
    ofirst_in[nlocal] = o;
    return n;
#else
    (void)nlocal; (void)x; (void)wrap; (void)q; (void)first; (void)neigh; (void)ofirst; (void)offs; (void)cutsq;
    (void)first_in; (void)neigh_in; (void)ofirst_in; (void)offs_in;
    return -1;
#endif
}
