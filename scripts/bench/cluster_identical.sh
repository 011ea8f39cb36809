#!/usr/bin/env bash
# Two builds on one deck, by default the talk's seven-atom cluster (input/argon_frozen_2d.nml, one
# rank): every CSV file the runs write byte for byte (cmp) and every dataset and attribute of every
# HDF5 file they write byte for byte (raw bytes through h5py; the files' own HDF5 metadata may
# differ). A change that keeps the arithmetic prints "identical" for each.
# Usage: [DECK=input/square_well.nml] scripts/bench/cluster_identical.sh OLD_TERRACE NEW_TERRACE [NS]
#   DECK: the deck (its input/<stem>.atoms is copied beside it when there is one); NS: simulated ns of
#   the cluster deck (default 100; other decks run as they are).
set -euo pipefail
[[ $# -ge 2 ]] || { echo "usage: [DECK=deck.nml] $0 OLD_TERRACE NEW_TERRACE [NS]" >&2; exit 2; }
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
old="$(realpath "$1")"; new="$(realpath "$2")"; ns="${3:-100}"
deck="$(realpath "${DECK:-$repo/input/argon_frozen_2d.nml}")"; stem="$(basename "$deck" .nml)"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
for side in old new; do
    mkdir -p "$work/$side"
    [[ -f "$(dirname "$deck")/$stem.atoms" ]] && cp "$(dirname "$deck")/$stem.atoms" "$work/$side/"
    if [[ $stem == argon_frozen_2d ]]; then
        sed -e "s/run_time=100000.0/run_time=${ns}000.0/" "$deck" > "$work/$side/run.nml"
    else
        cp "$deck" "$work/$side/run.nml"
    fi
done
(cd "$work/old" && "$old" run.nml > run.log 2>&1) || { echo "old build failed" >&2; tail -3 "$work/old/run.log" >&2; exit 1; }
(cd "$work/new" && "$new" run.nml > run.log 2>&1) || { echo "new build failed" >&2; tail -3 "$work/new/run.log" >&2; exit 1; }
echo "old: $old"; echo "new: $new"; echo "deck: ${deck#"$repo"/}$([[ $stem == argon_frozen_2d ]] && echo ", $ns ns")"
export PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}"
if [[ $stem == argon_frozen_2d ]]; then
    for side in old new; do
        echo "$side events: $(for k in events ups downs reflections; do /usr/bin/python3 -m terrace_tools.summary get \
            "$work/$side/run.summary.json" energy_stepping/$k; done | tr '\n' ' ')(events, ups, downs, reflections)"
    done
fi
status=0
shopt -s nullglob
csvs=("$work"/old/*.csv); h5s=("$work"/old/*.h5)
[[ ${#csvs[@]} -gt 0 || ${#h5s[@]} -gt 0 ]] || { echo "the runs wrote no CSV or HDF5 file" >&2; exit 1; }
for f in "${csvs[@]}"; do
    if cmp -s "$f" "$work/new/$(basename "$f")"; then echo "$(basename "$f"): identical"
    else echo "$(basename "$f"): DIFFERENT"; status=1; fi
done
for f in "${h5s[@]}"; do     # (the heredoc below is the loop's body)
/usr/bin/python3 - "$f" "$work/new/$(basename "$f")" <<'PY' || status=1
import os, sys, h5py
a, b = h5py.File(sys.argv[1], 'r'), h5py.File(sys.argv[2], 'r')
fname = os.path.basename(sys.argv[1])
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
    print(f'{fname}: DIFFERENT in', len(bad), 'of', len(set(ia) | set(ib)), 'items:', ', '.join(bad[:8]))
    sys.exit(1)
print(f'{fname}: identical ({ndata} datasets, {len(ia) - ndata} attributes, raw bytes)')
PY
done
exit $status
