#!/usr/bin/env bash
# The outer list (&neighbor outer_skin) on a slice of the 100 ns argon job (input/argon_nvt_100ns.nml,
# ARGON_PS ps, default 1000 = 100,000 steps, from the liquid input/argon_nvt.nml leaves): the slice
# with each &neighbor variant of VARIANTS (skin:outer_skin, outer_skin 0 = no outer list; default
# "1.0:0 0.6:2.6", the deck's line before and after), and with OLD_TERRACE (another binary, e.g.
# main's) the first variant once more by it, labelled old. Each round runs every variant once, one
# after the other (alternating); then per variant the median [lowest, highest] of the loop time and of
# the Pair, Neigh and Comm phases (run summaries), the list builds and prunes, and the paired ratio
# of its loop time to the first variant's of the same round. CALLGRIND=1: instead, each variant once
# under callgrind (a -DTERRACE_PORTABLE=ON build: valgrind stops on AVX-512; ARGON_PS default 20),
# the whole process's instruction count and its ratio to the first variant's.
# Usage: [VARIANTS="1.0:0 0.6:2.6 1.0:3.0"] [ARGON_PS=1000] [CALLGRIND=1] scripts/bench/outer_list_ab.sh ROUNDS [TERRACE [OLD_TERRACE]]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
[[ $# -ge 1 && "$1" =~ ^[1-9][0-9]*$ ]] || { echo "usage: $0 ROUNDS [TERRACE [OLD_TERRACE]]" >&2; exit 2; }
rounds=$1; terrace="$(realpath "${2:-$repo/build/terrace}")"; old="${3:-}"
[[ -x "$terrace" ]] || { echo "outer_list_ab: $terrace is not executable" >&2; exit 2; }
[[ -z "$old" || -x "$old" ]] || { echo "outer_list_ab: $old is not executable" >&2; exit 2; }
[[ -n "$old" ]] && old="$(realpath "$old")"
cg="${CALLGRIND:-0}"; ps="${ARGON_PS:-1000}"; [[ $cg == 1 ]] && ps="${ARGON_PS:-20}"; [[ "$ps" =~ ^[1-9][0-9]*$ ]] || { echo "outer_list_ab: ARGON_PS must be a positive integer" >&2; exit 2; }
read -r -a variants <<< "${VARIANTS:-1.0:0 0.6:2.6}"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
cd "$work"
echo "outer list A/B on the argon job, $ps ps; $(date -u '+%Y-%m-%d %H:%M UTC'); commit $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "machine: $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1), $(nproc) cores visible, load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "terrace: $terrace${old:+; old: $old}"
cp "$repo/input/argon_nvt.nml" .
"$terrace" argon_nvt.nml > eq.log 2>&1 || { tail eq.log >&2; exit 1; }      # argon_nvt_eq.atoms
labels=(); bins=(); decks=()
add() {   # label binary skin outer
    local nb="skin=$3"; [[ $4 != 0 ]] && nb="skin=$3, outer_skin=$4"
    sed -e "s/run_time=100000.0/run_time=$ps.0/" -e "s#^&neighbor .*/#\\&neighbor $nb /#" \
        "$repo/input/argon_nvt_100ns.nml" > "$1.nml"
    grep -q "^&neighbor $nb /" "$1.nml" || { echo "outer_list_ab: could not set '$nb'" >&2; exit 1; }
    labels+=("$1"); bins+=("$2")
}
for v in "${variants[@]}"; do add "s${v%%:*}_o${v##*:}" "$terrace" "${v%%:*}" "${v##*:}"; done
[[ -n "$old" ]] && add old "$old" "${variants[0]%%:*}" "${variants[0]##*:}"
if [[ $cg == 1 ]]; then
    first=""
    for k in "${!labels[@]}"; do
        rm -f argon_nvt_100ns.csv argon_nvt_100ns.h5 argon_nvt_100ns.ckpt.h5
        valgrind --tool=callgrind --callgrind-out-file="${labels[$k]}.cg" "${bins[$k]}" "${labels[$k]}.nml" \
            > "${labels[$k]}.log" 2>&1 || { tail "${labels[$k]}.log" >&2; exit 1; }
        ir="$(callgrind_annotate "${labels[$k]}.cg" 2> /dev/null | sed -n 's/^ *\([0-9,]*\) .*PROGRAM TOTALS.*/\1/p' | tr -d ,)"
        first="${first:-$ir}"
        echo "  ${labels[$k]}: $ir instructions, $(/usr/bin/python3 -c "print('%.3f' % ($ir / $first))") of ${labels[0]}'s"
    done
    exit 0
fi
for ((r = 1; r <= rounds; r++)); do
    for k in "${!labels[@]}"; do
        rm -f argon_nvt_100ns.csv argon_nvt_100ns.h5 argon_nvt_100ns.ckpt.h5
        "${bins[$k]}" "${labels[$k]}.nml" > "${labels[$k]}.log" 2>&1 || { tail "${labels[$k]}.log" >&2; exit 1; }
        cp "${labels[$k]}.summary.json" "${labels[$k]}.r$r.json"
    done
done
PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 - "$rounds" "${labels[@]}" <<'EOF'
import statistics
import sys

from terrace_tools import summary

rounds, labels = int(sys.argv[1]), sys.argv[2:]
keys = [('loop', 'timing/loop_time_s'), ('Pair', 'timing/phases/Pair/avg_s'),
        ('Neigh', 'timing/phases/Neigh/avg_s'), ('Comm', 'timing/phases/Comm/avg_s')]
runs = {l: [summary.read(f'{l}.r{r}.json') for r in range(1, rounds + 1)] for l in labels}


def spread(xs):
    return f'{statistics.median(xs):.3f} [{min(xs):.3f}, {max(xs):.3f}]'


print(f'per variant, median [lowest, highest] of {rounds} rounds (seconds):')
for l in labels:
    f = runs[l][0]
    line = '  '.join(f'{n} {spread([summary.get(x, k) for x in runs[l]])}' for n, k in keys)
    ratio = [summary.get(a, 'timing/loop_time_s')/summary.get(b, 'timing/loop_time_s')
             for a, b in zip(runs[l], runs[labels[0]])]
    print(f'  {l:10s} {line}  builds {summary.get(f, "neighbor/builds")} prunes '
          f'{summary.get(f, "neighbor/prunes", 0)}  loop / {labels[0]}: {spread(ratio)}')
EOF
