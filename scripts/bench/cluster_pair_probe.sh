#!/usr/bin/env bash
# Issue 16, the mixed-precision kernel's goal (1.5x GROMACS mixed): would a cluster-pair force pass
# (GROMACS's nbnxm idea: 4 x 4 atom pairs of two clusters of four, 16 singles per AVX-512 vector)
# beat Terrace's atom-pair kernels on LAMMPS's LJ bench scene? Compiles the standalone probe
# cluster_pair_probe.f90 (not part of the engine; see its header) with the engine's flags and runs
# it five times on the LJ bench liquid (Terrace's state after 1000 steps): cluster lists at rc +
# skin (2.8 sigma: what every pass reads without pruning) and at rc (2.5: the fewest cluster pairs
# a pruned list could keep), each by bounding boxes alone and with GROMACS's atom check ('atoms': a
# cluster pair listed only when one of its 16 atom pairs is within the radius); and once built at
# 3.3 sigma and pruned to 2.7 (GROMACS's dynamic pruning: an outer list that lives longer, an inner
# one re-pruned from it). Each run times the list build and four passes (staged; replicated j
# layout with j forces in singles; the same in doubles; hi/lo separations, the mixed kernel's
# accuracy). One more run on the probe's own displaced lattice shows the force errors with closer
# pairs. Then it runs Terrace's double and mixed kernels on input/lj_bench.nml (200 steps, best of
# 3) and prints their force pass per step from the run log's Pair phase, per pair within rc +
# skin, and their atom-list build (Neigh phase per build). Last, the list schedules of the mixed
# kernel's run (builds in 1000 steps at skins 0.2, 0.3, 0.6) and the mixed Verlet step projected
# with the probe's pass, build and prune in place of the mixed kernel and its list: A, the list at
# rc + skin rebuilt on Terrace's exact trigger; B, rebuilt every 20 steps (the anchors' schedule);
# C, an outer list at 3.3 kept while no atom moved 0.3, pruned to 2.7 whenever one moved 0.1
# (exact too).
# Both the probe and Terrace's log time wall seconds (best of several): run it on a quiet machine.
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
# The probe's scene: the LJ bench liquid after 1000 steps of Terrace (the state the bench's list
# builds and force passes see), written by &output final_atoms_file
sed -E "s#^&output .*#\&output thermo_every=1000, thermo_file='', final_atoms_file='$work/liquid.atoms' /#" \
    "$repo/input/lj_bench.nml" > "$work/liquid.nml"
grep -q "final_atoms_file" "$work/liquid.nml" || { echo "cluster_pair_probe: could not set final_atoms_file" >&2; exit 1; }
"$terrace" "$work/liquid.nml" > "$work/liquid.log" 2>&1 || { echo "cluster_pair_probe: Terrace failed:" >&2; tail -5 "$work/liquid.log" >&2; exit 1; }
echo "== cluster-pair probe (single-precision pairs) on the LJ bench liquid after 1000 steps"
n=0
for args in "2.8 boxes 0" "2.5 boxes 0" "2.8 atoms 0" "2.5 atoms 0" "3.3 atoms 2.7"; do
    n=$((n + 1))
    "$work/probe" $args "$work/liquid.atoms" | tee "$work/probe$n.out"
    echo
done
echo "== the same probe on its own scene, the fcc lattice displaced by up to 0.2 sigma (closer pairs)"
"$work/probe" 2.8 atoms 0
echo
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

# The list schedules: builds in 1000 steps of the mixed kernel's run at skins 0.2, 0.3 and 0.6 (an
# atom moved more than skin/2 since the last build), and the rest of its step (Comm + Output + Other)
echo
echo "== list schedules: input/lj_bench.nml, precision='mixed', 1000 steps"
for sk in 0.2 0.3 0.6; do
    sed -E "s/skin=[0-9.]+/skin=$sk/" "$repo/input/lj_bench.nml" \
        | sed -E "s#shift=.false. /#shift=.false., precision='mixed' /#" > skin$sk.nml
    "$terrace" skin$sk.nml > skin$sk.log 2>&1 || { echo "cluster_pair_probe: Terrace failed:" >&2; tail -5 skin$sk.log >&2; exit 1; }
    b=$(sed -n 's/^ *Neighbour list builds: *//p' skin$sk.log | head -1)
    echo "skin $sk: $b builds"
    eval "builds_${sk/./}=$b"
