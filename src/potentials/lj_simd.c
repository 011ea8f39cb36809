/* Lennard-Jones kernels with SIMD intrinsics (called from terrace_lj, src/potentials/lj.f90).
 *
 * The ray pass's gather (terrace_lj, ray_rows): for atom i and its neighbours
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
 * the same fused multiply-adds as the scalar loop, so the results are the same bits:
 *   rr = fma(dz, dz, fma(dx, dx, dy*dy)), dw = fma(dz, wz, fma(dx, wx, dy*wy)),
 *   ww = fma(wz, wz, fma(wx, wx, wy*wy)).
 * With AVX-512 eight at a time first (four records per 64-byte register, the same unpacks; the ray
 * pass's Search phase another 8-9 % cheaper than with four, phase_ab.sh on both liquids). Without
 * AVX2 and FMA (a portable build), or for the last nn mod 4 pairs, the scalar loop.
 *
 * Below it, the fused force pass: one type (terrace_lj_one_type) and 2 to 8 types (terrace_lj_types,
 * each lane's coefficients by a register permute from its type). */
#include <math.h>
#include "../core/simd_rows.h"

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


/* The Lennard-Jones force pass over the half list, fused, with AVX-512: for each owned
 * atom i (0-based here; first and neigh 1-based, as the Fortran list has them) eight neighbours at a
 * time (a row's last four or fewer four at a time: tail4): their positions loaded as rows (core/simd_rows.h; the padding lanes of a row's last block
 * read a row 1e100 away), the pair terms computed in the vector as terrace_lj's lj_terms does (the
 * cutoff a mask, 1/infinity beyond it), the force on i summed in the vector, and the neighbours'
 * forces loaded, reduced and stored back as rows (the neighbours of a row are distinct, so the lanes
 * never collide; the padding lanes' forces go to a spill row). Rows instead of gathers and scatters
 * (vgatherdpd, vscatterdpd): the argon job's force pass a quarter cheaper (doc/performance.md). The
 * Fortran kernel stores the separations and the pair forces in rows and reads them again (a scalar
 * gather, the vectorised pair loop, a scalar scatter); here nothing
 * leaves the registers but the forces. With want_energy the pair energies are summed per atom into
 * atom_e[i] and the virial into *virial. The entry points (terrace_lj_one_type, terrace_lj_types,
 * at the end) return 0 (nothing done: the caller's Fortran kernel runs) where this build has no
 * AVX-512 (AVX512F, AVX512VL) and FMA; with AVX2 and FMA only, both run lj_pass4, the same pass
 * four pairs at a time (the argon job's Pair 0.78 of the Fortran kernel's on an AMD EPYC,
 * doc/performance.md).
 *
 * lj_pass: the pass for one type (multi = 0: the coefficients lj1[0] ... broadcast) or for up to
 * eight types (multi = 1: the coefficient tables of struct terrace_lj_tables, column-major with a
 * leading dimension of 8; per atom i its type's column in a register, per block the neighbours' types
 * from ntype (the list's row of neighbour types) and each lane's coefficients by a register permute,
 * vpermpd, not a gather). Inlined with a constant multi into the two entry points, so the one-type
 * pass has no type work. */

/* The several-types pass's coefficient tables, as terrace_lj's lj_simd_tables_t (bind(C)) holds
 * them: entry (a, b) of each table at [(b - 1) * 8 + a - 1] for types a, b in 1..ntypes. */
struct terrace_lj_tables {
    double lj1[64], lj2[64], lj3[64], lj4[64], cutsq[64], offset[64];
    int ntypes;
};
#if defined(__AVX2__) && defined(__FMA__)
/* Four pairs' terms from their separations (tail4's and lj_pass4's): the pair force fp and its
 * components, and with want_energy the pair energies (the offset taken inside the cutoff) and
 * r^2 fp added to *se and *wsum. Beyond the cutoff 1/r^2 is 1/infinity = 0. */
