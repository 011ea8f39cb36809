#!/usr/bin/env bash
# Run a deck on NP ranks, show the closing figures of its run summary, then check its thermo CSV with CHECKER
# (a Python script beside this one: check_conservation.py for velocity Verlet, check_energy_stepping.py
# for energy stepping) and the checker's own options.
# Usage: tests/regression/run_and_check.sh TERRACE_BINARY DECK OUTDIR NP CHECKER [checker arguments...]
#        (the checker gets OUTDIR/thermo.csv first)
set -euo pipefail
[[ $# -ge 5 ]] || { echo "usage: $0 TERRACE_BINARY DECK OUTDIR NP CHECKER [checker arguments]" >&2; exit 2; }
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
terrace="$(realpath "$1")"; deck="$2"; out="$3"; np="$4"; checker="$5"; shift 5
PYTHON="${PYTHON:-/usr/bin/python3}"; [[ -x "$PYTHON" ]] || PYTHON=python3
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
rm -rf "$out"; mkdir -p "$out"
sed "s#@REPO@#$repo#g" "$deck" > "$out/deck.nml"
(cd "$out" && timeout 600 mpirun --oversubscribe -np "$np" "$terrace" deck.nml > terrace.log 2>&1) || {
    echo "FAIL: terrace failed"; tail -5 "$out/terrace.log"; exit 1; }
"$PYTHON" -m terrace_tools.summary show "$out/deck.summary.json" conservation timing/loop_time_s energy_stepping
"$PYTHON" "$here/$checker" "$out/thermo.csv" "$@"
