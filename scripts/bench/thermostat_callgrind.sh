#!/usr/bin/env bash
# Instruction counts of the thermostats on the LJ benchmark scene (input/lj_bench.nml, the scene of
# thermostat_cost.sh), under valgrind's callgrind: unlike wall or CPU time they do not depend on
# the load of a shared machine, and they repeat to a few parts in 1e5.
#
# Usage: scripts/bench/thermostat_callgrind.sh [NSTEPS [TERRACE_BINARY]]   (defaults 20, build/terrace)
#
# Each style runs the deck for NSTEPS steps (thermostat as in thermostat_cost.sh: temperature 0.7,
# damping 0.5); only the time-step loop is counted (--toggle-collect on run_velocity_verlet).
# Reported: instructions per step of the loop, their excess over style 'none' (the thermostat's
# cost as a fraction of a Verlet step), the instructions per atom per step of that excess, and the
# neighbour-list builds (equal counts make the comparison fair: a build is ~25 % of a step here).
# Instructions are not time (vector and scalar instructions differ in cost): thermostat_cost.sh
# measures time; this script is its load-independent companion.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
nsteps="${1:-20}"
terrace="$(realpath "${2:-$repo/build/terrace}")"
command -v valgrind > /dev/null || { echo "SKIPPED: valgrind not installed"; exit 0; }
work="$(mktemp -d "${TMPDIR:-/tmp}/terrace_thermostat_callgrind.XXXXXX")"
trap 'rm -rf "$work"' EXIT
styles=(none langevin csvr nose_hoover andersen)
natoms=32000
declare -A ir builds
for s in "${styles[@]}"; do
    sed "s/n_steps=1000/n_steps=$nsteps/" "$repo/input/lj_bench.nml" > "$work/$s.nml"
    if [ "$s" != none ]; then
        echo "&thermostat style='$s', temperature=0.7, damping=0.5 /" >> "$work/$s.nml"
    fi
    (cd "$work" && valgrind --tool=callgrind --callgrind-out-file="$s.cg" \
        --toggle-collect='__terrace_velocity_verlet_MOD_run_velocity_verlet' "$terrace" "$s.nml" > "$s.log" 2>&1) \
        || { echo "FAIL: $s"; tail -3 "$work/$s.log"; exit 1; }
    ir[$s]=$(awk '/^summary:/ {print $2}' "$work/$s.cg")
    builds[$s]=$(awk '/^Neighbour list builds:/ {print $4}' "$work/$s.log")
done
printf '%-12s %16s %10s %14s %7s\n' style 'Ir/step (loop)' excess 'excess Ir/atom' builds
for s in "${styles[@]}"; do
    awk -v s="$s" -v a="${ir[$s]}" -v a0="${ir[none]}" -v n="$nsteps" -v na="$natoms" -v nb="${builds[$s]}" \
        'BEGIN { printf "%-12s %16.4e %9.2f%% %14.1f %7d\n", s, a/n, 100*(a/a0 - 1), (a - a0)/(n*na), nb }'
done
echo "($nsteps steps, $natoms atoms, callgrind instructions of the time-step loop; $(date -u +%F))"