static inline __attribute__((always_inline)) void pair_terms4(__m256d dx, __m256d dy, __m256d dz, __m256d c1,
                                                              __m256d c2, __m256d c3, __m256d c4, __m256d cs,
                                                              __m256d co, int want_energy, __m256d *fx, __m256d *fy,
                                                              __m256d *fz, __m256d *se, __m256d *wsum)
{
    const __m256d one = _mm256_set1_pd(1.0), inf = _mm256_set1_pd(INFINITY);
    const __m256d rsq = _mm256_fmadd_pd(dz, dz, _mm256_fmadd_pd(dx, dx, _mm256_mul_pd(dy, dy)));
    const __m256d in = _mm256_cmp_pd(rsq, cs, _CMP_LT_OQ);
    const __m256d r2inv = _mm256_div_pd(one, _mm256_blendv_pd(inf, rsq, in));
    const __m256d r6inv = _mm256_mul_pd(_mm256_mul_pd(r2inv, r2inv), r2inv);
    const __m256d fpair = _mm256_mul_pd(_mm256_mul_pd(r6inv, _mm256_fmsub_pd(c1, r6inv, c2)), r2inv);
    if (want_energy) {
        const __m256d e = _mm256_mul_pd(r6inv, _mm256_fmsub_pd(c3, r6inv, c4));
        *se = _mm256_add_pd(*se, _mm256_sub_pd(e, _mm256_and_pd(in, co)));
        *wsum = _mm256_fmadd_pd(rsq, fpair, *wsum);
    }
    *fx = _mm256_mul_pd(dx, fpair); *fy = _mm256_mul_pd(dy, fpair); *fz = _mm256_mul_pd(dz, fpair);
}

/* The position and force rows of neighbours nb[0..cnt-1] (1-based; cnt <= 4), the padding lanes'
 * at far_row and spill. */
static inline __attribute__((always_inline)) void rows4(const double *x, double *f, const int *nb, int cnt,
                                                        const double *far_row, double *spill, const double **q,
                                                        double **qf)
{
    for (int l = 0; l < 4; l++) {
        const long o = l < cnt ? 3 * (long)nb[l] - 3 : 0;   /* (one offset for both rows; none read past cnt) */
        q[l] = l < cnt ? x + o : far_row;
        qf[l] = l < cnt ? f + o : spill;
    }
}
#endif

#if defined(__AVX512F__) && defined(__AVX512VL__) && defined(__FMA__)
/* lj_pass's last block of a row when it holds four pairs or fewer (cnt <= 4): the same operations on
 * the lower four lanes, in 256-bit registers (half the arithmetic and rows of an eight-lane block),
 * and the sums' lower halves updated; their upper lanes, to which the eight-lane block would add
 * -0 or 0 from its padding lanes, are left as they are: the same forces, energy and virial as the
 * eight-lane block (adding a zero changes a sum only where it is an exact zero, in its sign). */
static inline __attribute__((always_inline)) void tail4(const double *x, double *f, const int *nb, int cnt,
                                                        const double *far_row, double *spill, __m512d xi, __m512d yi,
                                                        __m512d zi, __m512d c1, __m512d c2, __m512d c3, __m512d c4,
                                                        __m512d cs, __m512d co, int want_energy, __m512d *sx,
                                                        __m512d *sy, __m512d *sz, __m512d *se, __m512d *wsum)
{
    const double *q[4];
    double *qf[4];
    rows4(x, f, nb, cnt, far_row, spill, q, qf);
    __m256d dx, dy, dz;
    rows_xyz4(q, &dx, &dy, &dz);
    dx = _mm256_sub_pd(_mm512_castpd512_pd256(xi), dx);
    dy = _mm256_sub_pd(_mm512_castpd512_pd256(yi), dy);
    dz = _mm256_sub_pd(_mm512_castpd512_pd256(zi), dz);
    __m256d fx, fy, fz, e4 = _mm512_castpd512_pd256(*se), w4 = _mm512_castpd512_pd256(*wsum);
    pair_terms4(dx, dy, dz, _mm512_castpd512_pd256(c1), _mm512_castpd512_pd256(c2), _mm512_castpd512_pd256(c3),
                _mm512_castpd512_pd256(c4), _mm512_castpd512_pd256(cs), _mm512_castpd512_pd256(co), want_energy, &fx,
                &fy, &fz, &e4, &w4);
    if (want_energy) {
        *se = _mm512_insertf64x4(*se, e4, 0);
        *wsum = _mm512_insertf64x4(*wsum, w4, 0);
    }
    *sx = _mm512_insertf64x4(*sx, _mm256_add_pd(_mm512_castpd512_pd256(*sx), fx), 0);
    *sy = _mm512_insertf64x4(*sy, _mm256_add_pd(_mm512_castpd512_pd256(*sy), fy), 0);
    *sz = _mm512_insertf64x4(*sz, _mm256_add_pd(_mm512_castpd512_pd256(*sz), fz), 0);
    __m256d gx, gy, gz;
    rows_xyz4((const double *const *)qf, &gx, &gy, &gz);
    store_rows4(qf, _mm256_sub_pd(gx, fx), _mm256_sub_pd(gy, fy), _mm256_sub_pd(gz, fz));
}

