#!/usr/bin/env bash
# Issue 16: the mixed-precision kernel over the cluster-pair list (&neighbor list = 'clusters')
# against the same kernel over the atom list (list = 'cells', the default) and the double kernel,
# on the LJ bench scene (input/lj_bench.nml: 32,000 atoms, rho* 0.8442, rc 2.5, exact list
# schedule) at the bench's skin 0.3 and at each list's best skin of SKINS (default 0.4 0.5 0.6:
# a cluster pair costs the same whether its atoms are near or far, so the cluster list prefers a
# larger skin and fewer builds). REPEAT alternating rounds (default 3) of all runs, N steps each
# (default 1000); per variant the best round's loop time, the Pair phase per step, the Neigh
# phase per list build and the builds, from the run logs (wall clock, one rank).
# Usage: [REPEAT=N] scripts/bench/cluster_kernel.sh [STEPS] [TERRACE_BINARY]
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
steps="${1:-1000}"
terrace="$(realpath "${2:-$repo/build/terrace}")"
[[ -x "$terrace" ]] || { echo "cluster_kernel: no Terrace binary at $terrace (bash scripts/build.sh first)" >&2; exit 2; }
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
cd "$work"
base="$repo/input/lj_bench.nml"
skins="${SKINS:-0.4 0.5 0.6}"
sed -E "s/n_steps=[0-9]+/n_steps=$steps/" "$base" > double_0.3.nml
sed -E "s/shift=.false. \//shift=.false., precision='mixed' \//" double_0.3.nml > mixed.nml
sed -E "s/skin=0.3 \//skin=0.3, list='cells' \//" mixed.nml > mixed_cells_0.3.nml
sed -E "s/skin=0.3 \//skin=0.3, list='clusters' \//" mixed.nml > mixed_clusters_0.3.nml
grep -q "list='clusters'" mixed_clusters_0.3.nml && grep -q "list='cells'" mixed_cells_0.3.nml && grep -q "precision='mixed'" mixed.nml || {
    echo "cluster_kernel: could not edit $base" >&2; exit 1; }
variants="double_0.3 mixed_cells_0.3 mixed_clusters_0.3"
for sk in $skins; do
    sed -E "s/skin=0.3/skin=$sk/" mixed_cells_0.3.nml > "mixed_cells_$sk.nml"
    sed -E "s/skin=0.3/skin=$sk/" mixed_clusters_0.3.nml > "mixed_clusters_$sk.nml"
    variants="$variants mixed_cells_$sk mixed_clusters_$sk"
done
echo "cluster_kernel: $(date -u '+%Y-%m-%d %H:%M UTC'), commit $(git -C "$repo" rev-parse --short HEAD), $steps steps, ${REPEAT:-3} rounds"
echo "machine: $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | sed 's/^ //'), $(nproc) CPUs"
for r in $(seq 1 "${REPEAT:-3}"); do
    for v in $variants; do
        "$terrace" "$v.nml" > "${v}_$r.log" 2>&1 || { echo "cluster_kernel: $v failed" >&2; tail -5 "${v}_$r.log" >&2; exit 1; }
        cp "$v.summary.json" "${v}_$r.summary.json"
    done
done
PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 - "$steps" "${REPEAT:-3}" $variants <<'PY'
import sys
from terrace_tools import summary
steps, rounds, variants = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3:]
def parse(name):
    s = summary.read(name)
    ph = {p: summary.get(s, 'timing/phases/%s/avg_s' % p) for p in ('Pair', 'Neigh', 'Comm', 'Other')}
    return summary.get(s, 'timing/loop_time_s'), ph, summary.get(s, 'neighbor/builds')
print('%-20s %10s %14s %16s %7s %s' % ('variant_skin', 'loop (s)', 'Pair (ms/step)', 'Neigh (ms/build)', 'builds', 'rest (ms/step)'))
best = {}
for v in variants:
    runs = [parse('%s_%d.summary.json' % (v, r)) for r in range(1, rounds + 1)]
    loop, ph, b = min(runs, key=lambda x: x[0])
    best[v] = (loop, ph, b)
    pair = min(x[1]['Pair'] for x in runs) / steps * 1e3
    neigh = min(x[1]['Neigh'] / x[2] for x in runs) * 1e3
    print('%-20s %10.3f %14.3f %16.2f %7d %14.3f' % (v, loop, pair, neigh, b, (loop - ph['Pair'] - ph['Neigh']) / steps * 1e3))
c, a = best['mixed_clusters_0.3'], best['mixed_cells_0.3']
print('clusters / cells at skin 0.3: loop %.3f, Pair %.3f, Neigh per build %.3f' % (
    c[0] / a[0], c[1]['Pair'] / a[1]['Pair'], (c[1]['Neigh'] / c[2]) / (a[1]['Neigh'] / a[2])))
bc = min((v for v in variants if v.startswith('mixed_clusters')), key=lambda v: best[v][0])
ba = min((v for v in variants if v.startswith('mixed_cells')), key=lambda v: best[v][0])
print('best skins: %s %.3f s, %s %.3f s; clusters / cells %.3f; double (skin 0.3) / best clusters %.3f' % (
    ba, best[ba][0], bc, best[bc][0], best[bc][0] / best[ba][0], best['double_0.3'][0] / best[bc][0]))
PY
for v in $variants; do echo "$v: $(grep -hE '^(Cluster|List) pairs' "${v}_1.log" | sed -E 's/ \(.*\)//')"; done
