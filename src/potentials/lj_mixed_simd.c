/* The mixed-precision Lennard-Jones force pass over the half atom list, with AVX-512 (called from
 * terrace_lj's lj_compute, src/potentials/lj_force.inc; one type, style 'lj').
 *
 * Positions in fixed point: each force pass stages every position (owned and ghost) as three
 * 32-bit integers, q = nint((x - lo) / u), lo the smallest coordinate held in each dimension and u
 * the power of two at or above span / 2^30 (span: the largest extent of the atoms held in any
 * dimension), in a 16-byte record (qx, qy, qz, 0). A separation is the integer difference q_i - q_j
 * (exact), converted to single and multiplied by u (exact, a power of two): the double separation
 * to within u (2^-24, 6e-8 length units, on the argon job, whose atoms held span 32 to 64) and the single
 * rounding (6e-8 relative), however far the atoms lie from the origin.
 *
 * Wrapped images (the engine's, on one rank, when the box is more than twice the list's cutoff in
 * every dimension: neighbor_list_t%wrapped): only the owned atoms are staged, on the periodic grid
 * of the box (2^32 steps per box length, stage_periodic), and each ghost of the list is read as its
 * owner's record: the integer difference wraps to the nearest image. The ghosts are then neither
 * refreshed between builds (the prune reads the owners too) nor summed back (the records, and the pass's memory, are a third to a
 * quarter as many on the argon job). The pair terms are computed in a length unit in which the grid
 * step is a power of two (terrace_lj_mixed: lam), so that the separations stay exact products.
 *
 * Sixteen pairs per block (a row's last block of eight pairs or fewer loads and stores eight
 * records, pair_block with n = 8): the neighbours' records are loaded four to a 64-byte register (16-byte
 * broadcasts merged under a mask) and two unpacks give 16-lane rows of x, y and z, as GROMACS's
 * nbnxm kernels load their j-clusters; the pair terms in single precision (1/r^2 from vrcp14ps and
 * one Newton step, about 1 ulp). The neighbours' forces are summed in single-precision records
 * ff = (fx, fy, fz, 0), loaded and stored back as rows the same way (the neighbours of a row are
 * distinct; the padding lanes use a pad record after the atoms'); atom i's own sum is added to its
 * own record (added to f in double through the stack, the argon slice's Pair was 1/0.94 as long:
 * phase_ab.sh 9, doc/bench_data/isum_ab_eed0f12_xeon.txt). At the end the records are added to f in double (finish). The two sides of a pair are
 * rounded in different sums, so this rank's forces leave a small net force (about 1e-7 of a pair
 * force per pair); it is taken off the owned atoms equally (the cluster kernel, terrace_lj_cluster,
 * takes its own off every atom held), so that momentum is conserved to double round-off. With want_energy the
 * pair energies are summed per atom into atom_e[i] and the virial into *virial.
 *
 * The rows' byte offsets (16 (j - 1) per neighbour j, each row padded to whole blocks with the pad
 * record's) are formed once per list (terrace_row_offsets, neighbor/prune_simd.c; with wrapped images
 * by the list, terrace_prune_wrapped), not in every block of every pass.
 * Per pair on the argon geometry: scripts/bench/lj_pass_floor.sh (its `mixed` row).
 *
 * With AVX2 and FMA but no AVX-512 the row pass is lj_mixed_avx2.c's, eight pairs per block, and
 * staging and finishing are plain loops (below).
 *
 * Both entry points return 0 (nothing done: kernel_mixed's portable Fortran pass runs) where the
 * build has neither AVX-512 (F, VL, DQ) nor AVX2, each with FMA, or the atoms are too many for
 * 32-bit byte offsets. */
#include <math.h>
#include <stdint.h>
#include "../core/fixed_point_rows.h"
#if defined(TERRACE_FIXED_ROWS)
#define TERRACE_MIXED_SIMD 1