static inline __attribute__((always_inline)) void lj_pass(const int multi, int nlocal, const double *x, double *f,
                                                          const int *first, const int *neigh, const int *type,
                                                          const int *ntype, int ntypes, const double *lj1,
                                                          const double *lj2, const double *lj3, const double *lj4,
                                                          const double *cutsq, const double *offset, int want_energy,
                                                          double *atom_e, double *virial)
{
    __m512d c1 = _mm512_set1_pd(lj1[0]), c2 = _mm512_set1_pd(lj2[0]), c3 = _mm512_set1_pd(lj3[0]);
    __m512d c4 = _mm512_set1_pd(lj4[0]), cs = _mm512_set1_pd(cutsq[0]), co = _mm512_set1_pd(offset[0]);
    const __m512d one = _mm512_set1_pd(1.0), inf = _mm512_set1_pd(INFINITY), zero = _mm512_setzero_pd();
    static const double far_row[3] = {1.0e100, 1.0e100, 1.0e100};  /* the padding lanes' position */
    double spill[3] = {0, 0, 0};                                     /* and their forces (discarded) */
    const __mmask8 tmask = (__mmask8)((1u << ntypes) - 1u);
    __m512d t1 = zero, t2 = zero, t3 = zero, t4 = zero, ts = zero, to = zero;
    __m512d wsum = zero;
    for (int i = 0; i < nlocal; i++) {
        const int k0 = first[i] - 1, nn = first[i + 1] - first[i];
        const double *a = x + 3 * (long)i;
        const __m512d xi = _mm512_set1_pd(a[0]), yi = _mm512_set1_pd(a[1]), zi = _mm512_set1_pd(a[2]);
        if (multi) {      /* column type(i) of each table */
            const long col = (long)(type[i] - 1) * 8;
            t1 = _mm512_maskz_loadu_pd(tmask, lj1 + col); t2 = _mm512_maskz_loadu_pd(tmask, lj2 + col);
            ts = _mm512_maskz_loadu_pd(tmask, cutsq + col);
            if (want_energy) {
                t3 = _mm512_maskz_loadu_pd(tmask, lj3 + col); t4 = _mm512_maskz_loadu_pd(tmask, lj4 + col);
                to = _mm512_maskz_loadu_pd(tmask, offset + col);
            }
        }
        __m512d sx = zero, sy = zero, sz = zero, se = zero;
        for (int k = 0; k < nn; k += 8) {
            const int cnt = nn - k < 8 ? nn - k : 8;
            const __mmask8 live = (__mmask8)((1u << cnt) - 1u);
            if (multi) {  /* each lane's coefficients (padding lanes: any, they lie 1e100 away) */
                const __m512i tj = _mm512_cvtepi32_epi64(
                    _mm256_sub_epi32(_mm256_maskz_loadu_epi32(live, ntype + k0 + k), _mm256_set1_epi32(1)));
                c1 = _mm512_permutexvar_pd(tj, t1); c2 = _mm512_permutexvar_pd(tj, t2);
                cs = _mm512_permutexvar_pd(tj, ts);
                if (want_energy) {
                    c3 = _mm512_permutexvar_pd(tj, t3); c4 = _mm512_permutexvar_pd(tj, t4);
                    co = _mm512_permutexvar_pd(tj, to);
                }
            }
            if (cnt <= 4) {   /* a row's last block of four pairs or fewer: four lanes, half the work */
                tail4(x, f, neigh + k0 + k, cnt, far_row, spill, xi, yi, zi, c1, c2, c3, c4, cs, co, want_energy,
                      &sx, &sy, &sz, &se, &wsum);
                continue;
            }
            double *qf[8];
            __m512d dx, dy, dz;
            separations(x, neigh + k0 + k, cnt, far_row, xi, yi, zi, &dx, &dy, &dz);
            neighbour_rows(f, neigh + k0 + k, cnt, spill, (const double **)qf);
            __m512d rsq = _mm512_fmadd_pd(dz, dz, _mm512_fmadd_pd(dx, dx, _mm512_mul_pd(dy, dy)));
            __mmask8 in = _mm512_cmp_pd_mask(rsq, cs, _CMP_LT_OQ);
            __m512d r2inv = _mm512_div_pd(one, _mm512_mask_blend_pd(in, inf, rsq));
            __m512d r6inv = _mm512_mul_pd(_mm512_mul_pd(r2inv, r2inv), r2inv);
            __m512d fpair = _mm512_mul_pd(_mm512_mul_pd(r6inv, _mm512_fmsub_pd(c1, r6inv, c2)), r2inv);
            if (want_energy) {
                __m512d e = _mm512_mul_pd(r6inv, _mm512_fmsub_pd(c3, r6inv, c4));
                se = _mm512_add_pd(se, _mm512_mask_sub_pd(e, in, e, co));   /* the offset inside the cutoff */
                wsum = _mm512_fmadd_pd(rsq, fpair, wsum);
            }
            __m512d fx = _mm512_mul_pd(dx, fpair), fy = _mm512_mul_pd(dy, fpair), fz = _mm512_mul_pd(dz, fpair);
            sx = _mm512_add_pd(sx, fx); sy = _mm512_add_pd(sy, fy); sz = _mm512_add_pd(sz, fz);
            /* the neighbours' forces: loaded, reduced and stored back as rows, eight at a time (the
             * neighbours of one row are distinct; the padding lanes' rows are the spill row) */
            __m512d gx, gy, gz;
            rows_xyz((const double *const *)qf, &gx, &gy, &gz);
            store_rows(qf, _mm512_sub_pd(gx, fx), _mm512_sub_pd(gy, fy), _mm512_sub_pd(gz, fz));
        }
        double *fi = f + 3 * (long)i;
        fi[0] += _mm512_reduce_add_pd(sx); fi[1] += _mm512_reduce_add_pd(sy); fi[2] += _mm512_reduce_add_pd(sz);
        if (want_energy) atom_e[i] = _mm512_reduce_add_pd(se);
    }
    if (want_energy) *virial += _mm512_reduce_add_pd(wsum);
}
#endif

