#!/usr/bin/env bash
# Rahman's liquid argon (864 atoms, LJ eps/k_B = 120 K, sigma = 3.4 A, shifted at 2.5 sigma, the
# potential of input/argon_nvt.nml) at 94.4 K and 1 bar: Terrace's barostats (c_rescale, mc: CSVR
# thermostat; mttk: its Nose-Hoover chain, tau = 0.5 ps, tau_p = 2 ps as LAMMPS's) against LAMMPS's `fix npt` (Nose-Hoover chains, MTTK) on the same scene. Each run
# equilibrates EQ ps from the fcc start (melting), then samples the volume every 0.1 ps for PROD ps.
# Prints the density and the isothermal compressibility kappa_T = <dV^2> / (k T <V>) with standard
# errors from block averages (BLOCKS blocks), and whether each Terrace style lies within 2 combined
# standard errors of LAMMPS.
# Styles (STYLES): c_rescale, mc, mttk (velocity Verlet, 10 fs), mc_es (energy stepping, mean event
# interval about 4 fs, Andersen thermostat with zero_momentum, volume moves every 0.25 ps). A LAMMPS
# log already in WORKDIR is reused (so a later call with STYLES=mc_es and a shorter PROD compares
# with the same reference).
# COUPLE=aniso: every box edge on its own (LAMMPS `fix npt ... aniso`, Terrace `couple = 'aniso'`);
# a WORKDIR holds the runs of one coupling (it records it in couple.txt and refuses the other).
# usage: barostat_npt.sh TERRACE [WORKDIR]   (env: PROD=2000 EQ=100 BLOCKS=20 NP=1 STYLES="c_rescale mc" COUPLE=iso)
set -euo pipefail
terrace=$(readlink -f "$1"); work=${2:-barostat_npt_work}
PROD=${PROD:-2000}; EQ=${EQ:-100}; BLOCKS=${BLOCKS:-20}; NP=${NP:-1}; STYLES=${STYLES:-c_rescale mc}
COUPLE=${COUPLE:-iso}
case "$COUPLE" in iso|aniso) ;; *) echo "barostat_npt.sh: COUPLE=$COUPLE: unknown (allowed: iso, aniso)" >&2; exit 2;; esac
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$work"; cd "$work"
if [ -s couple.txt ] && [ "$(cat couple.txt)" != "$COUPLE" ]; then
    echo "barostat_npt.sh: $work holds COUPLE=$(cat couple.txt) runs (use another WORKDIR for COUPLE=$COUPLE)" >&2; exit 2
fi
echo "$COUPLE" > couple.txt
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
nsteps_eq=$(python3 -c "print(int(round($EQ/0.01)))")
nsteps_prod=$(python3 -c "print(int(round($PROD/0.01)))")

cat > lmp_npt.in <<IN
units metal
atom_style atomic
boundary p p p
lattice fcc 5.780150
region box block 0 6 0 6 0 6
create_box 1 box
create_atoms 1 box
mass 1 39.948
pair_style lj/cut 8.5
pair_coeff 1 1 0.0103408116 3.4
pair_modify shift yes
neighbor 1.0 bin
velocity all create 184.0 1964 dist gaussian mom yes
timestep 0.01
fix 1 all npt temp 94.4 94.4 0.5 $COUPLE 1.0 1.0 2.0
thermo 10
thermo_style custom step temp pe vol press
thermo_modify format float %.10g
run $nsteps_eq
reset_timestep 0
run $nsteps_prod
IN
total=$(python3 -c "print($EQ + $PROD)")
deck() {   # deck NAME BAROSTAT_LINE [INTEGRATOR_LINE THERMOSTAT_LINE]: one run of EQ + PROD ps (the
           # table drops the first EQ ps)
integ=${3:-"style='velocity_verlet', dt=0.01"}
thermo=${4:-"style='csvr', temperature=94.4, damping=0.5"}
cat > "$1.nml" <<NML
&run units='metal', dimension=3, run_time=$total, seed=1964 /
&system lattice='fcc', lattice_constant=5.780150, cells=6,6,6, periodic=.true.,.true.,.true.,
        mass=39.948, temperature=184.0 /
&potential style='lj', epsilon=0.0103408116, sigma=3.4, cutoff=8.5, shift=.true. /
&integrator $integ /
&neighbor skin=1.0 /
&thermostat $thermo /
&barostat $2, couple='$COUPLE' /
&output thermo_interval=0.1, thermo_file='$1.csv', overwrite=.true. /
NML
}
deck c_rescale "style='c_rescale', pressure=1.0, damping=2.0, compressibility=2.0e-4"
deck mc "style='mc', pressure=1.0"
deck mttk "style='mttk', pressure=1.0, damping=2.0" "style='velocity_verlet', dt=0.01" \
    "style='nose_hoover', temperature=94.4, damping=0.5"
deck mc_es "style='mc', pressure=1.0, interval=0.25" "style='energy_stepping', target_mean_dt=0.01" \
    "style='andersen', temperature=94.4, damping=0.5, zero_momentum=.true."
[ -s lmp_npt.log ] || mpirun --oversubscribe -np "$NP" lmp -in lmp_npt.in -log lmp_npt.log > /dev/null
for s in $STYLES; do
    [ -s "$s.csv" ] && [ -s "$s.summary.json" ] || mpirun --oversubscribe -np "$NP" "$terrace" "$s.nml" > "$s.log"
done
PY=${PYTHON:-$HOME/.cache/terrace-venv/bin/python}; [ -x "$PY" ] || PY=python3
"$PY" "$here/barostat_npt_table.py" --blocks "$BLOCKS" --eq "$EQ" .
