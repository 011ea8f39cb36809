/* The candidate filter of event-driven dynamics' prediction (terrace_event_driven, earliest_event):
 * of the atoms of the 27 cells around atom i, those that provably cannot give i an event sooner
 * than `best` (its cell crossing), dropped before the exact per-pair search, which then runs over
 * the rest in the same order with the same arithmetic: the prediction is the same bits.
 *
 * Records pk(8, n) (Fortran order, 1-based indices in cand): x(3) at the atom's own time tl, tl,
 * v(3), type. With y = dx / L per component, the image is the one earliest_event takes
 * (k = 1 for y >= 1/2, -1 for y <= -1/2). A candidate j is dropped when it is i, or when it lies
 * clearly outside the largest first radius of i's pairs (|dx|^2 > r2far (1 + 1e-6); inside it the
 * pair may be bound, and the search looks it up) and then either
 *   - it moves away (b = dx.dv >= 0): no inward crossing; or
 *   - it misses even the largest sphere: D = b^2 - |dv|^2 (|dx|^2 - r2far) < -1e-12 (b^2 + |dv|^2 c);
 *   - or it reaches it no sooner than best: the inward time c / (-b + sqrt(D)) is at least
 *     c / (-2 b) (D <= b^2), and c > best (-2 b) (1 + 1e-12), c = |dx|^2 - r2far.
 * The margins cover the round-off between this arithmetic and the search's (which may fuse other
 * products); a candidate with any |y| within 1e-9 of 1/2 (an image the two might choose
 * differently) is always kept. With AVX2 four candidates per step, the kept indices compressed by
 * store_kept4; otherwise scalar. Returns the number kept (written to kept, room for m + 4). */
#include <math.h>
#include "../core/simd_rows.h"

static int drop_one(const double *pk, int i, int j, double t, const double *xi, const double *vi,
                    const double *length, const double *inv_len, double r2far, double best)
{
    if (j == i) return 1;
    const double *p = pk + 8 * (long)(j - 1);
    double dx[3], dv[3];
    for (int k = 0; k < 3; k++) {
        const double d = xi[k] - (p[k] + p[4 + k] * (t - p[3]));
        const double y = d * inv_len[k];
        if (fabs(fabs(y) - 0.5) < 1.0e-9) return 0;
        dx[k] = d - length[k] * (y >= 0.5 ? 1.0 : (y <= -0.5 ? -1.0 : 0.0));
        dv[k] = vi[k] - p[4 + k];
    }
    const double rsq = dx[0] * dx[0] + dx[1] * dx[1] + dx[2] * dx[2];
    if (!(rsq > r2far * (1.0 + 1.0e-6))) return 0;
    const double b = dx[0] * dv[0] + dx[1] * dv[1] + dx[2] * dv[2];
    if (b >= 0) return 1;
    const double vv = dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2], c = rsq - r2far;
    if (b * b - vv * c < -1.0e-12 * (b * b + vv * c)) return 1;
    return c > best * (-2.0 * b) * (1.0 + 1.0e-12);
}