#if defined(__AVX2__) && defined(__FMA__) && !(defined(__AVX512F__) && defined(__AVX512VL__))
/* The lanes' coefficients from a table column of up to eight doubles, lo (types 1-4) and hi (5-8):
 * idx the 32-bit halves' indices of each lane's type within its four (2 t, 2 t + 1, t = type - 1
 * mod 4), upper the lanes of types 5-8 (all ones; only where half) */
static inline __attribute__((always_inline)) __m256d column4(const int half, __m256i idx, __m256i upper, __m256d lo,
                                                             __m256d hi)
{
    const __m256d a = _mm256_castps_pd(_mm256_permutevar8x32_ps(_mm256_castpd_ps(lo), idx));
    if (!half) return a;
    return _mm256_blendv_pd(a, _mm256_castps_pd(_mm256_permutevar8x32_ps(_mm256_castpd_ps(hi), idx)),
                            _mm256_castsi256_pd(upper));
}

/* The pass with AVX2 and FMA but no AVX-512: lj_pass's operations four pairs at a time in 256-bit
 * registers (pair_terms4, as tail4). multi = 1: 2 to 8 types (lj_pass's tables; per atom i its
 * type's column in registers, per block each lane's coefficients by a permute of 32-bit halves,
 * vpermps, and with more than four types a blend of two); multi = 0: one type, lj1..offset[0]. */
