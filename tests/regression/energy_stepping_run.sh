#!/usr/bin/env bash
# Run an energy-stepping deck on NP ranks and check its thermo with check_energy_stepping.py.
# Usage: tests/regression/energy_stepping_run.sh TERRACE_BINARY DECK OUTDIR NP [checker options...]
set -euo pipefail
[[ $# -ge 4 ]] || { echo "usage: $0 TERRACE_BINARY DECK OUTDIR NP [checker options]" >&2; exit 2; }
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
terrace="$(realpath "$1")"; deck="$2"; out="$3"; np="$4"; shift 4
PYTHON="${PYTHON:-/usr/bin/python3}"; [[ -x "$PYTHON" ]] || PYTHON=python3
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
rm -rf "$out"; mkdir -p "$out"
sed "s#@REPO@#$repo#g" "$deck" > "$out/deck.nml"
(cd "$out" && timeout 600 mpirun --oversubscribe -np "$np" "$terrace" deck.nml > terrace.log 2>&1) || {
    echo "FAIL: terrace failed"; tail -5 "$out/terrace.log"; exit 1; }
grep -E "^(Loop time|Events|Mean event)" "$out/terrace.log" || true
"$PYTHON" "$here/check_energy_stepping.py" "$out/thermo.csv" "$@"