int terrace_event_filter(const double *pk, int i, const int *cand, int m, double t, const double *xi,
                         const double *vi, const double *length, const double *inv_len, double r2far, double best,
                         int *kept)
{
    int n = 0, k = 0;
#if defined(__AVX2__) && defined(__FMA__)
    const __m256d vt = _mm256_set1_pd(t), r2hi = _mm256_set1_pd(r2far * (1.0 + 1.0e-6)), r2 = _mm256_set1_pd(r2far);
    const __m256d limit = _mm256_set1_pd(best * (1.0 + 1.0e-12)), half = _mm256_set1_pd(0.5), one = _mm256_set1_pd(1.0);
    const __m256d zero = _mm256_setzero_pd(), tiny = _mm256_set1_pd(1.0e-9), rel = _mm256_set1_pd(1.0e-12);
    const __m256d sign = _mm256_set1_pd(-0.0), mhalf = _mm256_set1_pd(-0.5), mtwo = _mm256_set1_pd(-2.0);
    const __m256d xiv[3] = {_mm256_set1_pd(xi[0]), _mm256_set1_pd(xi[1]), _mm256_set1_pd(xi[2])};
    const __m256d viv[3] = {_mm256_set1_pd(vi[0]), _mm256_set1_pd(vi[1]), _mm256_set1_pd(vi[2])};
    const __m256d len[3] = {_mm256_set1_pd(length[0]), _mm256_set1_pd(length[1]), _mm256_set1_pd(length[2])};
    const __m256d inv[3] = {_mm256_set1_pd(inv_len[0]), _mm256_set1_pd(inv_len[1]), _mm256_set1_pd(inv_len[2])};
    for (; k + 4 <= m; k += 4) {
        const double *p0 = pk + 8 * (long)(cand[k] - 1), *p1 = pk + 8 * (long)(cand[k + 1] - 1);
        const double *p2 = pk + 8 * (long)(cand[k + 2] - 1), *p3 = pk + 8 * (long)(cand[k + 3] - 1);
        /* (x y z tl) and (vx vy vz type) of the four records, transposed */
        const __m256d a0 = _mm256_loadu_pd(p0), a1 = _mm256_loadu_pd(p1), a2 = _mm256_loadu_pd(p2), a3 = _mm256_loadu_pd(p3);
        const __m256d b0 = _mm256_loadu_pd(p0 + 4), b1 = _mm256_loadu_pd(p1 + 4), b2 = _mm256_loadu_pd(p2 + 4);
        const __m256d b3 = _mm256_loadu_pd(p3 + 4);
        const __m256d lo01 = _mm256_unpacklo_pd(a0, a1), hi01 = _mm256_unpackhi_pd(a0, a1);   /* x0 x1 z0 z1, y0 y1 t0 t1 */
        const __m256d lo23 = _mm256_unpacklo_pd(a2, a3), hi23 = _mm256_unpackhi_pd(a2, a3);
        const __m256d vlo01 = _mm256_unpacklo_pd(b0, b1), vhi01 = _mm256_unpackhi_pd(b0, b1);
        const __m256d vlo23 = _mm256_unpacklo_pd(b2, b3), vhi23 = _mm256_unpackhi_pd(b2, b3);
        const __m256d x[3] = {_mm256_permute2f128_pd(lo01, lo23, 0x20), _mm256_permute2f128_pd(hi01, hi23, 0x20),
                              _mm256_permute2f128_pd(lo01, lo23, 0x31)};
        const __m256d tl = _mm256_permute2f128_pd(hi01, hi23, 0x31);
        const __m256d v[3] = {_mm256_permute2f128_pd(vlo01, vlo23, 0x20), _mm256_permute2f128_pd(vhi01, vhi23, 0x20),
                              _mm256_permute2f128_pd(vlo01, vlo23, 0x31)};
        const __m256d dt = _mm256_sub_pd(vt, tl);
        __m256d dx[3], dv[3], amb = zero;
        for (int c = 0; c < 3; c++) {
            const __m256d d = _mm256_sub_pd(xiv[c], _mm256_fmadd_pd(v[c], dt, x[c]));
            const __m256d y = _mm256_mul_pd(d, inv[c]);
            const __m256d ay = _mm256_andnot_pd(sign, y);
            amb = _mm256_or_pd(amb, _mm256_cmp_pd(_mm256_andnot_pd(sign, _mm256_sub_pd(ay, half)), tiny, _CMP_LT_OQ));
            const __m256d img = _mm256_sub_pd(_mm256_and_pd(_mm256_cmp_pd(y, half, _CMP_GE_OQ), one),
                                              _mm256_and_pd(_mm256_cmp_pd(y, mhalf, _CMP_LE_OQ), one));
            dx[c] = _mm256_fnmadd_pd(len[c], img, d);
            dv[c] = _mm256_sub_pd(viv[c], v[c]);
        }
        const __m256d rsq = _mm256_fmadd_pd(dx[2], dx[2], _mm256_fmadd_pd(dx[1], dx[1], _mm256_mul_pd(dx[0], dx[0])));
        const __m256d b = _mm256_fmadd_pd(dx[2], dv[2], _mm256_fmadd_pd(dx[1], dv[1], _mm256_mul_pd(dx[0], dv[0])));
        const __m256d vv = _mm256_fmadd_pd(dv[2], dv[2], _mm256_fmadd_pd(dv[1], dv[1], _mm256_mul_pd(dv[0], dv[0])));
        const __m256d c = _mm256_sub_pd(rsq, r2);
        const __m256d bb = _mm256_mul_pd(b, b), vc = _mm256_mul_pd(vv, c);
        const __m256d miss = _mm256_cmp_pd(_mm256_sub_pd(bb, vc), _mm256_mul_pd(_mm256_mul_pd(rel, _mm256_add_pd(bb, vc)),
                                                                                  _mm256_set1_pd(-1.0)), _CMP_LT_OQ);
        const __m256d late = _mm256_cmp_pd(c, _mm256_mul_pd(limit, _mm256_mul_pd(mtwo, b)), _CMP_GT_OQ);
        const __m256d away = _mm256_cmp_pd(b, zero, _CMP_GE_OQ);
        const __m256d outside = _mm256_cmp_pd(rsq, r2hi, _CMP_GT_OQ);
        __m256d drop = _mm256_and_pd(outside, _mm256_or_pd(away, _mm256_or_pd(miss, late)));
        drop = _mm256_andnot_pd(amb, drop);
        int dmask = _mm256_movemask_pd(drop);
        const __m128i idx = _mm_loadu_si128((const __m128i *)(cand + k));
        dmask |= _mm_movemask_ps(_mm_castsi128_ps(_mm_cmpeq_epi32(idx, _mm_set1_epi32(i))));   /* j == i */
        n += store_kept4(kept + n, idx, ~dmask & 15);
    }
#endif
    for (; k < m; k++)
        if (!drop_one(pk, i, cand[k], t, xi, vi, length, inv_len, r2far, best)) kept[n++] = cand[k];
    return n;
}
