#!/usr/bin/env bash
# Where energy stepping's event search spends its ray evaluations: a copy of the working tree's
# sources with counters added (scripts/bench/solver/search_probe.py; the repository is not touched),
# built (Release, native), runs a deck and prints three tables: evaluations per search by the kick
# before it, how far the first evaluation lands from the level, and the solver's predicted error of
# the next Taylor root against the error found there.
# Usage: scripts/bench/es_search_probe.sh [DECK.nml [KEY=VALUE]]
#   default deck input/argon_frozen_2d.nml with run_time=10000.0 (10 ns); KEY=VALUE replaces the
#   deck's run length (n_steps=... or run_time=...). Environment: ES_PROBE_ACCEPT (default 0.1): the
#   fraction of the tolerance below which the solver returns the next root unevaluated.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
deck="$(realpath "${1:-$repo/input/argon_frozen_2d.nml}")"; length="${2:-run_time=10000.0}"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
(cd "$repo" && git ls-files -z | tar --null -T - -cf - | tar -xf - -C "$work")
/usr/bin/python3 "$here/solver/search_probe.py" patch "$work"
cmake -S "$work" -B "$work/build" -DCMAKE_BUILD_TYPE=Release -DTERRACE_TESTS=OFF > "$work/configure.log" 2>&1 ||
    { tail -20 "$work/configure.log" >&2; exit 1; }
cmake --build "$work/build" -j "$(nproc)" --target terrace > "$work/build.log" 2>&1 || { grep -B2 -A6 -i error "$work/build.log" | head -40 >&2; exit 1; }
mkdir "$work/run"
find "$(dirname "$deck")" -maxdepth 1 -type f -exec cp {} "$work/run"/ \;
key="${length%%=*}"
sed -E "s/\b(n_steps|run_time)\s*=\s*[0-9.eE+-]+/$length/" "$deck" > "$work/run/probe.nml"
grep -q "$key=" "$work/run/probe.nml" || { echo "es_search_probe: no run length in $deck" >&2; exit 2; }
echo "deck: $deck ($length); commit $(git -C "$repo" rev-parse --short HEAD)$(git -C "$repo" diff --quiet HEAD -- src || echo ' + changes'); $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1); $(date -u '+%Y-%m-%d %H:%M UTC')"
(cd "$work/run" && ES_PROBE_OUT="$work/probe.txt" OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 \
    "$work/build/terrace" probe.nml > run.log 2>&1) || { tail -5 "$work/run/run.log" >&2; exit 1; }
figure() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get "$work/run/probe.summary.json" "energy_stepping/$1"; }
echo "events $(figure events) ($(figure reflections) reflections); ray evaluations per event $(figure ray_evaluations_per_event), verification misses $(figure verification_misses)"
/usr/bin/python3 "$here/solver/search_probe.py" report "$work/probe.txt"
