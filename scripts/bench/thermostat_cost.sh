#!/usr/bin/env bash
# Cost of the thermostats on the LJ benchmark scene (input/lj_bench.nml: 32,000 atoms, fcc
# rho* = 0.8442 melting from T* = 1.44, lj/cut 2.5, skin 0.3, velocity Verlet dt 0.005).
#
# Usage: scripts/bench/thermostat_cost.sh [NSTEPS [TERRACE_BINARY]]   (defaults 1000, build/terrace)
#        REPEAT=N (default 3): every style is run N times, interleaved; its best and median loop
#        times are reported.
#
# Each style runs the same deck with &thermostat style=..., temperature=0.7 (about where the NVE
# run settles, so that the neighbour-list rebuild counts stay comparable), damping=0.5. Reported:
# the best and the median loop time and their overheads over style 'none', the user CPU time of the process (less
# sensitive than wall time to other jobs on a shared machine; GNU /usr/bin/time) and its overhead,
# the neighbour-list builds, and the direct cost of the thermostat operators: the growth of the
# 'Other' phase (integration, where the thermostat kernels run) as a fraction of the NVE loop time.
# One rank, one thread. Timings on a shared machine are noisy: repeat, and compare the CPU column.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
# the run summary's figures (scripts/terrace_tools)
figure() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get "$@"; }
nsteps="${1:-1000}"
terrace="$(realpath "${2:-$repo/build/terrace}")"
repeat="${REPEAT:-3}"
work="$(mktemp -d "${TMPDIR:-/tmp}/terrace_thermostat_cost.XXXXXX")"
trap 'rm -rf "$work"' EXIT
styles=(none langevin csvr nose_hoover andersen)
for s in "${styles[@]}"; do
    sed "s/n_steps=1000/n_steps=$nsteps/" "$repo/input/lj_bench.nml" > "$work/$s.nml"
    if [ "$s" != none ]; then
        echo "&thermostat style='$s', temperature=0.7, damping=0.5 /" >> "$work/$s.nml"
    fi
done
declare -A best other builds cpu all
timer=()
[ -x /usr/bin/time ] && timer=(/usr/bin/time -f 'CPU %U' -o cpu.txt)
for r in $(seq 1 "$repeat"); do
    for s in "${styles[@]}"; do
        (cd "$work" && "${timer[@]}" "$terrace" "$s.nml" > "$s.log" 2>&1) || { echo "FAIL: $s"; tail -3 "$work/$s.log"; exit 1; }
        u=$(awk '/^CPU/ {print $2}' "$work/cpu.txt" 2>/dev/null || true); u=${u:-0}
        if [ -z "${cpu[$s]:-}" ] || awk -v a="$u" -v b="${cpu[$s]}" 'BEGIN {exit !(a < b)}'; then cpu[$s]=$u; fi
        loop=$(figure "$work/$s.summary.json" timing/loop_time_s)
        all[$s]="${all[$s]:-} $loop"
        oth=$(figure "$work/$s.summary.json" timing/phases/Other/avg_s)
        nb=$(figure "$work/$s.summary.json" neighbor/builds)
        if [ -z "${best[$s]:-}" ] || awk -v a="$loop" -v b="${best[$s]}" 'BEGIN {exit !(a < b)}'; then
            best[$s]=$loop; other[$s]=$oth; builds[$s]=$nb
        fi
    done
done
median() { tr ' ' '\n' | grep -v '^$' | sort -g | awk '{a[NR] = $1} END {print (NR % 2 ? a[(NR + 1)/2] : (a[NR/2] + a[NR/2 + 1])/2)}'; }
declare -A med
for s in "${styles[@]}"; do med[$s]=$(echo "${all[$s]}" | median); done
printf '%-12s %10s %9s %12s %9s %10s %9s %7s %16s\n' style 'loop (s)' overhead 'median (s)' overhead 'CPU (s)' overhead builds 'thermostat cost'
for s in "${styles[@]}"; do
    awk -v s="$s" -v l="${best[$s]}" -v l0="${best[none]}" -v o="${other[$s]}" -v o0="${other[none]}" -v nb="${builds[$s]}" \
        -v c="${cpu[$s]}" -v c0="${cpu[none]}" -v m="${med[$s]}" -v m0="${med[none]}" \
        'BEGIN { printf "%-12s %10.3f %8.1f%% %12.3f %8.1f%% %10.2f %8.1f%% %7d %15.1f%%\n", s, l, 100*(l/l0 - 1), m, 100*(m/m0 - 1), c, (c0 > 0 ? 100*(c/c0 - 1) : 0), nb, 100*(o - o0)/l0 }'
done
echo "($nsteps steps, 32,000 atoms, best and median of $repeat runs, interleaved; CPU: best user time;"
echo " 'thermostat cost' = growth of the Other phase / NVE loop time, of the best runs; $(date -u +%F), load average $(cut -d' ' -f1-3 /proc/loadavg))"
