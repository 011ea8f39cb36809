#!/usr/bin/env bash
# Does the mixed-precision LJ kernel's pair pass vectorise 16 singles wide? Compiles
# src/potentials/lj.f90 with the build's flags (-O3 -march=native -funroll-loops) and
# -fopt-info-vec, prints what GCC reports for pairs_mixed's loops and the widths of the
# single-precision arithmetic (v*ps on zmm = 16 singles, ymm = 8, xmm = 4 or scalar-in-vector)
# and of the divides in the compiled lj_compute (where the mixed kernel is inlined).
# Usage: scripts/bench/mixed_vec_check.sh [BUILD_DIR]   (default build/, for its module files)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
build="$(realpath "${1:-$repo/build}")"
[[ -d "$build/modules" ]] || { echo "mixed_vec_check: no $build/modules (bash scripts/build.sh first)" >&2; exit 2; }
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
src="$repo/src/potentials/lj.f90"
gfortran -I "$build/modules" -J "$work" -std=f2018 -ffree-line-length-none -fimplicit-none -O3 -march=native \
    -funroll-loops -fopt-info-vec-optimized -c "$src" -o "$work/lj.o" 2> "$work/vec.txt"
echo "compiler: $(gfortran --version | head -1); -march=native = $(gfortran -march=native -Q --help=target 2>/dev/null | sed -n 's/^ *-march= *//p' | head -1)"
echo "commit  : $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
a=$(grep -n 'pure subroutine pairs_mixed' "$src" | cut -d: -f1); b=$(grep -n 'end subroutine pairs_mixed' "$src" | cut -d: -f1)
echo "GCC on pairs_mixed (lines $a-$b):"
awk -F: -v a="$a" -v b="$b" '$2 >= a && $2 <= b' "$work/vec.txt" | sed 's/^/    /'
objdump -d --no-show-raw-insn "$work/lj.o" | awk '/<__terrace_lj_MOD_lj_compute>:/,/^$/' > "$work/dis.txt"
echo "single-precision arithmetic in lj_compute (v{add,sub,mul,div,fma}ps) by register width:"
grep -E 'v(div|mul|add|sub|fmadd[0-9]*|fmsub[0-9]*|fnmadd[0-9]*)ps' "$work/dis.txt" | grep -oE '%(zmm|ymm|xmm)[0-9]+$' \
    | sed 's/[0-9]*$//; s/%//' | sort | uniq -c | sed 's/^/    /'
echo "divides: $(grep -cE 'vdivps.*zmm' "$work/dis.txt") vdivps zmm, $(grep -cE 'vdivps.*ymm' "$work/dis.txt") vdivps ymm (remainder), $(grep -cE 'vdivss' "$work/dis.txt") vdivss (scalar remainder)"