/* the inverse of rows_n: lane l < n of (vx, vy, vz) stored to the record at base + off[l] as (x, y, z, 0) */
static inline __attribute__((always_inline)) void store_n(const int n, char *base, const int32_t *off, __m512 vx,
                                                          __m512 vy, __m512 vz)
{
    const __m512 zero = _mm512_setzero_ps();
    const __m512d u0 = _mm512_castps_pd(_mm512_unpacklo_ps(vx, vy));     /* x0 y0 x1 y1 */
    const __m512d u1 = _mm512_castps_pd(_mm512_unpackhi_ps(vx, vy));     /* x2 y2 x3 y3 */
    const __m512d v0 = _mm512_castps_pd(_mm512_unpacklo_ps(vz, zero));   /* z0 0 z1 0 */
    const __m512d v1 = _mm512_castps_pd(_mm512_unpackhi_ps(vz, zero));   /* z2 0 z3 0 */
    const __m512 b[4] = {_mm512_castpd_ps(_mm512_unpacklo_pd(u0, v0)), _mm512_castpd_ps(_mm512_unpackhi_pd(u0, v0)),
                         _mm512_castpd_ps(_mm512_unpacklo_pd(u1, v1)), _mm512_castpd_ps(_mm512_unpackhi_pd(u1, v1))};
    for (int m = 0; m < 4; m++) {   /* b[m], 128-bit lane L: record 4 L + m */
        _mm_storeu_ps((float *)(base + off[m]), _mm512_castps512_ps128(b[m]));
        _mm_storeu_ps((float *)(base + off[m + 4]), _mm512_extractf32x4_ps(b[m], 1));
        if (n == 16) {
            _mm_storeu_ps((float *)(base + off[m + 8]), _mm512_extractf32x4_ps(b[m], 2));
            _mm_storeu_ps((float *)(base + off[m + 12]), _mm512_extractf32x4_ps(b[m], 3));
        }
    }
}

/* the coefficients and constants of the pass (rows_pass forms them from terrace_lj_mixed's k) */
struct pass_consts {
    __m512 c1, c2, c3, c4, cs, co, ux, uy, uz, uxl, uyl, uzl, two;
};

/* the separation along one dimension: the integer difference converted to single, times the grid
 * step u (split: u + ul, u's high and low parts, where the step is not a power of two) */
static inline __attribute__((always_inline)) __m512 separation(const int split, __m512i qi, __m512 qj, __m512 u,
                                                               __m512 ul)
{
    const __m512 c = _mm512_cvtepi32_ps(_mm512_sub_epi32(qi, _mm512_castps_si512(qj)));
    return split ? _mm512_fmadd_ps(c, ul, _mm512_mul_ps(c, u)) : _mm512_mul_ps(c, u);
}

/* One block of a row: the cnt (<= n) neighbours at byte offsets off of atom i (its fixed-point
 * position xi, yi, zi): their pair forces into the sums of i and, subtracted, into their records;
 * with want_energy the pair energies and virials into se and sw. n = 16, or 8 for a row's last
 * block of eight pairs or fewer (the upper lanes then hold no pair). */
