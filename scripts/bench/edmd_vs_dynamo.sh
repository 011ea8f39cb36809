#!/usr/bin/env bash
# Event-driven hard spheres, Terrace against DynamO (Bannerman, Sargant & Lue, J. Comput. Chem. 32,
# 3329 (2011)) on the same machine, run alternately.
#
# The same system in both codes: elastic hard spheres (sigma = m = kT = 1), N = 4 n^3 atoms on an
# fcc lattice of n cells at packing fraction ETA, velocities drawn at kT = 1, one process, no
# equilibration in either. Each code runs every size twice, for the simulated time of C and of 3 C
# collisions per atom (time = C / Enskog's collision rate per atom; Terrace: `run_time`, DynamO:
# `dynarun -f`), with C = max(COLLISIONS, 2 MIN_COLLISIONS / N) so that the short run has at least
# MIN_COLLISIONS pair collisions. The cost is the difference of the two runs' CPU times (user +
# system, /usr/bin/time) over the difference of their counts, so that start-up, reading and
# writing of configurations drop out, and other jobs on a shared machine do not count.
# DynamO runs as users run it (`dynarun` with its default output plugin, Misc); its event counter
# counts pair collisions only (cell crossings and re-predictions are not counted: its output's
# Duration Events = TwoParticleEvents), Terrace's counts pair crossings, cell crossings and stale
# predictions. The table gives both codes' events per second by their own count, and collisions
# per second and microseconds per collision by the same count, and each code's peak resident
# memory (MiB) in its longer run.
# Rounds alternate the order (Terrace first in odd rounds, DynamO first in even ones); the table
# gives the median and the range (min-max) over the rounds, and the ratio of the medians.
#
# Inputs (environment):
#   DYNAMO_BIN      directory holding dynamod and dynarun (required)
#   TERRACE         the terrace binary (default: build/terrace of this checkout)
#   SIZES           fcc cells per side (default '6 14 29': N = 864, 10976, 97556; 63 gives 1000188)
#   ETA             packing fraction (default 0.45)
#   COLLISIONS      collisions per atom of the short run, at least (default 5)
#   MIN_COLLISIONS  pair collisions of the short run, at least (default 400000)
#   ROUNDS          rounds for N < 500000 (default 3); ROUNDS_LARGE for larger N (default 1)
#   OUT             work directory (default /tmp/edmd_vs_dynamo)
# DynamO is built outside this repository (doc/event_driven.md, section Cost, says how).
# Usage: DYNAMO_BIN=/work/dynamo-build scripts/bench/edmd_vs_dynamo.sh
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
: "${DYNAMO_BIN:?set DYNAMO_BIN to the directory holding dynamod and dynarun}"
terrace="$(realpath "${TERRACE:-$repo/build/terrace}")"
sizes="${SIZES:-6 14 29}"; eta="${ETA:-0.45}"; coll="${COLLISIONS:-5}"; min_coll="${MIN_COLLISIONS:-400000}"
rounds="${ROUNDS:-3}"; rounds_large="${ROUNDS_LARGE:-1}"; out="${OUT:-/tmp/edmd_vs_dynamo}"
py=/usr/bin/python3
for exe in "$DYNAMO_BIN/dynamod" "$DYNAMO_BIN/dynarun" "$terrace"; do
    [[ -x "$exe" ]] || { echo "edmd_vs_dynamo: $exe is not an executable" >&2; exit 1; }
done
mkdir -p "$out"; results="$out/results.txt"; : > "$results"

# number density and the Enskog collision rate per atom (kT = m = sigma = 1)
read -r dens rate <<< "$($py -c "
import math; e = $eta; n = 6*e/math.pi; g = (1 - e/2)/(1 - e)**3
print('%.17g %.17g' % (n, 4*n*g*math.sqrt(math.pi)))")"