done
rest=$(awk '/^(Comm|Output|Other) +[0-9]/ {s += $2} END {printf "%.4f", s}' skin0.3.log)
pair03=$(awk '/^Pair +[0-9]/ {print $2; exit}' skin0.3.log)
neigh03=$(awk '/^Neigh +[0-9]/ {print $2; exit}' skin0.3.log)
loop=$(sed -n 's/^Loop time: *\([0-9.]*\) s.*/\1/p' skin0.3.log | head -1)
echo "skin 0.3 run: Comm + Output + Other $rest s in 1000 steps; loop ${loop:-?} s"
# figures of the probe runs: build and prune (ms), and the replicated single pass (ms)
build3=$(sed -n 's/.*build (columns, clusters, list; best of 3): *\([0-9.]*\) ms.*/\1/p' "$work/probe3.out")
pass3=$(sed -n 's/^replicated j layout, j forces in singles: *\([0-9.]*\) ms.*/\1/p' "$work/probe3.out")
build5=$(sed -n 's/.*build (columns, clusters, list; best of 3): *\([0-9.]*\) ms.*/\1/p' "$work/probe5.out")
prune5=$(sed -n 's/.*prune pass (best of 5) *\([0-9.]*\) ms.*/\1/p' "$work/probe5.out")
pass5=$(sed -n 's/^replicated j layout, j forces in singles: *\([0-9.]*\) ms.*/\1/p' "$work/probe5.out")
hl3=$(sed -n 's/^replicated, hi\/lo separations, j forces in singles: *\([0-9.]*\) ms.*/\1/p' "$work/probe3.out")
hl5=$(sed -n 's/^replicated, hi\/lo separations, j forces in singles: *\([0-9.]*\) ms.*/\1/p' "$work/probe5.out")
echo
echo "== projected mixed Verlet step with the probe's pass, build and prune in place of the mixed kernel and its list"
echo "   (ms per step; the rest of the step as the skin 0.3 run's; GROMACS's step: scripts/bench/anchors.sh)"
for variant in single hilo; do
    if [[ $variant == single ]]; then p3=$pass3; p5=$pass5; label="single relative positions"; else p3=$hl3; p5=$hl5; label="hi/lo separations (the mixed kernel's accuracy)"; fi
    echo "-- pass with $label"
    awk -v f3="$p3" -v b3="$build3" -v f5="$p5" -v b5="$build5" -v p5="$prune5" -v rest="$rest" \
        -v n02="$builds_02" -v n03="$builds_03" -v n06="$builds_06" -v fp="$pair03" -v fn="$neigh03" 'BEGIN {
        r = rest                 # s per 1000 steps = ms per step
        printf "now: the mixed kernel, skin 0.3 (%d builds): %.3f pass + %.3f builds + %.3f rest = %.3f (its run log)\n", n03, fp, fn, r, fp + fn + r
        printf "A  list at 2.8 (atom check), rebuilt on the skin 0.3 trigger (%d builds): %.3f pass + %.3f builds + %.3f rest = %.3f\n", n03, f3, n03*b3/1000, r, f3 + n03*b3/1000 + r
        printf "B  the same list rebuilt every 20 steps (50 builds, the anchors schedule):  %.3f pass + %.3f builds + %.3f rest = %.3f\n", f3, 50*b3/1000, r, f3 + 50*b3/1000 + r
        printf "C  outer list at 3.3 on the skin 0.6 trigger (%d builds), pruned to 2.7 on the skin 0.2 trigger (%d prunes): %.3f pass + %.3f builds + %.3f prunes + %.3f rest = %.3f\n", n06, n02, f5, n06*b5/1000, n02*p5/1000, r, f5 + n06*b5/1000 + n02*p5/1000 + r
    }'
done
