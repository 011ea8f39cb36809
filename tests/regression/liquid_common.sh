# Sourced by the regression scripts that run the 2048-atom liquid deck (decks/liquid_2048.nml) in
# variants: neighbor_schedule.sh, verlet_buffer.sh. Takes their arguments (TERRACE_BINARY
# OUTPUT_DIR), sets here, repo, terrace, out and PYTHON, empties OUTPUT_DIR and works in it, and
# defines
#   run NAME NP          terrace on NAME.nml (NP ranks; 1: the binary alone) into NAME.log, or FAIL
#   compare A B WHAT     A.csv and B.csv the same thermo to 1e-10 (scripts/compare_lammps.py), or FAIL
set -euo pipefail
[[ $# -eq 2 ]] || { echo "usage: $0 TERRACE_BINARY OUTPUT_DIR" >&2; exit 2; }
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
terrace="$(realpath "$1")"; out="$2"
PYTHON="${PYTHON:-/usr/bin/python3}"; [[ -x "$PYTHON" ]] || PYTHON=python3
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
rm -rf "$out"; mkdir -p "$out"; cd "$out"
run() {    # name np
    if [[ $2 == 1 ]]; then timeout 300 "$terrace" "$1.nml" > "$1.log" 2>&1
    else timeout 300 mpirun --oversubscribe -np "$2" "$terrace" "$1.nml" > "$1.log" 2>&1; fi || {
        echo "FAIL: terrace failed on $1 ($2 ranks)"; tail -5 "$1.log"; exit 1; }
}
compare() {  # a b what
    if "$PYTHON" "$repo/scripts/compare_lammps.py" terrace "$1.csv" "$2.csv" --tol 1e-10 --atol 1e-9 > "cmp_$1_$2.txt" 2>&1; then
        echo "ok   $3"
    else
        echo "FAIL $3:"; cat "cmp_$1_$2.txt"; exit 1
    fi
}