static inline __attribute__((always_inline)) void pair_block(const int n, const int split, int cnt, const char *qb,
                                                             char *fb,
                                                             const int32_t *off, __m512i xi, __m512i yi, __m512i zi,
                                                             const struct pass_consts *k_, int want_energy,
                                                             __m512 *sx, __m512 *sy, __m512 *sz, __m512 *se, __m512 *sw)
{
    const __mmask16 live = (__mmask16)((1u << cnt) - 1u);
    __m512 qx, qy, qz, gx, gy, gz;
    rows_n(n, qb, off, &qx, &qy, &qz);
    rows_n(n, fb, off, &gx, &gy, &gz);
    const __m512 dx = separation(split, xi, qx, k_->ux, k_->uxl);
    const __m512 dy = separation(split, yi, qy, k_->uy, k_->uyl);
    const __m512 dz = separation(split, zi, qz, k_->uz, k_->uzl);
    const __m512 rsq = _mm512_fmadd_ps(dz, dz, _mm512_fmadd_ps(dx, dx, _mm512_mul_ps(dy, dy)));
    const __mmask16 in = _mm512_mask_cmp_ps_mask(live, rsq, k_->cs, _CMP_LT_OQ);
    __m512 r2inv = _mm512_maskz_rcp14_ps(in, rsq);
    r2inv = _mm512_mul_ps(r2inv, _mm512_fnmadd_ps(rsq, r2inv, k_->two));   /* Newton: r (2 - rsq r) */
    const __m512 r6inv = _mm512_mul_ps(_mm512_mul_ps(r2inv, r2inv), r2inv);
    const __m512 fpair = _mm512_mul_ps(_mm512_mul_ps(r6inv, _mm512_fmsub_ps(k_->c1, r6inv, k_->c2)), r2inv);
    if (want_energy) {
        const __m512 e = _mm512_mul_ps(r6inv, _mm512_fmsub_ps(k_->c3, r6inv, k_->c4));
        *se = _mm512_add_ps(*se, _mm512_mask_sub_ps(e, in, e, k_->co));   /* the offset inside the cutoff */
        *sw = _mm512_fmadd_ps(rsq, fpair, *sw);
    }
    const __m512 fx = _mm512_mul_ps(dx, fpair), fy = _mm512_mul_ps(dy, fpair), fz = _mm512_mul_ps(dz, fpair);
    *sx = _mm512_add_ps(*sx, fx); *sy = _mm512_add_ps(*sy, fy); *sz = _mm512_add_ps(*sz, fz);
    store_n(n, fb, off, _mm512_sub_ps(gx, fx), _mm512_sub_ps(gy, fy), _mm512_sub_ps(gz, fz));
}

/* the upper and lower halves of v added */
static inline __m256 halves_sum(__m512 v)
{
    return _mm256_add_ps(_mm512_castps512_ps256(v), _mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(v), 1)));
}

/* the sums of the lanes of x, y, z and e, as (x, y, z, e): the halves added, then three horizontal
 * adds (one transposing reduction for the four, in single precision) */
static inline __m128 sums4(__m512 x, __m512 y, __m512 z, __m512 e)
{
    const __m256 t = _mm256_hadd_ps(_mm256_hadd_ps(halves_sum(x), halves_sum(y)),
                                    _mm256_hadd_ps(halves_sum(z), halves_sum(e)));
    return _mm_add_ps(_mm256_castps256_ps128(t), _mm256_extractf128_ps(t, 1));
}

/* the sum of a 16-single vector's lanes, in double */
static inline double sum_double(__m512 v)
{
    const __m512d lo = _mm512_cvtps_pd(_mm512_castps512_ps256(v));
    const __m512d hi = _mm512_cvtps_pd(_mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(v), 1)));
    return _mm512_reduce_add_pd(_mm512_add_pd(lo, hi));
}
#endif

#if defined(TERRACE_MIXED_SIMD) || defined(TERRACE_FIXED_ROWS8)
/* stage's bounds: lo and hi (the components' smallest and largest so far) over the flat x[t0..nflat-1]
 * (component t mod 3), and 1 / u, u the power of two at or above 2^-30 of the largest extent */
static double stage_bounds(long t0, long nflat, const double *x, double *lo, double *hi)
{
    double span = 0;
    for (long t = t0; t < nflat; t++) {
        lo[t % 3] = x[t] < lo[t % 3] ? x[t] : lo[t % 3];
        hi[t % 3] = x[t] > hi[t % 3] ? x[t] : hi[t % 3];
    }
    for (int c = 0; c < 3; c++) span = hi[c] - lo[c] > span ? hi[c] - lo[c] : span;
    int e;
    (void)frexp(span, &e);                   /* span <= 2^e */
    return 1.0 / ldexp(1.0, e - 30);
}

