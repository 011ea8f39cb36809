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
# pairs. Then it runs Terrace's double and mixed kernels on input/lj_bench.nml (200 steps) and
# reads their force pass per step from the run summary's Pair phase and their atom-list build (Neigh
# phase per build); and the list schedules of the mixed kernel's run (builds in 1000 steps at skins
# 0.2, 0.3, 0.6). The summary projects the mixed Verlet step with the probe's pass, build and prune
# in place of the mixed kernel and its list: A, the list at rc + skin rebuilt on Terrace's exact
# trigger; B, rebuilt every 20 steps (the anchors' schedule); C, an outer list at 3.3 kept while no
# atom moved 0.3, pruned to 2.7 whenever one moved 0.1 (exact too).
# REPEAT rounds (default 3) of the liquid probe runs and of Terrace's kernels, alternating; the
# summary at the end takes the best of them. With ANCHORS=FILE (an output of scripts/bench/anchors.sh,
# e.g. doc/bench_data/anchors_all_098eb85_epyc.txt) the projections also use that run's mixed-kernel
# phases and GROMACS mixed loop time and print the ratio to GROMACS.
# Both the probe and Terrace's log time wall seconds (best of several): run it on a quiet machine.
# Usage: [REPEAT=N] [ANCHORS=FILE] scripts/bench/cluster_pair_probe.sh [TERRACE_BINARY]   (default build/terrace)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
terrace="$(realpath "${1:-$repo/build/terrace}")"
[[ -x "$terrace" ]] || { echo "cluster_pair_probe: no Terrace binary at $terrace (bash scripts/build.sh first)" >&2; exit 2; }
repeat="${REPEAT:-3}"
[[ "$repeat" =~ ^[1-9][0-9]*$ ]] || { echo "cluster_pair_probe: REPEAT must be a positive integer, not '$repeat'" >&2; exit 2; }
anchors=""
if [[ -n "${ANCHORS:-}" ]]; then
    anchors="$(realpath "$ANCHORS")"
    grep -q '^gromacs_mix ' "$anchors" || { echo "cluster_pair_probe: $ANCHORS has no gromacs_mix row (an anchors.sh output?)" >&2; exit 2; }
fi
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
gfortran -std=f2018 -ffree-line-length-none -O3 -march=native -funroll-loops \
    "$here/cluster_pair_probe.f90" -J "$work" -o "$work/probe"
echo "machine : $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1), $(nproc) cores visible"
echo "date    : $(date -u '+%Y-%m-%d %H:%M UTC'); load $(cut -d' ' -f1-3 /proc/loadavg) at start"
echo "commit  : $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "compiler: $(gfortran --version | head -1); -O3 -march=native -funroll-loops"
echo "rounds  : $repeat"
echo
fail() { echo "cluster_pair_probe: Terrace failed:" >&2; tail -5 "$1" >&2; exit 1; }
cd "$work"
# The probe's scene: the LJ bench liquid after 1000 steps of Terrace (the state the bench's list
# builds and force passes see), written by &output final_atoms_file
sed -E "s#^&output .*#\&output thermo_every=1000, thermo_file='', final_atoms_file='$work/liquid.atoms' /#" \
    "$repo/input/lj_bench.nml" > liquid.nml
grep -q "final_atoms_file" liquid.nml || { echo "cluster_pair_probe: could not set final_atoms_file" >&2; exit 1; }
"$terrace" liquid.nml > liquid.log 2>&1 || fail liquid.log
# Terrace's kernels: 200 steps, double and mixed
sed -E "s/n_steps=[0-9]+/n_steps=200/" "$repo/input/lj_bench.nml" > double.nml
sed -E "s#shift=.false. /#shift=.false., precision='mixed' /#" double.nml > mixed.nml
grep -q "precision='mixed'" mixed.nml || { echo "cluster_pair_probe: could not set precision='mixed'" >&2; exit 1; }
configs=("2.8 boxes 0" "2.5 boxes 0" "2.8 atoms 0" "2.5 atoms 0" "3.3 atoms 2.7")
for ((r = 1; r <= repeat; r++)); do
    echo "== round $r of $repeat: cluster-pair probe (single-precision pairs) on the LJ bench liquid after 1000 steps"
    for n in "${!configs[@]}"; do
        "$work/probe" ${configs[$n]} "$work/liquid.atoms" | tee "probe_${r}_$n.out"
        echo
    done
    echo "== round $r of $repeat: Terrace's atom-pair kernels, input/lj_bench.nml, 200 steps (run summary)"
    for k in double mixed; do
        "$terrace" $k.nml > ${k}_$r.log 2>&1 || fail ${k}_$r.log
        cp $k.summary.json ${k}_$r.summary.json
        PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary show \
            ${k}_$r.summary.json timing/phases/Pair timing/phases/Neigh neighbor/builds neighbor/list_pairs | sed "s/^/$k: /"
    done
    echo
