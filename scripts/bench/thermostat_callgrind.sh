#!/usr/bin/env bash
# Instruction counts of the thermostats on the LJ benchmark scene (input/lj_bench.nml, the scene of
# thermostat_cost.sh), under valgrind's callgrind: unlike wall or CPU time they do not depend on
# the load of a shared machine, and they repeat to a few parts in 1e5.
#
# Usage: scripts/bench/thermostat_callgrind.sh [NSTEPS [TERRACE_BINARY]]   (defaults 20, build/terrace)
#        LONG=N2 (N2 > NSTEPS): every style also runs N2 steps, and the steady cost per step,
#        (Ir(N2) - Ir(NSTEPS)) / (N2 - NSTEPS), is reported beside it: it leaves out what a run does
#        once (Andersen with velocity Verlet computes every atom's first collision time in its first
#        step, about 0.6 of a step's instructions on this scene).
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
# the run summary's figures (scripts/terrace_tools)
figure() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get "$@"; }
nsteps="${1:-20}"
terrace="$(realpath "${2:-$repo/build/terrace}")"
command -v valgrind > /dev/null || { echo "SKIPPED: valgrind not installed"; exit 0; }
work="$(mktemp -d "${TMPDIR:-/tmp}/terrace_thermostat_callgrind.XXXXXX")"
trap 'rm -rf "$work"' EXIT
styles=(none langevin csvr nose_hoover andersen)
natoms=32000
long="${LONG:-0}"
declare -A ir builds
count() {   # style, steps, tag: instructions of the loop into ir[tag], builds into builds[tag]
    sed "s/n_steps=1000/n_steps=$2/" "$repo/input/lj_bench.nml" > "$work/$3.nml"
    if [ "$1" != none ]; then
        echo "&thermostat style='$1', temperature=0.7, damping=0.5 /" >> "$work/$3.nml"
    fi
    (cd "$work" && valgrind --tool=callgrind --callgrind-out-file="$3.cg" \
        --toggle-collect='__terrace_velocity_verlet_MOD_run_velocity_verlet' "$terrace" "$3.nml" > "$3.log" 2>&1) \
        || { echo "FAIL: $3"; tail -3 "$work/$3.log"; exit 1; }
    ir[$3]=$(awk '/^summary:/ {print $2}' "$work/$3.cg")
    builds[$3]=$(figure "$work/$3.summary.json" neighbor/builds)
}
for s in "${styles[@]}"; do
    count "$s" "$nsteps" "$s"
    [ "$long" -gt "$nsteps" ] && count "$s" "$long" "$s.long"
done
if [ "$long" -gt "$nsteps" ]; then
    printf '%-12s %16s %10s %14s %7s   %16s %10s %14s %7s\n' style 'Ir/step (loop)' excess 'excess Ir/atom' builds \
        'steady Ir/step' excess 'excess Ir/atom' builds
else
    printf '%-12s %16s %10s %14s %7s\n' style 'Ir/step (loop)' excess 'excess Ir/atom' builds
fi
for s in "${styles[@]}"; do
    awk -v s="$s" -v a="${ir[$s]}" -v a0="${ir[none]}" -v n="$nsteps" -v na="$natoms" -v nb="${builds[$s]}" \
        'BEGIN { printf "%-12s %16.4e %9.2f%% %14.1f %7d", s, a/n, 100*(a/a0 - 1), (a - a0)/(n*na), nb }'
    if [ "$long" -gt "$nsteps" ]; then
        awk -v a="${ir[$s]}" -v a0="${ir[none]}" -v b="${ir[$s.long]}" -v b0="${ir[none.long]}" -v n="$nsteps" \
            -v m="$long" -v na="$natoms" -v nb="${builds[$s.long]}" \
            'BEGIN { d = (b - a)/(m - n); d0 = (b0 - a0)/(m - n);
                     printf "   %16.4e %9.2f%% %14.1f %7d", d, 100*(d/d0 - 1), (d - d0)/na, nb }'
    fi
    echo
done
echo "($nsteps steps$([ "$long" -gt "$nsteps" ] && echo "; steady: the difference of $long and $nsteps steps"), $natoms atoms,"
echo " callgrind instructions of the time-step loop; builds: neighbour-list builds; $(date -u +%F))"