/* stage's records of atoms i0..nall-1, one at a time, and the pad record after them */
static void stage_rest(long i0, int nall, const double *x, const double *lo, double inv, int32_t *q, float *ff)
{
    for (long i = i0; i < nall; i++) {
        for (int c = 0; c < 3; c++) q[4 * i + c] = (int32_t)((x[3 * i + c] - lo[c]) * inv + 0.5);
        q[4 * i + 3] = 0;
        for (int c = 0; c < 4; c++) ff[4 * i + c] = 0;
    }
    for (int c = 0; c < 4; c++) q[4 * (long)nall + c] = 0;   /* the pad record (its lanes are masked) */
}
#endif

#if defined(TERRACE_MIXED_SIMD)
/* The records of the nall atoms: q (fixed-point positions) and ff = 0, and q's pad record after
 * them; returns the unit u. Vectorised: the smallest and largest coordinates over the flat x in
 * blocks of 24 doubles (eight atoms; lane l of the block's register k holds component
 * (8 k + l) mod 3), then two atoms per step, their six doubles loaded and permuted into
 * (x, y, z, 0, x, y, z, 0). */
static float stage(int nall, const double *x, int32_t *q, float *ff)
{
    double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    if (nall > 0)
        for (int c = 0; c < 3; c++) lo[c] = hi[c] = x[c];
    const long nflat = 3 * (long)nall;
    long t = 0;
    if (nflat >= 24) {
        __m512d mn[3], mx[3];
        for (int k = 0; k < 3; k++) mn[k] = mx[k] = _mm512_loadu_pd(x + 8 * k);
        for (; t + 24 <= nflat; t += 24)
            for (int k = 0; k < 3; k++) {
                const __m512d v = _mm512_loadu_pd(x + t + 8 * k);
                mn[k] = _mm512_min_pd(mn[k], v);
                mx[k] = _mm512_max_pd(mx[k], v);
            }
        double a[24], b[24];
        for (int k = 0; k < 3; k++) {
            _mm512_storeu_pd(a + 8 * k, mn[k]);
            _mm512_storeu_pd(b + 8 * k, mx[k]);
        }
        for (int l = 0; l < 24; l++) {
            lo[l % 3] = a[l] < lo[l % 3] ? a[l] : lo[l % 3];
            hi[l % 3] = b[l] > hi[l % 3] ? b[l] : hi[l % 3];
        }
    }
    const double inv = stage_bounds(t, nflat, x, lo, hi);
    /* q = (x - lo) / u + 1/2, truncated: in [0, 2^30], rounded to nearest */
    const __m512d vlo = _mm512_setr_pd(lo[0], lo[1], lo[2], 0, lo[0], lo[1], lo[2], 0);
    const __m512d vinv = _mm512_set1_pd(inv), half = _mm512_setr_pd(0.5, 0.5, 0.5, 0, 0.5, 0.5, 0.5, 0);
    const __m256 zero = _mm256_setzero_ps();
    const __m512i spread = _mm512_setr_epi64(0, 1, 2, 0, 3, 4, 5, 0);
    long i = 0;
    for (; i + 2 <= nall; i += 2) {
        const __m512d v = _mm512_maskz_permutexvar_pd(0x77, spread, _mm512_maskz_loadu_pd(0x3F, x + 3 * i));
        _mm256_storeu_si256((__m256i *)(q + 4 * i),
                            _mm512_cvttpd_epi32(_mm512_fmadd_pd(_mm512_sub_pd(v, vlo), vinv, half)));
        _mm256_storeu_ps(ff + 4 * i, zero);
    }
    stage_rest(i, nall, x, lo, inv, q, ff);
    return (float)(1.0 / inv);
}

