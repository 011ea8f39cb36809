#!/usr/bin/env bash
# Energy conservation of the mixed-precision LJ kernel (&potential precision = 'mixed') against the
# double kernel, NVE velocity Verlet, one rank: the mixed kernel over the cluster-pair list
# (&neighbor list = 'clusters', 'mixed') and over the atom list (list = 'cells', 'mixed_cells'). Scene: LAMMPS's LJ bench scene (input/lj_bench.nml:
# 32,000 atoms, fcc rho* = 0.8442 melting from T* = 1.44, lj/cut rc = 2.5 unshifted, skin 0.3,
# dt = 0.005 tau). Both runs start from the same state; thermo every 100 steps.
# Prints per kernel: the drift of the total energy per atom per tau (least-squares slope of
# etotal(t) / N over the last 90 % of the run: the first tenth holds the melting of the hot lattice
# start, where E settles), the largest |E(t) - E(t0)| / N over that part, the rms fluctuation of E per atom, and the loop and
# "Pair" times; then the mixed/double ratio of the drifts.
# (The unshifted cutoff makes E jump when pairs cross rc; both kernels see that, it is the larger
# part of the fluctuation; a drift of the mixed kernel's own would show in the slope.)
# Usage: scripts/bench/mixed_drift.sh [NSTEPS [TERRACE_BINARY]]   (defaults 10000, build/terrace)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
n="${1:-10000}"; terrace="$(realpath "${2:-$repo/build/terrace}")"
[[ "$n" =~ ^[1-9][0-9]*$ ]] || { echo "usage: $0 [NSTEPS [TERRACE]] (NSTEPS a positive integer)" >&2; exit 2; }
[[ -x "$terrace" ]] || { echo "mixed_drift: Terrace binary '$terrace' not found (bash scripts/build.sh)" >&2; exit 2; }
work="$(mktemp -d "${TMPDIR:-/tmp}/mixed_drift.XXXXXX")"; trap 'rm -rf "$work"' EXIT
cd "$work"; cp "$terrace" ./terrace
echo "mixed-precision LJ kernel: energy drift against the double kernel, LJ bench scene, $n steps"
echo "machine : $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1) ($(nproc) cores visible)"
echo "date    : $(date -u '+%Y-%m-%d %H:%M UTC'), load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "commit  : $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)$(git -C "$repo" status --porcelain --untracked-files=no 2>/dev/null | grep -q . && echo ' (+ uncommitted changes)')"
for p in double mixed mixed_cells; do
    sed -E -e "s/n_steps=[0-9]+/n_steps=$n/" -e "s/thermo_file=''/thermo_file='thermo_$p.csv'/" \
        -e "s#shift=.false. /#shift=.false., precision='${p%_cells}' /#" "$repo/input/lj_bench.nml" > $p.nml
    grep -q "precision='${p%_cells}'" $p.nml || { echo "mixed_drift: could not set precision in the deck" >&2; exit 1; }
    if [[ $p != double ]]; then
        l="$([[ $p == mixed_cells ]] && echo cells || echo clusters)"
        sed -i -E "s#skin=0.3 /#skin=0.3, list='$l' /#" $p.nml
        grep -q "list='$l'" $p.nml || { echo "mixed_drift: could not set list in the deck" >&2; exit 1; }
    fi
    ./terrace $p.nml > $p.log 2>&1 || { echo "mixed_drift: the $p run failed:" >&2; tail -5 $p.log >&2; exit 1; }
done
PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 - "$n" <<'PY'
import csv, math, sys
from terrace_tools import summary
natoms = 32000
res = {}
for p in ('double', 'mixed', 'mixed_cells'):
    rows = list(csv.DictReader(open('thermo_%s.csv' % p)))
    rows = [r for r in rows if int(r['step']) >= int(sys.argv[1]) // 10]
    t = [float(r['time']) for r in rows]; e = [float(r['etotal']) for r in rows]
    m = len(t); tm = sum(t) / m; em = sum(e) / m
    slope = sum((a - tm) * (b - em) for a, b in zip(t, e)) / sum((a - tm) ** 2 for a in t)
    dev = max(abs(b - e[0]) for b in e) / natoms
    rms = math.sqrt(sum((b - em) ** 2 for b in e) / m) / natoms
    loop = summary.get('%s.summary.json' % p, 'timing/loop_time_s')
    pair = summary.get('%s.summary.json' % p, 'timing/phases/Pair/avg_s')
    res[p] = slope / natoms
    print('%-11s drift %+.3e eps/atom/tau   max |E(t)-E(t0)|/N %.3e   rms(E)/N %.3e   E(t0)/N %.6f   loop %.2f s, '
          'Pair %.2f s   (%d thermo rows, t = %g to %g tau)' % (p, slope / natoms, dev, rms, e[0] / natoms, loop, pair, m, t[0], t[-1]))
for p in ('mixed', 'mixed_cells'):
    print('%s/double drift ratio: %.2f   (|drift| difference %.3e eps/atom/tau)'
          % (p, res[p] / res['double'] if res['double'] else float('nan'), abs(res[p] - res['double'])))
PY