static inline __attribute__((always_inline)) void lj_pass4(const int multi, int nlocal, const double *x, double *f,
                                                           const int *first, const int *neigh, const int *type,
                                                           const int *ntype, int ntypes, const double *lj1,
                                                           const double *lj2, const double *lj3, const double *lj4,
                                                           const double *cutsq, const double *offset,
                                                           int want_energy, double *atom_e, double *virial)
{
    __m256d c1 = _mm256_set1_pd(lj1[0]), c2 = _mm256_set1_pd(lj2[0]), c3 = _mm256_set1_pd(lj3[0]);
    __m256d c4 = _mm256_set1_pd(lj4[0]), cs = _mm256_set1_pd(cutsq[0]), co = _mm256_set1_pd(offset[0]);
    const __m256d zero = _mm256_setzero_pd();
    static const double far_row[3] = {1.0e100, 1.0e100, 1.0e100};  /* the padding lanes' position */
    double spill[3] = {0, 0, 0};                                     /* and their forces (discarded) */
    const int half = ntypes > 4;
    __m256d t1[2] = {zero, zero}, t2[2] = {zero, zero}, t3[2] = {zero, zero}, t4[2] = {zero, zero};
    __m256d ts[2] = {zero, zero}, to[2] = {zero, zero};
    __m256d wsum = zero;
    for (int i = 0; i < nlocal; i++) {
        const int k0 = first[i] - 1, nn = first[i + 1] - first[i];
        const double *a = x + 3 * (long)i;
        const __m256d xi = _mm256_set1_pd(a[0]), yi = _mm256_set1_pd(a[1]), zi = _mm256_set1_pd(a[2]);
        if (multi) {      /* column type(i) of each table (eight entries: the tables hold 64) */
            const long col = (long)(type[i] - 1) * 8;
            for (int h = 0; h < 2; h++) {
                t1[h] = _mm256_loadu_pd(lj1 + col + 4 * h); t2[h] = _mm256_loadu_pd(lj2 + col + 4 * h);
                ts[h] = _mm256_loadu_pd(cutsq + col + 4 * h);
                if (want_energy) {
                    t3[h] = _mm256_loadu_pd(lj3 + col + 4 * h); t4[h] = _mm256_loadu_pd(lj4 + col + 4 * h);
                    to[h] = _mm256_loadu_pd(offset + col + 4 * h);
                }
            }
        }
        __m256d sx = zero, sy = zero, sz = zero, se = zero;
        for (int k = 0; k < nn; k += 4) {
            const int cnt = nn - k < 4 ? nn - k : 4;
            const int *nb = neigh + k0 + k;
            if (multi) {  /* each lane's coefficients (ntype: valid past the row; padding lanes lie 1e100 away) */
                const __m256i t = _mm256_cvtepi32_epi64(
                    _mm_sub_epi32(_mm_loadu_si128((const __m128i *)(ntype + k0 + k)), _mm_set1_epi32(1)));
                const __m256i lo = _mm256_slli_epi64(t, 1);   /* (vpermps reads the low three bits: t mod 4) */
                const __m256i idx = _mm256_or_si256(lo, _mm256_slli_epi64(_mm256_add_epi64(lo, _mm256_set1_epi64x(1)), 32));
                const __m256i upper = _mm256_cmpgt_epi64(t, _mm256_set1_epi64x(3));
                c1 = column4(half, idx, upper, t1[0], t1[1]); c2 = column4(half, idx, upper, t2[0], t2[1]);
                cs = column4(half, idx, upper, ts[0], ts[1]);
                if (want_energy) {
                    c3 = column4(half, idx, upper, t3[0], t3[1]); c4 = column4(half, idx, upper, t4[0], t4[1]);
                    co = column4(half, idx, upper, to[0], to[1]);
                }
            }
            const double *q[4];
            double *qf[4];
            if (cnt == 4)   /* (a whole block: no padding lanes to select) */
                rows4(x, f, nb, 4, far_row, spill, q, qf);
            else
                rows4(x, f, nb, cnt, far_row, spill, q, qf);
            __m256d dx, dy, dz;
            rows_xyz4(q, &dx, &dy, &dz);
            dx = _mm256_sub_pd(xi, dx); dy = _mm256_sub_pd(yi, dy); dz = _mm256_sub_pd(zi, dz);
            __m256d fx, fy, fz;
            pair_terms4(dx, dy, dz, c1, c2, c3, c4, cs, co, want_energy, &fx, &fy, &fz, &se, &wsum);
            sx = _mm256_add_pd(sx, fx); sy = _mm256_add_pd(sy, fy); sz = _mm256_add_pd(sz, fz);
            __m256d gx, gy, gz;
            rows_xyz4((const double *const *)qf, &gx, &gy, &gz);
            store_rows4(qf, _mm256_sub_pd(gx, fx), _mm256_sub_pd(gy, fy), _mm256_sub_pd(gz, fz));
        }
        double *fi = f + 3 * (long)i;
        fi[0] += sum4(sx); fi[1] += sum4(sy); fi[2] += sum4(sz);
        if (want_energy) atom_e[i] = sum4(se);
    }
    if (want_energy) *virial += sum4(wsum);
}
#endif