/* f += scale ff for the nall records' atoms, and f -= net / nlocal for the owned ones, where net is
 * the sum of scale ff (the owned atoms' own sums are in their records): the net force of this rank's pairs,
 * taken off the owned atoms (after the reverse sum of the ghosts' forces all forces then sum to
 * zero, to double round-off, across the ranks). Eight atoms per step: their records (x, y, z, 0)
 * converted to double and permuted into three registers of 24 consecutive components, f's own
 * layout (full loads and stores, no masks: a masked store of part of a register blocked the next
 * load's forwarding, and the pass ran slower than the scalar loop) */
static void finish(int nlocal, int nall, const float *ff, double *f, double scale)
{
    const __m512d vscale = _mm512_set1_pd(scale);
    const __m512i p0 = _mm512_setr_epi64(0, 1, 2, 4, 5, 6, 8, 9), p1 = _mm512_setr_epi64(2, 4, 5, 6, 8, 9, 10, 12);
    const __m512i p2 = _mm512_setr_epi64(5, 6, 8, 9, 10, 12, 13, 14);
    __m512d s = _mm512_setzero_pd();
    long j = 0;
    for (; j + 8 <= nall; j += 8) {
        const __m512 r0 = _mm512_loadu_ps(ff + 4 * j), r1 = _mm512_loadu_ps(ff + 4 * j + 16);
        const __m512d a = _mm512_mul_pd(_mm512_cvtps_pd(_mm512_castps512_ps256(r0)), vscale);   /* atoms j, j + 1 */
        const __m512d b = _mm512_mul_pd(
            _mm512_cvtps_pd(_mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(r0), 1))), vscale);
        const __m512d c = _mm512_mul_pd(_mm512_cvtps_pd(_mm512_castps512_ps256(r1)), vscale);
        const __m512d d = _mm512_mul_pd(
            _mm512_cvtps_pd(_mm256_castpd_ps(_mm512_extractf64x4_pd(_mm512_castps_pd(r1), 1))), vscale);
        s = _mm512_add_pd(s, _mm512_add_pd(_mm512_add_pd(a, b), _mm512_add_pd(c, d)));
        double *g = f + 3 * j;
        _mm512_storeu_pd(g, _mm512_add_pd(_mm512_loadu_pd(g), _mm512_permutex2var_pd(a, p0, b)));
        _mm512_storeu_pd(g + 8, _mm512_add_pd(_mm512_loadu_pd(g + 8), _mm512_permutex2var_pd(b, p1, c)));
        _mm512_storeu_pd(g + 16, _mm512_add_pd(_mm512_loadu_pd(g + 16), _mm512_permutex2var_pd(c, p2, d)));
    }
    double net[8];
    _mm512_storeu_pd(net, s);
    for (int k = 0; k < 3; k++) net[k] += net[k + 4];
    for (; j < nall; j++)
        for (int k = 0; k < 3; k++) {
            f[3 * j + k] += scale * ff[4 * j + k];
            net[k] += scale * ff[4 * j + k];
        }
    if (nlocal == 0) return;
    for (int k = 0; k < 3; k++) net[k] /= nlocal;
    for (j = 0; j < nlocal; j++)
        for (int k = 0; k < 3; k++) f[3 * j + k] -= net[k];
}

#endif

#if defined(TERRACE_FIXED_ROWS8)
/* AVX2 (lj_mixed_avx2.c): the row pass of eight lanes, k as terrace_lj_mixed forms it */
void terrace_lj_mixed_rows8(int split, int nlocal, const int32_t *q, float *ff, const int *first, const int *ofirst,
                            const int32_t *offs, const float *k, int want_energy, double escale, double *atom_e,
                            double *w);

/* stage above, one atom at a time */
static float stage(int nall, const double *x, int32_t *q, float *ff)
{
    double lo[3] = {0, 0, 0}, hi[3] = {0, 0, 0};
    if (nall > 0)
        for (int c = 0; c < 3; c++) lo[c] = hi[c] = x[c];
    const double inv = stage_bounds(0, 3 * (long)nall, x, lo, hi);
    stage_rest(0, nall, x, lo, inv, q, ff);
    return (float)(1.0 / inv);
}