done
echo "== the same probe on its own scene, the fcc lattice displaced by up to 0.2 sigma (closer pairs)"
"$work/probe" 2.8 atoms 0 | tee lattice.out
echo
# The list schedules: builds in 1000 steps of the mixed kernel's run at skins 0.2, 0.3 and 0.6 (an
# atom moved more than skin/2 since the last build), and the phases of its skin 0.3 run
echo "== list schedules: input/lj_bench.nml, precision='mixed', 1000 steps"
for sk in 0.2 0.3 0.6; do
    sed -E "s/skin=[0-9.]+/skin=$sk/" "$repo/input/lj_bench.nml" \
        | sed -E "s#shift=.false. /#shift=.false., precision='mixed' /#" > skin$sk.nml
    "$terrace" skin$sk.nml > skin$sk.log 2>&1 || fail skin$sk.log
    echo "skin $sk: $(PYTHONPATH="$repo/scripts" /usr/bin/python3 -m terrace_tools.summary get skin$sk.summary.json neighbor/builds) builds"
done
echo
PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 - "$repeat" "${#configs[@]}" "$anchors" <<'PY'
import re, sys
from terrace_tools import summary
rounds, nconf, anchors = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
def num(pat, text, cast=float):
    m = re.search(pat, text, re.M)
    return cast(m.group(1)) if m else None
keys = {'build': r'best of 3\):\s+([0-9.]+) ms', 'prune': r'prune pass \(best of 5\)\s+([0-9.]+) ms',
        'staged': r'^force pass \(best of 5 x 20\):\s+([0-9.]+) ms',
        'stw': r'per listed cluster pair: staging and write-back\s+([0-9.]+) ns',
        'single': r'^replicated j layout, j forces in singles:\s+([0-9.]+) ms',
        'jdouble': r'^replicated j layout, j forces in doubles:\s+([0-9.]+) ms',
        'hilo': r'^replicated, hi/lo separations, j forces in singles:\s+([0-9.]+) ms'}
errs = {'staged': r'^max \|F - F_double\| / F_rms:\s+(\S+)', 'single': r'in singles:.*F_rms\s+(\S+)',
        'jdouble': r'in doubles:.*F_rms\s+(\S+)', 'hilo': r'hi/lo separations.*F_rms\s+(\S+)',
        'mixed kernel (emulated)': r'emulated.*F_rms\s+(\S+)'}
best = []
for n in range(nconf):
    texts = [open('probe_%d_%d.out' % (r, n)).read() for r in range(1, rounds + 1)]
    b = {k: min(v for v in (num(p, t) for t in texts) if v is not None) for k, p in keys.items()
         if num(p, texts[0]) is not None}
    b['pairs'] = num(r"passes' list:\s+(\d+)", texts[0], int)
    b['cpp'] = num(r'pairs computed per pair within rc \+ skin\s+([0-9.]+)', texts[0])
    b['radius'] = num(r'^cluster list radius\s+([0-9.]+)', texts[0])
    b['atoms'] = 'checked atom by atom: T' in texts[0]
    b['text'] = texts[0]
    best.append(b)
print('== summary: best of %d rounds (wall ms per force pass; build best of 3, prune best of 5 per round)' % rounds)
print('%-26s %9s %6s %8s %9s %8s %9s %8s %8s %8s' % ('cluster list (liquid)', 'pairs', 'x pair', 'staged', 'ns stage',
      'single', 'j double', 'hi/lo', 'build', 'prune'))
