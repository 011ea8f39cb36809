#!/usr/bin/env bash
# Energy stepping's reflection warning: a run in which more than half of the events were reflections
# says so in its run log, with the share and the advice (a smaller terrace_height); a run below half does
# not. Both runs put the share into the run summary (energy_stepping/reflection_share).
# The seven-atom 2-D argon cluster (input/argon_frozen_2d.atoms) for 20 ps: at h = 0.004 eV about
# 80 % of its events are reflections, at h = 5e-4 eV well under half.
# Usage: tests/regression/reflection_warning.sh TERRACE_BINARY OUTDIR
set -euo pipefail
[[ $# -eq 2 ]] || { echo "usage: $0 TERRACE_BINARY OUTDIR" >&2; exit 2; }
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
terrace="$(realpath "$1")"; out="$2"
PYTHON="${PYTHON:-/usr/bin/python3}"; [[ -x "$PYTHON" ]] || PYTHON=python3
rm -rf "$out"; mkdir -p "$out"
cp "$repo/input/argon_frozen_2d.atoms" "$out/"
fail=0
run() {  # NAME H: run, leave NAME.log and NAME.summary.json
    cat > "$out/$1.nml" <<DECK
&run units='metal', dimension=2, run_time=20.0, seed=1 /
&system atoms_file='argon_frozen_2d.atoms', periodic=.false.,.false., mass=39.951 /
&potential style='lj', epsilon=0.010323577, sigma=3.41, cutoff=0.0 /
&integrator style='energy_stepping', terrace_height=$2 /
&output thermo_interval=10.0, thermo_file='' /
DECK
    (cd "$out" && timeout 300 "$terrace" "$1.nml" > "$1.log" 2>&1) || { echo "FAIL: $1: terrace failed"; tail -5 "$out/$1.log"; exit 1; }
}
share() { "$PYTHON" -c "import json,sys; print(json.load(open(sys.argv[1]))['energy_stepping']['reflection_share'])" "$out/$1.summary.json"; }

run high 0.004
s=$(share high); w=$(grep -c '^terrace: warning: .* % of the events were reflections' "$out/high.log" || true)
echo "h = 0.004 eV: reflection share $s, warnings: $w"; grep '^terrace: warning: .*reflections' "$out/high.log" || true
"$PYTHON" -c "import sys; sys.exit(0 if float(sys.argv[1]) > 0.5 else 1)" "$s" || { echo "FAIL: share $s is not above one half"; fail=1; }
[[ "$w" == 1 ]] || { echo "FAIL: no reflection warning above one half"; fail=1; }
grep -q 'smaller terrace_height' "$out/high.log" || { echo "FAIL: the warning does not say what to do"; fail=1; }
pct=$("$PYTHON" -c "import sys; print('%.1f' % (100 * float(sys.argv[1])))" "$s")
grep -q "warning: $pct % of the events" "$out/high.log" || { echo "FAIL: the warning does not give the share ($pct %)"; fail=1; }

run low 5e-4
s=$(share low); w=$(grep -c 'of the events were reflections' "$out/low.log" || true)
echo "h = 5e-4 eV: reflection share $s, warnings: $w"
"$PYTHON" -c "import sys; sys.exit(0 if float(sys.argv[1]) < 0.5 else 1)" "$s" || { echo "FAIL: share $s is not below one half"; fail=1; }
[[ "$w" == 0 ]] || { echo "FAIL: a reflection warning below one half"; fail=1; }
[[ $fail == 0 ]] && echo "PASS"
exit $fail
