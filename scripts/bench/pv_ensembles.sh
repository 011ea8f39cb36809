#!/usr/bin/env bash
# physical-validation's ensemble checks (Merz and Shirts 2018) on Rahman's liquid argon (864 atoms,
# the potential of input/argon_nvt.nml): the NPT check for each barostat (c_rescale and mc with a
# CSVR thermostat, mttk with its Nose-Hoover chain) on two pairs of state points, (94.4 K, 1 bar) against (97 K, 1 bar) (the enthalpy's
# distribution) and (94.4 K, 1 bar) against (94.4 K, 31 bar) (the volume's), and the NVT check for
# each thermostat (langevin, csvr, nose_hoover, andersen) at 94.4 K against 97 K at 1.374 g/cm^3.
# Each run equilibrates EQ ps (from fcc, melting) and samples every 0.1 ps for PROD ps. A check
# passes when the estimated temperature (or pressure) ratio lies within 3 standard deviations of the
# true one. physical-validation is installed from PyPI into the project's virtual environment
# ($TERRACE_VENV, default ~/.cache/terrace-venv) on first use; exit 77 when that cannot be done.
# usage: pv_ensembles.sh TERRACE [WORKDIR]     (env: PROD=1000 EQ=50 NP=1 STYLES="c_rescale mc"
#                                                     THERMOSTATS="langevin csvr nose_hoover andersen";
#                                                     STYLES= or THERMOSTATS= set empty: none of them;
#                                                     COUPLE=aniso: the barostats with couple = 'aniso',
#                                                     a WORKDIR of its own, recorded in couple.txt)
set -euo pipefail
terrace=$(readlink -f "$1"); work=${2:-pv_ensembles_work}
PROD=${PROD:-1000}; EQ=${EQ:-50}; NP=${NP:-1}
STYLES=${STYLES-c_rescale mc}; THERMOSTATS=${THERMOSTATS-langevin csvr nose_hoover andersen}
COUPLE=${COUPLE:-iso}
case "$COUPLE" in iso|aniso) ;; *) echo "pv_ensembles.sh: COUPLE=$COUPLE: unknown (allowed: iso, aniso)" >&2; exit 2;; esac
here=$(cd "$(dirname "$0")" && pwd)
venv="${TERRACE_VENV:-$HOME/.cache/terrace-venv}"
if ! "$venv/bin/python" -c 'import physical_validation' > /dev/null 2>&1; then
    [ -x "$venv/bin/pip" ] || /usr/bin/python3 -m venv --system-site-packages "$venv" || { echo "SKIPPED: no venv"; exit 77; }
    timeout 600 "$venv/bin/pip" install --disable-pip-version-check --timeout 20 --retries 1 -q physical-validation \
        || { echo "SKIPPED: physical-validation could not be installed (offline?)"; exit 77; }
fi
mkdir -p "$work"; cd "$work"
if [ -s couple.txt ] && [ "$(cat couple.txt)" != "$COUPLE" ]; then
    echo "pv_ensembles.sh: $work holds COUPLE=$(cat couple.txt) runs (use another WORKDIR for COUPLE=$COUPLE)" >&2; exit 2
fi
echo "$COUPLE" > couple.txt
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
total=$(python3 -c "print($EQ + $PROD)")
run() {   # run NAME SEED THERMOSTAT_LINE BAROSTAT_LINE
    [ -s "$1.csv" ] && [ -s "$1.summary.json" ] && return 0   # a finished run left its summary
    cat > "$1.nml" <<NML
&run units='metal', dimension=3, run_time=$total, seed=$2 /
&system lattice='fcc', lattice_constant=5.780150, cells=6,6,6, periodic=.true.,.true.,.true.,
        mass=39.948, temperature=184.0 /
&potential style='lj', epsilon=0.0103408116, sigma=3.4, cutoff=8.5, shift=.true. /
&integrator style='velocity_verlet', dt=0.01 /
&neighbor skin=1.0 /
&thermostat $3 /
$4
&output thermo_interval=0.1, thermo_file='$1.csv', overwrite=.true. /
NML
    mpirun --oversubscribe -np "$NP" "$terrace" "$1.nml" > "$1.log"
}
for s in $STYLES; do
    ts=csvr
    case $s in
        c_rescale) b="style='c_rescale', damping=2.0, compressibility=5.0e-4" ;;
        mttk) b="style='mttk', damping=2.0"; ts=nose_hoover ;;
        *) b="style='$s'" ;;
    esac
    b="$b, couple='$COUPLE'"
    run "npt_${s}_T94.4_P1" 11 "style='$ts', temperature=94.4, damping=0.5" "&barostat $b, pressure=1.0 /"
    run "npt_${s}_T97_P1" 12 "style='$ts', temperature=97.0, damping=0.5" "&barostat $b, pressure=1.0 /"
    run "npt_${s}_T94.4_P31" 13 "style='$ts', temperature=94.4, damping=0.5" "&barostat $b, pressure=31.0 /"
done
for t in $THERMOSTATS; do
    extra=""; [ "$t" = andersen ] && extra=", zero_momentum=.true."
    run "nvt_${t}_T94.4" 21 "style='$t', temperature=94.4, damping=0.5$extra" ""
    run "nvt_${t}_T97" 22 "style='$t', temperature=97.0, damping=0.5$extra" ""
done
"$venv/bin/python" "$here/pv_ensembles.py" --eq "$EQ" --styles "$STYLES" --thermostats "$THERMOSTATS" .