for b in best:
    name = ('%.1f, %s' % (b['radius'], 'atom check' if b['atoms'] else 'boxes only'))
    if 'prune' in b:
        name = 'outer 3.3, pruned to 2.7'
    print('%-26s %9d %6.2f %8.2f %9.1f %8.2f %9.2f %8.2f %8.2f %8s' % (name, b['pairs'], b['cpp'], b['staged'], b['stw'],
          b['single'], b['jdouble'], b['hilo'], b['build'], '%.2f' % b['prune'] if 'prune' in b else '-'))
print('force errors, max |F - F_double| / rms F (atoms with a pair within 1e-6 sigma of rc left out):')
lat = open('lattice.out').read()
for name, p in errs.items():
    print('  %-24s liquid %9s   displaced lattice %9s' % (name, num(p, best[2]['text'], str), num(p, lat, str)))
kern = {}
for k in ('double', 'mixed'):
    runs = [summary.read('%s_%d.summary.json' % (k, r)) for r in range(1, rounds + 1)]
    pair = min(summary.get(s, 'timing/phases/Pair/avg_s') for s in runs)
    build = min(summary.get(s, 'timing/phases/Neigh/avg_s') / summary.get(s, 'neighbor/builds') for s in runs)
    npairs = summary.get(runs[0], 'neighbor/list_pairs')
    kern[k] = 1e3 * pair / 200
    print("Terrace %-6s %6.2f ms per step (%.2f ns per list pair, %d pairs); atom list %.2f ms per build" %
          (k, 1e3 * pair / 200, 1e9 * pair / 200 / npairs, npairs, 1e3 * build))
builds = {sk: summary.get('skin%s.summary.json' % sk, 'neighbor/builds') for sk in ('0.2', '0.3', '0.6')}
s03 = summary.read('skin0.3.summary.json')
own = lambda name: summary.get(s03, 'timing/phases/%s/avg_s' % name)
phase = lambda name, text: num(r'^ *%s +([0-9.]+)' % name, text)      # (the anchors report's phase table)
now = (own('Pair'), own('Neigh'), sum(own(p) for p in ('Comm', 'Output', 'Other')))
source, gmx = "this run's skin 0.3 run summary", None
if anchors:
    a = open(anchors).read()
    block = a[a.index('Terrace mixed-precision kernel, phases'):].split('\n')[1:]
    block = '\n'.join(block[:next(i for i, l in enumerate(block) if not l.startswith('    '))])   # its indented table
    steps = num(r'^== LJ scene: [0-9,]+ atoms, (\d+) steps', a, int)
    now = tuple(x * 1000 / steps for x in (phase('Pair', block), phase('Neigh', block),
                                           sum(phase(p, block) for p in ('Comm', 'Output', 'Other'))))
    gmx = num(r'^gromacs_mix +\d+ +([0-9.]+)', a) * 1000 / steps
    source = anchors.split('/')[-1]
rest = now[2]
print('== projected mixed Verlet step, ms per step (probe: best figures above; the mixed kernel now, the rest of')
print('   the step%s: %s)' % (' and GROMACS mixed' if gmx else '', source))
def line(label, parts):
    t = sum(parts)
    ratio = '   %.2fx GROMACS mixed' % (gmx / t) if gmx else ''
    print('  %-62s %s = %.2f%s' % (label, ' + '.join('%.2f' % x for x in parts), t, ratio))
line('now: the mixed kernel, exact list (%d builds)' % builds['0.3'], list(now))
for v in ('single', 'hilo'):
    a3, c5 = best[2], best[4]
    print(' -- pass with %s' % ('single relative positions' if v == 'single' else 'hi/lo separations'))
    line('A: list at 2.8 + atom check, exact trigger (%d builds)' % builds['0.3'], [a3[v], builds['0.3'] * a3['build'] / 1000, rest])
    line('B: the same rebuilt every 20 steps (50 builds)', [a3[v], 50 * a3['build'] / 1000, rest])
    line('C: outer 3.3 (%d builds), pruned to 2.7 (%d prunes)' % (builds['0.6'], builds['0.2']),
         [c5[v], builds['0.6'] * c5['build'] / 1000, builds['0.2'] * c5['prune'] / 1000, rest])
if gmx:
    print('  (1.5x GROMACS mixed: %.2f ms per step)' % (gmx / 1.5))
PY
