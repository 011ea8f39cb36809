#!/usr/bin/env bash
# Two builds on the talk's seven-atom cluster (input/argon_frozen_2d.nml, one rank): the thermo file
# byte for byte (cmp) and every dataset and attribute of the trajectory byte for byte (raw bytes
# through h5py; the files' own HDF5 metadata may differ). A change to the energy-stepping path that
# keeps the arithmetic prints "identical".
# Usage: scripts/bench/cluster_identical.sh OLD_TERRACE NEW_TERRACE [NS]   (NS: simulated ns, default 100)
set -euo pipefail
[[ $# -ge 2 ]] || { echo "usage: $0 OLD_TERRACE NEW_TERRACE [NS]" >&2; exit 2; }
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
old="$(realpath "$1")"; new="$(realpath "$2")"; ns="${3:-100}"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
for side in old new; do
    mkdir -p "$work/$side"; cp "$repo/input/argon_frozen_2d.atoms" "$work/$side/"
    sed -e "s/run_time=100000.0/run_time=${ns}000.0/" "$repo/input/argon_frozen_2d.nml" > "$work/$side/cluster.nml"
done
(cd "$work/old" && "$old" cluster.nml > run.log 2>&1) || { echo "old build failed" >&2; tail -3 "$work/old/run.log" >&2; exit 1; }
(cd "$work/new" && "$new" cluster.nml > run.log 2>&1) || { echo "new build failed" >&2; tail -3 "$work/new/run.log" >&2; exit 1; }
echo "old: $old"; echo "new: $new"; echo "deck: input/argon_frozen_2d.nml, $ns ns"
export PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}"
for side in old new; do
    echo "$side events: $(for k in events ups downs reflections; do /usr/bin/python3 -m terrace_tools.summary get \
        "$work/$side/cluster.summary.json" energy_stepping/$k; done | tr '\n' ' ')(events, ups, downs, reflections)"
done
status=0
if cmp -s "$work/old/argon_frozen_2d.csv" "$work/new/argon_frozen_2d.csv"; then echo "thermo file: identical"
else echo "thermo file: DIFFERENT"; status=1; fi
/usr/bin/python3 - "$work/old/argon_frozen_2d.h5" "$work/new/argon_frozen_2d.h5" <<'PY' || status=1
import sys, h5py
a, b = h5py.File(sys.argv[1], 'r'), h5py.File(sys.argv[2], 'r')
def items(f):
    out = {}
    def visit(name, obj):
        if isinstance(obj, h5py.Dataset):
            out['data ' + name] = obj[()].tobytes() if obj.shape != () else bytes(repr(obj[()]), 'utf8')
        for k, v in obj.attrs.items():
            out['attr ' + name + '@' + k] = bytes(repr(v), 'utf8')
    f.visititems(visit)
    return out
ia, ib = items(a), items(b)
bad = sorted(k for k in set(ia) | set(ib) if ia.get(k) != ib.get(k))
ndata = sum(1 for k in ia if k.startswith('data '))
if bad:
    print('trajectory: DIFFERENT in', len(bad), 'of', len(set(ia) | set(ib)), 'items:', ', '.join(bad[:8]))
    sys.exit(1)
print(f'trajectory: identical ({ndata} datasets, {len(ia) - ndata} attributes, raw bytes)')
PY
exit $status
