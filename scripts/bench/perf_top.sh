#!/usr/bin/env bash
# Where a run's time goes, by function: `perf record` (cpu-clock samples) of one Terrace run of a deck,
# then the share of each function in the samples, highest first (the "perf put X % of the run in Y"
# figures of doc/performance.md). The deck runs in a temporary copy of its directory (its files, not
# its subdirectories), so that its relative paths work and its outputs land there.
# Usage: scripts/bench/perf_top.sh DECK.nml [TERRACE_BINARY] [N_LINES]   (defaults build/terrace, 15)
# Needs perf (Debian: linux-perf) and a kernel that lets this user sample (perf_event_paranoid).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
[[ $# -ge 1 && -f "$1" ]] || { echo "usage: $0 DECK.nml [TERRACE_BINARY] [N_LINES]" >&2; exit 2; }
deck="$(realpath "$1")"; bin="$(realpath "${2:-$repo/build/terrace}")"; lines="${3:-15}"
command -v perf > /dev/null || { echo "perf_top: perf not found (as root: apt-get install -y linux-perf)" >&2; exit 2; }
[[ -x "$bin" ]] || { echo "perf_top: $bin is not an executable (bash scripts/build.sh)" >&2; exit 2; }
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
find "$(dirname "$deck")" -maxdepth 1 -type f -exec cp {} "$work"/ \;
cd "$work"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
echo "deck    : $deck"
echo "binary  : $bin"
echo "machine : $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1), $(date -u '+%Y-%m-%d %H:%M UTC')"
perf record -q -e cpu-clock -o perf.data "$bin" "$(basename "$deck")" > run.log 2>&1 \
    || { echo "perf_top: the run failed:" >&2; tail -5 run.log >&2; exit 1; }
# the loop time and the phases from the deck's run summary (its default name, beside the deck)
PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary show \
    "$(basename "$deck" .nml).summary.json" timing/loop_time_s timing/phases || true
perf report -i perf.data --stdio --no-children --sort symbol 2> /dev/null | grep -E '^ +[0-9]' | head -n "$lines"
