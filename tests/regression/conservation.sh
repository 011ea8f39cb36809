#!/usr/bin/env bash
# Conservation under velocity Verlet: run DECK on NP ranks, then check total momentum stays at its
# initial value to round-off and report the energy drift (check_conservation.py).
# Usage: tests/regression/conservation.sh TERRACE_BINARY DECK OUTDIR NP NATOMS P_TOL E_TOL
set -euo pipefail
[[ $# -eq 7 ]] || { echo "usage: $0 TERRACE_BINARY DECK OUTDIR NP NATOMS P_TOL E_TOL" >&2; exit 2; }
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
terrace="$(realpath "$1")"; out="$3"
PYTHON="${PYTHON:-/usr/bin/python3}"; [[ -x "$PYTHON" ]] || PYTHON=python3
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
rm -rf "$out"; mkdir -p "$out"
sed "s#@REPO@#$repo#g" "$2" > "$out/deck.nml"
(cd "$out" && timeout 300 mpirun --oversubscribe -np "$4" "$terrace" deck.nml > terrace.log 2>&1) || {
    echo "FAIL: terrace failed"; tail -5 "$out/terrace.log"; exit 1; }
grep -E "Energy drift" "$out/terrace.log" || true
"$PYTHON" "$here/check_conservation.py" "$out/thermo.csv" "$5" --p-tol "$6" --e-tol "$7"