int terrace_lj_one_type(int nlocal, const double *x, double *f, const int *first, const int *neigh, double lj1,
                        double lj2, double lj3, double lj4, double cutsq, double offset, int want_energy,
                        double *atom_e, double *virial)
{
#if defined(__AVX512F__) && defined(__AVX512VL__) && defined(__FMA__)
    lj_pass(0, nlocal, x, f, first, neigh, 0, 0, 1, &lj1, &lj2, &lj3, &lj4, &cutsq, &offset, want_energy, atom_e,
            virial);
    return 1;
#elif defined(__AVX2__) && defined(__FMA__)
    lj_pass4(0, nlocal, x, f, first, neigh, 0, 0, 1, &lj1, &lj2, &lj3, &lj4, &cutsq, &offset, want_energy, atom_e,
             virial);
    return 1;
#else
    (void)nlocal; (void)x; (void)f; (void)first; (void)neigh; (void)lj1; (void)lj2; (void)lj3; (void)lj4;
    (void)cutsq; (void)offset; (void)want_energy; (void)atom_e; (void)virial;
    return 0;
#endif
}

/* The same pass for 2 to 8 atom types (style 'lj', not smooth): type(nlocal) the owned atoms' types,
 * ntype the list's neighbour types (list%ntype: eight valid entries past the last row), t the six
 * coefficient tables and the type count. Returns 0 (nothing done: the Fortran kernel runs)
 * where this build has neither AVX-512 nor AVX2 (each with FMA) or ntypes is outside 2..8. */
int terrace_lj_types(int nlocal, const double *x, double *f, const int *first, const int *neigh, const int *type,
                     const int *ntype, const struct terrace_lj_tables *t, int want_energy, double *atom_e,
                     double *virial)
{
#if defined(__AVX512F__) && defined(__AVX512VL__) && defined(__FMA__)
    if (t->ntypes < 2 || t->ntypes > 8) return 0;
    lj_pass(1, nlocal, x, f, first, neigh, type, ntype, t->ntypes, t->lj1, t->lj2, t->lj3, t->lj4, t->cutsq, t->offset,
            want_energy, atom_e, virial);
    return 1;
#elif defined(__AVX2__) && defined(__FMA__)
    if (t->ntypes < 2 || t->ntypes > 8) return 0;
    lj_pass4(1, nlocal, x, f, first, neigh, type, ntype, t->ntypes, t->lj1, t->lj2, t->lj3, t->lj4, t->cutsq,
             t->offset, want_energy, atom_e, virial);
    return 1;
#else
    (void)nlocal; (void)x; (void)f; (void)first; (void)neigh; (void)type; (void)ntype; (void)t; (void)want_energy;
    (void)atom_e; (void)virial;
    return 0;
#endif
}