run_terrace() {   # cells, collisions per atom, directory -> 'cpu events collisions' on stdout
    local m=$1 c=$2 d=$3 t
    mkdir -p "$d"; t="$($py -c "print('%.17g' % ($c/$rate))")"
    cat > "$d/run.nml" <<NML
&run units='lj', dimension=3, run_time=$t, seed=4 /
&system lattice='fcc', density=$dens, cells=$m,$m,$m, mass=1.0, temperature=1.0 /
&potential style='hard_sphere', diameter=1.0 /
&integrator style='event_driven' /
&output thermo_interval=$t /
NML
    (cd "$d" && /usr/bin/time -f '%U %S %M' -o time.txt "$terrace" run.nml > terrace.log 2>&1)
    $py - "$d" <<'PY'
import json, sys
d = sys.argv[1]
u, s, mem = open(d + '/time.txt').read().split()[-3:]
ed = json.load(open(d + '/run.summary.json'))['event_driven']
print(float(u) + float(s), ed['events'], ed['pair_crossings'], int(mem) // 1024)
PY
}

run_dynamo() {    # config, collisions per atom, directory -> 'cpu events collisions' on stdout
    local cfg=$1 c=$2 d=$3 t
    mkdir -p "$d"; t="$($py -c "print('%.17g' % ($c/$rate))")"
    (cd "$d" && /usr/bin/time -f '%U %S %M' -o time.txt "$DYNAMO_BIN/dynarun" "$cfg" -f "$t" \
         -o end.xml.bz2 --out-data-file output.xml.bz2 > dynamo.log 2>&1)
    $py - "$d" <<'PY'
import bz2, sys, xml.etree.ElementTree as ET
d = sys.argv[1]
u, s, mem = open(d + '/time.txt').read().split()[-3:]
dur = ET.fromstring(bz2.open(d + '/output.xml.bz2').read()).find('Misc/Duration')
print(float(u) + float(s), dur.get('Events'), dur.get('TwoParticleEvents'), int(mem) // 1024)
PY
}

for m in $sizes; do
    n=$((4 * m * m * m)); r=$rounds; (( n >= 500000 )) && r=$rounds_large
    c="$($py -c "print('%.6g' % max($coll, 2*$min_coll/$n))")"
    cfg="$out/dynamo_m$m.xml.bz2"
    # mode 0 of dynamod: monocomponent hard spheres on an fcc lattice, kT = 1, total momentum zero
    "$DYNAMO_BIN/dynamod" -m 0 -C "$m" -d "$dens" -s 4 -o "$cfg" > "$out/dynamod_m$m.log" 2>&1
    for ((k = 1; k <= r; k++)); do
        if (( k % 2 )); then order="terrace dynamo"; else order="dynamo terrace"; fi
        for code in $order; do
            for len in 1 3; do
                d="$out/m$m/$code.r$k.x$len"; cl="$($py -c "print('%.6g' % ($len*$c))")"
                if [[ $code == terrace ]]; then res="$(run_terrace "$m" "$cl" "$d")"
                else res="$(run_dynamo "$cfg" "$cl" "$d")"; fi
                echo "$n $c $code $k $len $res" >> "$results"
                echo "N = $n, $code, round $k, $cl collisions per atom: cpu s, events, collisions = $res" >&2
            done
        done
    done
done

$py - "$results" "$eta" <<'PY'
import collections, datetime, statistics, subprocess, sys
path, eta = sys.argv[1], float(sys.argv[2])
runs = collections.defaultdict(dict)
per_atom = {}
for line in open(path):
    n, c, code, k, length, cpu, ev, co, mib = line.split()
    runs[(int(n), code, int(k))][int(length)] = (float(cpu), int(ev), int(co), int(mib))
    per_atom[int(n)] = float(c)
rates = collections.defaultdict(list)          # (N, code) -> [(events/s, coll/s)]
memory = collections.defaultdict(int)          # (N, code) -> peak MiB of the longer runs
for (n, code, k), r in sorted(runs.items()):
    if 1 in r and 3 in r:
        dcpu = r[3][0] - r[1][0]
        rates[(n, code)].append(((r[3][1] - r[1][1]) / dcpu, (r[3][2] - r[1][2]) / dcpu))
        memory[(n, code)] = max(memory[(n, code)], r[3][3])
model = 'unknown'
for line in subprocess.run(['lscpu'], capture_output=True, text=True).stdout.splitlines():
    if line.startswith('Model name:'):
        model = line.split(':', 1)[1].strip()
print('hard spheres, eta = %g, fcc start, one process; %s, %s UTC'
      % (eta, model, datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M')))
print('CPU time of the run for 3 C collisions per atom minus the run for C; median [min-max] over the rounds')
print('%9s %6s %8s %6s %24s %24s %20s %8s' % ('N', 'C', 'code', 'rounds', 'events/s (own count)',
                                              'collisions/s', 'us per collision', 'MiB'))
def fmt(values, scale=1.0, f='%.3g'):
    v = [scale * x for x in values]
    return (f + ' [' + f + '-' + f + ']') % (statistics.median(v), min(v), max(v))
for n in sorted({n for n, _ in rates}):
    for code in ('terrace', 'dynamo'):
        if (n, code) not in rates:
            continue
        ev = [e for e, _ in rates[(n, code)]]; co = [c for _, c in rates[(n, code)]]
        print('%9d %6.3g %8s %6d %24s %24s %20s %8d' % (n, per_atom[n], code, len(co), fmt(ev), fmt(co),
                                                  fmt([1e6 / c for c in co], f='%.2f'), memory[(n, code)]))
    if (n, 'terrace') in rates and (n, 'dynamo') in rates:
        t = statistics.median(c for _, c in rates[(n, 'terrace')])
        d = statistics.median(c for _, c in rates[(n, 'dynamo')])
        print('%9d   collisions/s terrace / dynamo = %.2f' % (n, t / d))
PY
