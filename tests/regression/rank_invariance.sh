#!/usr/bin/env bash
# Rank-count invariance: the same deck on 1 rank and on each of NPROCS ranks must give the same
# thermo (every column but the cost statistic evals_per_event, every sampled step) to --tol relative
# (1e-10 by default).
#
# Usage: tests/regression/rank_invariance.sh TERRACE_BINARY DECK OUTPUT_DIR [NPROCS...]
#        (default NPROCS: 2 3 4 8; oversubscribed, as this is a correctness test)
set -euo pipefail
[[ $# -ge 3 ]] || { echo "usage: $0 TERRACE_BINARY DECK OUTPUT_DIR [NPROCS...]" >&2; exit 2; }
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
terrace="$(realpath "$1")"; deck="$(realpath "$2")"; out="$3"; shift 3
nprocs=("$@"); [[ ${#nprocs[@]} -gt 0 ]] || nprocs=(2 3 4 8)
PYTHON="${PYTHON:-/usr/bin/python3}"; [[ -x "$PYTHON" ]] || PYTHON=python3
TOL="${TOL:-1e-10}"   # ATOL (default 1e-9): absolute slack for columns that are ~0 (momenta)
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMPI_MCA_rmaps_base_oversubscribe=1
rm -rf "$out"; mkdir -p "$out"
# decks may name repository files as @REPO@/...
sed "s#@REPO@#$repo#g" "$deck" > "$out/deck.nml"; name="$(basename "$deck")"; deck="$(realpath "$out/deck.nml")"
run() {  # run NP DIR
    mkdir -p "$2"
    (cd "$2" && timeout 300 mpirun --oversubscribe -np "$1" "$terrace" "$deck" > terrace.log 2>&1) || {
        echo "FAIL: terrace on $1 rank(s) failed:"; tail -5 "$2/terrace.log"; exit 1; }
}
run 1 "$out/np1"
status=0
for np in "${nprocs[@]}"; do
    run "$np" "$out/np$np"
    if "$PYTHON" "$repo/scripts/compare_lammps.py" terrace "$out/np1/thermo.csv" "$out/np$np/thermo.csv" \
        --tol "$TOL" --atol "${ATOL:-1e-9}" --ignore evals_per_event > "$out/compare_np$np.txt" 2>&1; then
        echo "ok   $name: 1 vs $np ranks agree to $TOL"
    else
        echo "FAIL $name: 1 vs $np ranks differ:"; cat "$out/compare_np$np.txt"; status=1
    fi
done
exit $status
