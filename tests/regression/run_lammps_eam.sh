#!/usr/bin/env bash
# Terrace vs LAMMPS regression for the EAM potentials, one of three scenes:
#
#   cu    4000-atom hot fcc Cu, Foiles' Cu_u3.eam (funcfl, pair_style eam); reference dt 0.005 ps
#         (lammps/in.eam_cu_make: fcc a = 3.615 A, 10^3 cells, velocities at 1600 K, 300 NVE steps)
#   cuni  4000-atom random 50/50 Cu-Ni alloy, CuNi.eam.alloy (setfl, pair_style eam/alloy,
#         elements Cu Ni); reference dt 0.002 ps (lammps/in.eam_cuni_make: fcc a = 3.56 A, 10^3
#         cells, set type/fraction with a fixed seed, velocities at 2000 K, 300 NVE steps)
#   fe    4394-atom hot bcc Fe, Fe_mm.eam.fs (Finnis-Sinclair, pair_style eam/fs, element Fe);
#         reference dt 0.002 ps (lammps/in.eam_fe_make: bcc a = 2.8665 A, 13^3 cells, velocities
#         at 2000 K, 300 NVE steps)
#
# Usage: tests/regression/run_lammps_eam.sh TERRACE_BINARY OUTPUT_DIR [cu|cuni|fe]   (default cu)
#
#   1. builds the system with LAMMPS (lammps/in.eam_SCENE_make -> SCENE.data)
#   2. runs the LAMMPS reference   (lammps/in.eam_SCENE_ref -> lammps_ref.log,
#      lammps_forces0.dump; 100 steps)
#   3. writes terrace_SCENE_eam.nml and runs Terrace on the same data file
#      (-> thermo.csv, forces0.txt)
#   4. compares with scripts/compare_lammps.py (step 0 pe/press/forces to
#      1e-10, step 100 thermo to 1e-8)
#
# Environment (optional):
#   LMP               LAMMPS executable (default: lmp)
#   EAM_POTENTIAL     the potential file (default: the scene's file in /usr/share/lammps/potentials,
#                     Debian package lammps-data)
#   PYTHON            Python interpreter (default: /usr/bin/python3 or python3)
#   TERRACE_LAUNCHER  prefix for the Terrace command, e.g. "mpirun -np 4"
#   COMPARE_ARGS      extra arguments for compare_lammps.py (e.g. tolerances)
#
# Exit status: 0 pass, 77 skipped (LAMMPS or the potential file unavailable), anything else failure.
set -euo pipefail

if [[ $# -lt 2 || $# -gt 3 ]]; then
    echo "usage: $0 TERRACE_BINARY OUTPUT_DIR [cu|cuni|fe]" >&2
    exit 2
fi

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
lmpdir="$here/lammps"
compare="$repo/scripts/compare_lammps.py"

terrace="$1"
outdir="$2"
scene="${3:-cu}"

# scene: default potential file, Terrace style and elements line, time step (ps)
case "$scene" in
    cu)   default_potential=Cu_u3.eam;      style=eam;       elements='';                  dt=0.005 ;;
    cuni) default_potential=CuNi.eam.alloy; style=eam/alloy; elements=", elements='Cu','Ni'"; dt=0.002 ;;
    fe)   default_potential=Fe_mm.eam.fs;   style=eam/fs;    elements=", elements='Fe'";       dt=0.002 ;;
    *)    echo "usage: $0 TERRACE_BINARY OUTPUT_DIR [cu|cuni|fe]  (unknown scene '$scene')" >&2
          exit 2 ;;
esac
data="$scene.data"
nml="terrace_${scene}_eam.nml"

LMP="${LMP:-lmp}"
EAM_POTENTIAL="${EAM_POTENTIAL:-/usr/share/lammps/potentials/$default_potential}"
if [[ -z "${PYTHON:-}" ]]; then
    if [[ -x /usr/bin/python3 ]]; then PYTHON=/usr/bin/python3; else PYTHON=python3; fi
fi

# ---- (a) LAMMPS and the potential file available? ----------------------------
apt_install() {   # apt_install PACKAGE: 0 when installed
    [[ "$(id -u)" -eq 0 ]] && command -v apt-get >/dev/null 2>&1 || return 1
    echo "run_lammps_eam: installing Debian package '$1'"
    DEBIAN_FRONTEND=noninteractive apt-get install -y "$1" \
        || { apt-get update && DEBIAN_FRONTEND=noninteractive apt-get install -y "$1"; }
}
if ! command -v "$LMP" >/dev/null 2>&1; then
    if ! apt_install lammps || ! command -v lmp >/dev/null 2>&1; then
        echo "SKIP: LAMMPS executable '$LMP' not found." >&2
        echo "      Install the Debian package 'lammps':  sudo apt-get install -y lammps" >&2
        exit 77
    fi
    LMP=lmp
fi
if [[ ! -r "$EAM_POTENTIAL" ]]; then
    if [[ "$EAM_POTENTIAL" != /usr/share/lammps/potentials/* ]] || ! apt_install lammps-data \
       || [[ ! -r "$EAM_POTENTIAL" ]]; then
        echo "SKIP: EAM potential file '$EAM_POTENTIAL' not found." >&2
        echo "      Install the Debian package 'lammps-data' or set EAM_POTENTIAL" >&2
        exit 77
    fi
fi
EAM_POTENTIAL="$(cd "$(dirname "$EAM_POTENTIAL")" && pwd)/$(basename "$EAM_POTENTIAL")"

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
      thermo.csv forces0.txt terrace.log "$nml"

export OMP_NUM_THREADS=1

# ---- (b) LAMMPS: build the system, then the reference ------------------------
echo "== LAMMPS ($scene): building $data ($EAM_POTENTIAL)"
if ! "$LMP" -screen none -log lammps_make.log -var data "$data" -var potential "$EAM_POTENTIAL" \
        -in "$lmpdir/in.eam_${scene}_make"; then
    echo "FAIL: LAMMPS in.eam_${scene}_make failed; see $outdir/lammps_make.log" >&2
    tail -n 20 lammps_make.log >&2 || true
    exit 1
fi
echo "== LAMMPS: reference run"
if ! "$LMP" -screen none -log lammps_ref.log -var data "$data" -var potential "$EAM_POTENTIAL" \
        -var forces lammps_forces0.dump -var nsteps 100 -in "$lmpdir/in.eam_${scene}_ref"; then
    echo "FAIL: LAMMPS in.eam_${scene}_ref failed; see $outdir/lammps_ref.log" >&2
    tail -n 20 lammps_ref.log >&2 || true
    exit 1
fi

# ---- (c) Terrace on the same scene ------------------------------------------
cat > "$nml" <<NML
&run units='metal', dimension=3, n_steps=100, seed=1 /
&system read_data='$data' /
&potential style='$style', file='$EAM_POTENTIAL'$elements /
&integrator style='velocity_verlet', dt=$dt /
&neighbor skin=1.0 /
&output thermo_every=100, thermo_file='thermo.csv', forces_file='forces0.txt' /
NML

echo "== Terrace: ${TERRACE_LAUNCHER:+$TERRACE_LAUNCHER }$terrace $nml"
# shellcheck disable=SC2086  # TERRACE_LAUNCHER is deliberately word-split
if ! ${TERRACE_LAUNCHER:-} "$terrace" "$nml" > terrace.log 2>&1; then
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
