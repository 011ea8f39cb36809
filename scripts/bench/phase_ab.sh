#!/usr/bin/env bash
# Phase-by-phase A/B of Terrace binaries on one deck: each round runs every binary once, one after
# the other (alternating, so that a load that drifts weighs on all of them), ROUNDS rounds; then,
# per binary, the lowest and the median of each phase of the run summary (Pair, Neigh, Comm, Other,
# Search) and of the loop time, and the ratio of each binary's median to the first one's. For a
# change that moves one phase by a few per cent, which the loop time of a shared machine hides.
# Where the runs differ in their step or event count (energy stepping: a change of round-off gives
# another trajectory, with other events in the same simulated time), the times are per step or
# event (microseconds) instead of per run.
#
# Usage: scripts/bench/phase_ab.sh ROUNDS DECK.nml BINARY_A BINARY_B [BINARY...]
#        e.g. scripts/bench/phase_ab.sh 7 input/lj_bench.nml /tmp/terrace_before build/terrace
# The deck runs in a temporary directory holding a copy of the files of the deck's directory (not
# its subdirectories), so that its relative paths work and its outputs land in the copy (removed
# after each run: decks that write a trajectory need no overwrite).
set -euo pipefail
[[ $# -ge 4 && "$1" =~ ^[1-9][0-9]*$ ]] || { echo "usage: $0 ROUNDS DECK.nml BINARY_A BINARY_B [BINARY...]" >&2; exit 2; }
rounds=$1; deck="$(realpath "$2")"; shift 2
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bins=(); for b in "$@"; do [[ -x "$b" ]] || { echo "phase_ab: $b is not an executable" >&2; exit 2; }; bins+=("$(realpath "$b")"); done
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
find "$(dirname "$deck")" -maxdepth 1 -type f -exec cp {} "$work"/ \;
cd "$work"
inputs="$(ls -A | LC_ALL=C sort)"
echo "deck    : $deck"
echo "machine : $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1), $(nproc) cores visible"
echo "date    : $(date -u '+%Y-%m-%d %H:%M UTC'); load $(cut -d' ' -f1-3 /proc/loadavg) at start"
for k in "${!bins[@]}"; do echo "binary $k: ${bins[$k]}"; done
summary="$(basename "$deck" .nml).summary.json"     # the deck's run summary (its default name)
for ((r = 1; r <= rounds; r++)); do
    for k in "${!bins[@]}"; do
        rm -f "$summary"
        "${bins[$k]}" "$(basename "$deck")" > run.log 2>&1 || { echo "phase_ab: binary $k failed:" >&2; tail -5 run.log >&2; exit 1; }
        mv "$summary" "run_${r}_$k.summary.json"
        # the run's outputs removed, so that the next run of a deck that writes them does not find them
        LC_ALL=C comm -13 <(printf '%s\n' "$inputs") <(ls -A | LC_ALL=C sort) | grep -v -e '^run_.*\.summary\.json$' -e '^run\.log$' |
            while IFS= read -r f; do rm -rf -- "$f"; done
    done
done
PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" python3 - "$rounds" "${#bins[@]}" <<'PY'
import sys, statistics as st
from terrace_tools import summary
rounds, nbins = int(sys.argv[1]), int(sys.argv[2])
t = {}
counts = {}
unit = 'step'
for r in range(1, rounds + 1):
    for k in range(nbins):
        s = summary.read('run_%d_%d.summary.json' % (r, k))
        timing = s['timing']
        t.setdefault('Loop', {}).setdefault(k, []).append(timing['loop_time_s'])
        for phase in ('Pair', 'Neigh', 'Comm', 'Other', 'Search'):
            if phase in timing['phases']:
                t.setdefault(phase, {}).setdefault(k, []).append(timing['phases'][phase]['avg_s'])
        unit = 'step' if 'steps' in timing else 'event'
        counts.setdefault(k, []).append(timing.get('steps', timing.get('events')))
what = 'seconds'
if len({c for v in counts.values() for c in v}) > 1:
    # energy stepping: a change of round-off gives another trajectory, with another number of events
    # in the same simulated time: compare per event (per step) instead of per run
    for phase in t:
        for k in t[phase]:
            t[phase][k] = [1e6 * x / n for x, n in zip(t[phase][k], counts[k])]
    what = 'microseconds per %s (the runs differ in %ss: %s)' % (
        unit, unit, ', '.join('binary %d %d-%d' % (k, min(v), max(v)) for k, v in sorted(counts.items())))
print('%d rounds; %s, lowest / median; "vs 0": median over binary 0\'s' % (rounds, what))
print('%-7s %s' % ('phase', '  '.join('%-26s' % ('binary %d' % k) for k in sorted(t['Loop']))))
for phase in ('Pair', 'Neigh', 'Comm', 'Search', 'Other', 'Loop'):
    if phase not in t:
        continue
    cells = []
    for k in sorted(t[phase]):
        v = t[phase][k]
        ratio = st.median(v) / st.median(t[phase][0]) if k and st.median(t[phase][0]) > 0 else None
        cells.append('%8.4f / %8.4f%s' % (min(v), st.median(v), ('  vs 0 %.3f' % ratio) if ratio else ''))
    print('%-7s %s' % (phase, '  '.join('%-26s' % c for c in cells)))
PY
