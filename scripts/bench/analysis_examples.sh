#!/usr/bin/env bash
# The examples of doc/analysis.md: runs Terrace and terrace-analyze and prints the figures compared
# with published values; writes the doc figures (doc/figures/analysis_*.png) with
# scripts/bench/analysis_figures.py.
#   1. fcc Cu, Foiles' EAM (Cu_u3.eam), 4000 atoms, 600 K start (~300 K), 4 ps to equilibrate, then
#      20 ps of velocity Verlet at 2 fs with velocities every 10 fs -> VDOS (5 ps correlation, Hann).
#   2. Rahman's liquid argon (input/argon_liquid.nml: 864 atoms, 1.374 g/cm^3): 30 ps to melt and
#      settle at ~95 K, then 200 ps at 10 fs with positions, velocities and images every 50 fs
#      -> g(r), S(q), MSD/D (5 blocks of 40 ps), VACF/VDOS.
# usage: bash scripts/bench/analysis_examples.sh [BUILD_DIR] [WORK_DIR] [NP]     (~5 min on 2 vCPUs)
set -euo pipefail
here=$(cd "$(dirname "$0")/../.." && pwd)
build=$(readlink -f "${1:-$here/build}")
work=${2:-/tmp/terrace_analysis_examples}
np=${3:-2}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
analyze=(mpirun --oversubscribe -np "$np" "$build/terrace-analyze")
mkdir -p "$work/cu" "$work/argon"

cd "$work/cu"
sed -e "s/run_time=20.0/run_time=4.0/" -e "s|thermo_file='cu_eam.csv'|thermo_file='eq.csv', final_atoms_file='cu4000_eq.atoms'|" \
    "$here/input/cu_eam.nml" > eq.nml
cat > prod.nml <<'NML'
&run units='metal', dimension=3, run_time=20.0, seed=2021 /
&system atoms_file='cu4000_eq.atoms', box_lo=0,0,0, box_hi=36.15,36.15,36.15, periodic=.true.,.true.,.true.,
        mass=63.55 /
&potential style='eam', file='/usr/share/lammps/potentials/Cu_u3.eam' /
&integrator style='velocity_verlet', dt=0.002 /
&neighbor skin=1.0 /
&output thermo_interval=0.2, thermo_file='prod.csv', trajectory_file='prod.h5',
        trajectory_interval=0.01, trajectory_fields='velocity', overwrite=.true. /
NML
"$build/terrace" eq.nml > eq.log
"$build/terrace" prod.nml > prod.log
"${analyze[@]}" --trajectory_file=prod.h5 --compute=vdos --correlation_time=5.0 --output_prefix=cu | tee analyze.log

cd "$work/argon"
sed -e "s|thermo_file='argon_liquid.csv'|thermo_file='eq.csv'|" "$here/input/argon_liquid.nml" > eq.nml
cat > prod.nml <<'NML'
&run units='metal', dimension=3, run_time=200.0, seed=1964 /
&system atoms_file='argon_liquid_eq.atoms', box_lo=0.0,0.0,0.0, box_hi=34.6809019,34.6809019,34.6809019,
        periodic=.true.,.true.,.true., mass=39.948 /
&potential style='lj', epsilon=0.0103408116, sigma=3.4, cutoff=8.5, shift=.true. /
&integrator style='velocity_verlet', dt=0.01 /
&neighbor skin=1.0 /
&output thermo_interval=1.0, thermo_file='prod.csv', trajectory_file='prod.h5',
        trajectory_interval=0.05, trajectory_fields='position velocity image', overwrite=.true. /
NML
"$build/terrace" eq.nml > eq.log
"$build/terrace" prod.nml > prod.log
"${analyze[@]}" --trajectory_file=prod.h5 --compute=rdf,sq,msd,vdos --output_prefix=argon --rdf_every=10 \
    --sq_every=40 --sq_bin_width=0.05 --correlation_time=5 | tee analyze.log

PYTHONPATH="$here/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 "$here/scripts/bench/analysis_figures.py" "$work" "$here/doc/figures"
