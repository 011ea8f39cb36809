#!/usr/bin/env bash
# Terrace vs LAMMPS regression: 4000-atom LJ liquid (lj/cut 2.5, unshifted), or (LJ_SCENE=lj_ka)
# the 4000-atom Kob-Andersen mixture (two types, a cutoff per type pair).
#
# Usage: tests/regression/run_lammps_compare.sh TERRACE_BINARY OUTPUT_DIR
#
#   1. builds the liquid with LAMMPS (lammps/in.lj_liquid_make -> liquid.data)
#   2. runs the LAMMPS reference   (lammps/in.lj_liquid_ref -> lammps_ref.log,
#      lammps_forces0.dump)
#   3. writes terrace_lj_liquid.nml and runs Terrace on the same data file
#      (-> thermo.csv, forces0.txt)
#   4. compares with scripts/compare_lammps.py (step 0 pe/press/forces to
#      1e-10, step 100 thermo to 1e-8)
#
# Environment (optional):
#   LMP               LAMMPS executable (default: lmp)
#   PYTHON            Python interpreter (default: /usr/bin/python3 or python3)
#   TERRACE_LAUNCHER  prefix for the Terrace command, e.g. "mpirun -np 4"
#   COMPARE_ARGS      extra arguments for compare_lammps.py (e.g. tolerances)
#   LJ_SCENE          lj_liquid (default: the one-type liquid) or lj_ka (the 4000-atom Kob-Andersen
#                     mixture of lammps/in.lj_ka_make: two types, a cutoff per type pair)
#
# Exit status: 0 pass, 77 skipped (LAMMPS unavailable), anything else failure.
set -euo pipefail

if [[ $# -ne 2 ]]; then
    echo "usage: $0 TERRACE_BINARY OUTPUT_DIR" >&2
    exit 2
fi

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
lmpdir="$here/lammps"
compare="$repo/scripts/compare_lammps.py"

terrace="$1"
outdir="$2"
scene="${LJ_SCENE:-lj_liquid}"
case "$scene" in
    lj_liquid) data=liquid.data
               potential="&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.false. /" ;;
    lj_ka)     data=ka.data
               potential="&potential style='lj', epsilon(1,1)=1.0, sigma(1,1)=1.0, epsilon(2,2)=0.5, sigma(2,2)=0.88, epsilon(1,2)=1.5, sigma(1,2)=0.8, cutoff=2.5, pair_cutoff(1,2)=2.0, pair_cutoff(2,2)=2.2, shift=.false. /" ;;
    *) echo "run_lammps_compare: unknown LJ_SCENE '$scene' (allowed: lj_liquid, lj_ka)" >&2; exit 2 ;;
esac

LMP="${LMP:-lmp}"
if [[ -z "${PYTHON:-}" ]]; then
    if [[ -x /usr/bin/python3 ]]; then PYTHON=/usr/bin/python3; else PYTHON=python3; fi
fi

# ---- (a) LAMMPS available? -------------------------------------------------
if ! command -v "$LMP" >/dev/null 2>&1; then
    if [[ "$(id -u)" -eq 0 ]] && command -v apt-get >/dev/null 2>&1; then
        echo "run_lammps_compare: '$LMP' not found; installing Debian package 'lammps'"
        if ! { DEBIAN_FRONTEND=noninteractive apt-get install -y lammps \
               || { apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y lammps; }; }; then
            echo "SKIP: could not install Debian package 'lammps' (apt-get install -y lammps failed)" >&2
            exit 77
        fi
        LMP=lmp
        if ! command -v "$LMP" >/dev/null 2>&1; then
            echo "SKIP: package 'lammps' installed but 'lmp' still not on PATH" >&2
            exit 77
        fi
    else
        echo "SKIP: LAMMPS executable '$LMP' not found." >&2
        echo "      Install the Debian package 'lammps':  sudo apt-get install -y lammps" >&2
        exit 77
    fi
fi

# ---- Terrace binary ---------------------------------------------------------
if [[ "$terrace" != */* ]] && command -v "$terrace" >/dev/null 2>&1; then
    terrace="$(command -v "$terrace")"
fi
if [[ ! -x "$terrace" ]]; then
    echo "FAIL: Terrace binary '$terrace' not found or not executable" >&2
    exit 1
fi
terrace="$(cd "$(dirname "$terrace")" && pwd)/$(basename "$terrace")"

mkdir -p "$outdir"
outdir="$(cd "$outdir" && pwd)"
cd "$outdir"
rm -f "$data" lammps_make.log lammps_ref.log lammps_forces0.dump \
      thermo.csv forces0.txt terrace.log terrace_lj_liquid.nml

export OMP_NUM_THREADS=1

# ---- (b) LAMMPS: build the liquid, then the reference ------------------------
echo "== LAMMPS: building $data"
if ! "$LMP" -screen none -log lammps_make.log -var data "$data" \
        -in "$lmpdir/in.${scene}_make"; then
    echo "FAIL: LAMMPS in.${scene}_make failed; see $outdir/lammps_make.log" >&2
    tail -n 20 lammps_make.log >&2 || true
    exit 1
fi
echo "== LAMMPS: reference run"
if ! "$LMP" -screen none -log lammps_ref.log -var data "$data" \
        -var forces lammps_forces0.dump -var nsteps 100 \
        -in "$lmpdir/in.${scene}_ref"; then
    echo "FAIL: LAMMPS in.${scene}_ref failed; see $outdir/lammps_ref.log" >&2
    tail -n 20 lammps_ref.log >&2 || true
    exit 1
fi

# ---- (c) Terrace on the same scene ------------------------------------------
cat > terrace_lj_liquid.nml <<EOF
&run units='lj', dimension=3, n_steps=100, seed=1 /
&system read_data='$data' /
$potential
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&output thermo_every=100, thermo_file='thermo.csv', forces_file='forces0.txt' /
EOF

echo "== Terrace: ${TERRACE_LAUNCHER:+$TERRACE_LAUNCHER }$terrace terrace_lj_liquid.nml"
# shellcheck disable=SC2086  # TERRACE_LAUNCHER is deliberately word-split
if ! ${TERRACE_LAUNCHER:-} "$terrace" terrace_lj_liquid.nml > terrace.log 2>&1; then
    echo "FAIL: Terrace run failed; last lines of $outdir/terrace.log:" >&2
    tail -n 20 terrace.log >&2 || true
    exit 1
fi
for f in thermo.csv forces0.txt; do
    if [[ ! -s "$f" ]]; then
        echo "FAIL: Terrace did not write $outdir/$f" >&2
        exit 1
    fi
done

# ---- (d) compare ---------------------------------------------------------------
echo "== compare_lammps.py"
# shellcheck disable=SC2086  # COMPARE_ARGS is deliberately word-split
"$PYTHON" "$compare" lammps \
    --lammps-log lammps_ref.log --lammps-forces lammps_forces0.dump \
    --terrace-thermo thermo.csv --terrace-forces forces0.txt \
    --step 100 ${COMPARE_ARGS:-}
