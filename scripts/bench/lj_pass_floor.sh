#!/usr/bin/env bash
# What the fused LJ force pass (src/potentials/lj_simd.c: AVX-512, or AVX2 four lanes wide) spends
# its time on, on the argon job's geometry (scripts/bench/lj_pass_floor.c: 864 atoms, 8.5 A, list
# 9.1 A; the pass alone, no engine). The pass is compiled as it is and in variants made here from a
# copy of the source (sed; the script stops if an edit finds nothing to change), each linked to the
# driver:
#   as_is         the pass as it is, half list
#   no_j_forces   without the neighbours' force rows (loaded, reduced, stored back): the i side
#                 alone, the cost of a half-list pass whose j forces were free (wrong forces: a floor)
#   full_list     the same without j forces over a full list (Newton's third law off: each pair twice,
#                 right forces on owned atoms)
#   rcp14         as_is with 1/r^2 from the reciprocal estimate and two Newton steps in place of the
#                 division (not the division's bits)
#   mixed         the mixed-precision pass (src/potentials/lj_mixed_simd.c, linked to every variant) on
#                 the same half list: positions staged in fixed point, single pair terms and forces
# Prints each variant's cost per pair of the half list, median and range of 7 batches, in ROUNDS
# alternating rounds (default 3). Needs gcc and an AVX-512 machine, or one with AVX2 and FMA (the
# pass four lanes wide, lj_pass4, and the mixed pass eight wide; no rcp14 variant there).
# Usage: [ROUNDS=N] scripts/bench/lj_pass_floor.sh
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
rounds="${ROUNDS:-3}"
variants="as_is no_j_forces rcp14"
if ! grep -q avx512f /proc/cpuinfo; then
    grep -q avx2 /proc/cpuinfo && grep -qw fma /proc/cpuinfo \
        || { echo "lj_pass_floor: this machine has neither AVX-512 nor AVX2 with FMA" >&2; exit 2; }
    variants="as_is no_j_forces"
fi
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
src="$repo/src/potentials/lj_simd.c"
mkdir -p "$work/core" "$work/potentials"
cp "$repo/src/core/simd_rows.h" "$work/core/"
cp "$src" "$work/potentials/as_is.c"
# the j-force rows: the lines that load and store them (eight lanes, and the four-lane tail)
sed -e '/rows_xyz4\?((const double \*const \*)qf/d' -e '/store_rows4\?(qf, /d' "$src" > "$work/potentials/no_j_forces.c"
sed -e 's|__m512d r2inv = _mm512_div_pd(one, _mm512_mask_blend_pd(in, inf, rsq));|__m512d r2inv = _mm512_rcp14_pd(rsq); r2inv = _mm512_mul_pd(r2inv, _mm512_fnmadd_pd(rsq, r2inv, _mm512_set1_pd(2.0))); r2inv = _mm512_maskz_mul_pd(in, r2inv, _mm512_fnmadd_pd(rsq, r2inv, _mm512_set1_pd(2.0)));|' \
    -e 's|const __m256d r2inv = _mm256_div_pd(one, _mm256_blendv_pd(inf, rsq, in));|__m256d r2inv = _mm256_rcp14_pd(rsq); r2inv = _mm256_mul_pd(r2inv, _mm256_fnmadd_pd(rsq, r2inv, _mm256_set1_pd(2.0))); r2inv = _mm256_and_pd(in, _mm256_mul_pd(r2inv, _mm256_fnmadd_pd(rsq, r2inv, _mm256_set1_pd(2.0))));|' \
    "$src" > "$work/potentials/rcp14.c"
[[ $(grep -c 'store_rows4\?(qf' "$work/potentials/no_j_forces.c") == 0 && $(grep -c 'store_rows4\?(qf' "$src") -ge 2 ]] \
    || { echo "lj_pass_floor: could not remove the j-force rows from $src" >&2; exit 1; }
[[ $(grep -c '_rcp14_pd(rsq)' "$work/potentials/rcp14.c") == 2 ]] || { echo "lj_pass_floor: could not replace the divisions in $src" >&2; exit 1; }
# (rcp14 exists with AVX-512 only: that variant is built there alone)
for v in $variants; do
    gcc -O3 -march=native -funroll-loops -o "$work/$v" "$here/lj_pass_floor.c" "$work/potentials/$v.c" \
        "$repo/src/potentials/lj_mixed_simd.c" "$repo/src/potentials/lj_mixed_avx2.c" "$repo/src/neighbor/prune_simd.c" -lm
done
echo "LJ force pass alone, argon geometry; $(date -u '+%Y-%m-%d %H:%M UTC'); commit $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "machine: $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1), model $(sed -n 's/^model[[:space:]]*: //p' /proc/cpuinfo | head -1), load $(cut -d' ' -f1-3 /proc/loadavg)"
for r in $(seq "$rounds"); do
    echo "round $r"
    printf '  %-12s ' as_is; "$work/as_is" 0
    printf '  %-12s ' no_j_forces; "$work/no_j_forces" 0
    printf '  %-12s ' full_list; "$work/no_j_forces" 1
    if [[ -x "$work/rcp14" ]]; then printf '  %-12s ' rcp14; "$work/rcp14" 0; fi
    printf '  %-12s ' mixed; "$work/as_is" 2
done
