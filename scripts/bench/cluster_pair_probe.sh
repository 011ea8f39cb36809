#!/usr/bin/env bash
# Issue 16, the mixed-precision kernel's goal (1.5x GROMACS mixed): would a cluster-pair force pass
# (GROMACS's nbnxm idea: 4 x 4 atom pairs of two clusters of four, 16 singles per AVX-512 vector)
# beat Terrace's atom-pair kernels on LAMMPS's LJ bench scene? Compiles the standalone probe
# cluster_pair_probe.f90 (not part of the engine; see its header) with the engine's flags and runs
# it five times: cluster lists at rc + skin (2.8 sigma: what every pass reads without pruning) and
# at rc (2.5: the fewest cluster pairs a pruned list could keep), each by bounding boxes alone and
# with GROMACS's atom check ('atoms': a cluster pair listed only when one of its 16 atom pairs is
# within the radius); and once built at 3.1 sigma and pruned to 2.8 (GROMACS's dynamic pruning: an
# outer list that lives longer, an inner one re-pruned from it). Each run times the list build and
# three passes (staged; replicated j layout with j forces in singles; the same in doubles). Then
# it runs Terrace's double and mixed kernels on input/lj_bench.nml (200 steps, best of 3) and
# prints their force pass per step from the run log's Pair phase, per pair within rc + skin, and
# their atom-list build (Neigh phase per build).
# The probe times CPU seconds, Terrace's log wall seconds: run it on a quiet machine.
# Usage: scripts/bench/cluster_pair_probe.sh [TERRACE_BINARY]   (default build/terrace)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
terrace="$(realpath "${1:-$repo/build/terrace}")"
[[ -x "$terrace" ]] || { echo "cluster_pair_probe: no Terrace binary at $terrace (bash scripts/build.sh first)" >&2; exit 2; }
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
gfortran -std=f2018 -ffree-line-length-none -O3 -march=native -funroll-loops \
    "$here/cluster_pair_probe.f90" -J "$work" -o "$work/probe"
echo "machine : $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1), $(nproc) cores visible"
echo "date    : $(date -u '+%Y-%m-%d %H:%M UTC'); load $(cut -d' ' -f1-3 /proc/loadavg) at start"
echo "commit  : $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "compiler: $(gfortran --version | head -1); -O3 -march=native -funroll-loops"
echo
echo "== cluster-pair probe (single-precision pairs)"
for args in "2.8" "2.5" "2.8 atoms" "2.5 atoms" "3.1 atoms 2.8"; do
    "$work/probe" $args
    echo
done
echo "== Terrace's atom-pair kernels, input/lj_bench.nml, 200 steps (best of 3): force pass per step"
cd "$work"
sed -E "s/n_steps=[0-9]+/n_steps=200/" "$repo/input/lj_bench.nml" > double.nml
sed -E "s#shift=.false. /#shift=.false., precision='mixed' /#" double.nml > mixed.nml
grep -q "precision='mixed'" mixed.nml || { echo "cluster_pair_probe: could not set precision='mixed'" >&2; exit 1; }
for k in double mixed; do
    best=""
    for r in 1 2 3; do
        "$terrace" $k.nml > $k.log 2>&1 || { echo "cluster_pair_probe: Terrace failed:" >&2; tail -5 $k.log >&2; exit 1; }
        pair=$(awk '/^Pair +[0-9]/ {print $2; exit}' $k.log)
        if [[ -z "$best" ]] || awk -v a="$pair" -v b="$best" 'BEGIN {exit !(a < b)}'; then best=$pair; fi
    done
    pairs=$(sed -n 's/^List pairs (within rc + skin, last build): *//p' $k.log)
    neigh=$(awk '/^Neigh +[0-9]/ {print $2; exit}' $k.log)
    builds=$(sed -n 's/^ *Neighbour list builds: *//p' $k.log | head -1)
    awk -v k="$k" -v t="$best" -v n="$pairs" -v g="$neigh" -v b="$builds" 'BEGIN {printf "%-7s %7.3f ms per step; %6.3f ns per pair within rc + skin (%d pairs); list builds %d, %.2f ms each (Neigh phase of the last run)\n", k, 1e3*t/200, 1e9*t/200/n, n, b, 1e3*g/b}'
done