/* finish above, one atom at a time */
static void finish(int nlocal, int nall, const float *ff, double *f, double scale)
{
    double net[3] = {0, 0, 0};
    for (long j = 0; j < nall; j++)
        for (int k = 0; k < 3; k++) {
            const double g = scale * (double)ff[4 * j + k];
            f[3 * j + k] += g;
            net[k] += g;
        }
    if (nlocal == 0) return;
    for (int k = 0; k < 3; k++) net[k] /= nlocal;
    for (long j = 0; j < nlocal; j++)
        for (int k = 0; k < 3; k++) f[3 * j + k] -= net[k];
}
#endif

#if defined(TERRACE_MIXED_SIMD)
/* the row loop of the pass (split: the grid steps in two parts, separation; k: terrace_lj_mixed's) */
static inline __attribute__((always_inline)) void rows_pass(const int split, int nlocal, const int32_t *q, char *fb,
                                                            const int *first, const int *ofirst, const int32_t *offs,
                                                            const float *k, int want_energy, double escale,
                                                            double *atom_e, double *w)
{
    const struct pass_consts kv = {
        _mm512_set1_ps(k[0]), _mm512_set1_ps(k[1]), _mm512_set1_ps(k[2]), _mm512_set1_ps(k[3]),
        _mm512_set1_ps(k[4]), _mm512_set1_ps(k[5]), _mm512_set1_ps(k[6]), _mm512_set1_ps(k[7]),
        _mm512_set1_ps(k[8]), _mm512_set1_ps(k[9]), _mm512_set1_ps(k[10]), _mm512_set1_ps(k[11]), _mm512_set1_ps(2.0f)};
    const struct pass_consts *k_ = &kv;
    const __m512 zero = _mm512_setzero_ps();
    const char *qb = (const char *)q;
    for (int i = 0; i < nlocal; i++) {
        const int nn = first[i + 1] - first[i];
        const int32_t *a = q + 4 * (long)i;
        const __m512i xi = _mm512_set1_epi32(a[0]), yi = _mm512_set1_epi32(a[1]), zi = _mm512_set1_epi32(a[2]);
        __m512 sx = zero, sy = zero, sz = zero, se = zero, sw = zero;
        for (int k = 0; k < nn; k += 16) {
            const int cnt = nn - k < 16 ? nn - k : 16;
            const int32_t *off = offs + ofirst[i] + k;
            if (cnt <= 8)   /* a row's last block of eight pairs or fewer: half the loads and stores */
                pair_block(8, split, cnt, qb, fb, off, xi, yi, zi, k_, want_energy, &sx, &sy, &sz, &se, &sw);
            else
                pair_block(16, split, cnt, qb, fb, off, xi, yi, zi, k_, want_energy, &sx, &sy, &sz, &se, &sw);
        }
        /* (fx, fy, fz, e) of atom i: the force added to its own record (finish adds it to f) */
        const __m128 t = sums4(sx, sy, sz, se);
        float *fr = (float *)(fb + 16 * (long)i);
        _mm_storeu_ps(fr, _mm_add_ps(_mm_loadu_ps(fr), _mm_blend_ps(t, _mm_setzero_ps(), 8)));
        if (want_energy) {
            atom_e[i] = escale * (double)_mm_cvtss_f32(_mm_permute_ps(t, 0xFF));
            *w += escale * sum_double(sw);
        }
    }
}
#endif

