#!/usr/bin/env bash
# Instructions per pair and per neighbour build of Terrace on the LJ bench scene (input/lj_bench.nml,
# 32,000 atoms), counted by callgrind (they repeat exactly on a shared machine, unlike wall times).
# Needs a -DTERRACE_PORTABLE=ON build (valgrind stops a -march=native build with SIGILL), so the
# counts are of SSE2 code (2 doubles per vector), not of the AVX2 build the wall times measure.
# Pairs: LAMMPS's half list of the same scene within rc + skin ("Total # of neighbors", run 0).
# Usage: scripts/bench/lj_callgrind.sh PORTABLE_TERRACE [NSTEPS]   (default 20 steps)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
# the run summary's figures (scripts/terrace_tools)
figure() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get "$@"; }
[[ $# -ge 1 && -x "$1" ]] || { echo "usage: $0 PORTABLE_TERRACE [NSTEPS]" >&2; exit 2; }
ter="$(realpath "$1")"; n="${2:-20}"
[[ "$n" =~ ^[1-9][0-9]*$ ]] || { echo "NSTEPS must be a positive integer" >&2; exit 2; }
for c in valgrind callgrind_annotate lmp; do command -v $c > /dev/null || { echo "lj_callgrind: $c not found" >&2; exit 2; }; done
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT; cd "$work"
sed -E "s/n_steps=[0-9]+/n_steps=$n/" "$repo/input/lj_bench.nml" > lj.nml
lmp -screen none -log lmp.log -var nsteps 0 -in "$here/in.lj_bench" > /dev/null
pairs=$(sed -n 's/^Total # of neighbors = \([0-9]*\).*/\1/p' lmp.log | tail -1)
valgrind --tool=callgrind --callgrind-out-file=cg.out "$ter" lj.nml > ter.log 2> cg.err || {
    echo "lj_callgrind: terrace failed under valgrind (a -march=native build? use -DTERRACE_PORTABLE=ON)" >&2; tail -3 cg.err >&2; exit 2; }
builds=$(figure lj.summary.json neighbor/builds)
callgrind_annotate --inclusive=yes cg.out > ann.txt 2> /dev/null
ir() { awk -v pat="$1" '$0 ~ pat { gsub(/,/, "", $1); print $1; exit }' ann.txt; }
total=$(sed -n 's/^summary: *\([0-9]*\).*/\1/p' cg.out | head -1)
kern=$(ir 'lj_MOD_kernel'); build=$(ir 'neighbor_list_MOD_nl_build')
echo "Terrace on the LJ bench scene under callgrind: $n steps (+ the forces at step 0), $builds list builds"
echo "binary  : $ter"
echo "commit  : $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown); date $(date -u '+%Y-%m-%d %H:%M UTC')"
echo "pairs   : $pairs within rc + skin (LAMMPS half list of the start lattice)"
awk -v t="$total" -v k="${kern:-0}" -v b="${build:-0}" -v nb="$builds" -v p="$pairs" -v n="$n" 'BEGIN {
    printf "whole process      %.4e instructions\n", t
    printf "LJ kernel          %.4e instructions  %.1f per pair per force pass (%d passes)\n", k, k / (p * (n + 1)), n + 1
    printf "neighbour builds   %.4e instructions  %.4g per build, %.1f per atom per build, %.1f per pair per build\n",
           b, b / nb, b / nb / 32000, b / nb / p }'
echo "top functions (inclusive):"
grep -E 'MOD_' ann.txt | head -8 | sed 's/^/    /'