/* nlocal owned and nall held atoms; x, f (3, nall) in double; q (4, nrec + 1) and ff (4, nrec + 1)
 * the work records (the last, the padding lanes' pad record), nrec = nall, or nlocal with wrapped
 * images (wrapped != 0: the list's ghosts read as their owners on the periodic grid of the box wrap
 * = lo(3), length(3), stage_periodic; the ghosts' forces are then left untouched, no reverse sum);
 * first the half list's row starts (1-based) and ofirst, offs its offsets (terrace_row_offsets,
 * formed with the same wrapped); c = (lj1, lj2, lj3, lj4, cutsq, offset); with want_energy
 * atom_e[0..nlocal-1] (set) and *virial (added to).
 *
 * Units: the pair terms are computed with lengths in a unit 1/lam, lam = 2^m / L_x with 2^m <= L_x
 * < 2^(m + 1) on the periodic grid (lam = 1 otherwise), so that the grid step L_x / 2^32 is a power
 * of two in that unit and the separations are exact products, as on the power-of-two grid of the
 * copies (and along y and z where their edges are L_x times a power of two; otherwise the step is
 * split in two singles, separation). The coefficients are scaled in double and rounded to single
 * once (lj1 lam^6, lj2, lj3 lam^6, lj4, cutsq lam^2, offset lam^-6), and the sums scaled back in
 * double: forces by lam^7, energies and virials by lam^6. */
int terrace_lj_mixed(int nlocal, int nall, const double *x, double *f, int32_t *q, float *ff, const int *first,
                     const int *ofirst, const int32_t *offs, const double *c, int want_energy, int wrapped,
                     const double *wrap, double *atom_e, double *virial)
{
#if defined(TERRACE_MIXED_SIMD) || defined(TERRACE_FIXED_ROWS8)
    if (nall >= terrace_fixed_max_atoms) return 0;
    const int nrec = wrapped ? nlocal : nall;
    double lam = 1, u[3];
    int split = 0;
    if (wrapped) {
        stage_periodic(nlocal, x, wrap, q, ff);
        int m;
        (void)frexp(wrap[3], &m);            /* 2^(m - 1) <= L_x < 2^m */
        lam = ldexp(1.0, m - 1) / wrap[3];
        for (int d = 0; d < 3; d++) {
            u[d] = wrap[3 + d] * lam * ldexp(1.0, -32);
            int e;
            split = split || frexp(u[d], &e) != 0.5;   /* not a power of two */
        }
    } else {
        u[0] = u[1] = u[2] = stage(nall, x, q, ff);
    }
    const double l6 = lam * lam * lam * lam * lam * lam;
    /* the pass's constants in single: lj1..lj4, cutsq and offset in the unit 1/lam, the grid steps'
     * high and low parts */
    float k[12] = {(float)(c[0] * l6), (float)c[1], (float)(c[2] * l6), (float)c[3], (float)(c[4] * lam * lam),
                   (float)(c[5] / l6)};
    for (int d = 0; d < 3; d++) {
        k[6 + d] = (float)u[d];
        k[9 + d] = (float)(u[d] - (double)k[6 + d]);
    }
    double w = 0;
#if defined(TERRACE_MIXED_SIMD)
    if (split)
        rows_pass(1, nlocal, q, (char *)ff, first, ofirst, offs, k, want_energy, l6, atom_e, &w);
    else
        rows_pass(0, nlocal, q, (char *)ff, first, ofirst, offs, k, want_energy, l6, atom_e, &w);
#else
    terrace_lj_mixed_rows8(split, nlocal, q, ff, first, ofirst, offs, k, want_energy, l6, atom_e, &w);
#endif
    finish(nlocal, nrec, ff, f, l6 * lam);
    if (want_energy) *virial += w;
    return 1;
#else
    (void)nlocal; (void)nall; (void)x; (void)f; (void)q; (void)ff; (void)first; (void)ofirst; (void)offs; (void)c;
    (void)want_energy; (void)wrapped; (void)wrap; (void)atom_e; (void)virial;
    return 0;
#endif
}

/* 1 where this build has the AVX-512 pass, 2 the AVX2 one (the scene planner's choice of list for the mixed kernel), else 0 */
int terrace_lj_mixed_simd(void)
{
#if defined(TERRACE_MIXED_SIMD)
    return 1;
#elif defined(TERRACE_FIXED_ROWS8)
    return 2;
#else
    return 0;
#endif
}
