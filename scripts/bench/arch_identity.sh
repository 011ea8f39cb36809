#!/usr/bin/env bash
# Bitwise identity of two builds on a fixed set of runs (issue 11: no behaviour change):
# LJ liquid with velocity Verlet (1000 steps), Rahman argon with energy stepping (2000 events, from
# a Verlet-equilibrated state), Cu EAM with velocity Verlet and with energy stepping, a free
# seven-atom cluster (all-pairs path, energy stepping), on 1 and 4 ranks. Prints one line per run
# and exits non-zero if any thermo file differs by a single byte.
# Usage: scripts/bench/arch_identity.sh OLD_TERRACE NEW_TERRACE [WORKDIR]
set -euo pipefail
old="$(realpath "$1")"; new="$(realpath "$2")"
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
work="${3:-$(mktemp -d)}"; mkdir -p "$work"; cd "$work"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
eam="/usr/share/lammps/potentials/Cu_u3.eam"
cat > lj_vv.nml <<NML
&run units='lj', dimension=3, n_steps=1000, seed=87287 /
&system lattice='fcc', density=0.8442, cells=8,8,8, periodic=.true.,.true.,.true., mass=1.0, temperature=1.44 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&output thermo_every=50, thermo_file='thermo.csv' /
NML
sed -e 's/run_time=30.0/run_time=2.0/' -e "s/thermo_file='argon_liquid.csv'/thermo_file='eq.csv'/" \
    "$repo/input/argon_liquid.nml" > rahman_eq.nml
sed -e 's/run_time=10.0/n_steps=2000/' -e "s/thermo_interval=1.0/thermo_every=100/" \
    -e "s/thermo_file='argon_liquid_es.csv'/thermo_file='thermo.csv'/" "$repo/input/argon_liquid_es.nml" > rahman_es.nml
cat > cu_vv.nml <<NML
&run units='metal', dimension=3, n_steps=200, seed=2021 /
&system lattice='fcc', lattice_constant=3.615, cells=6,6,6, periodic=.true.,.true.,.true., temperature=600.0 /
&potential style='eam', file='$eam' /
&integrator style='velocity_verlet', dt=0.002 /
&neighbor skin=1.0 /
&output thermo_every=20, thermo_file='thermo.csv' /
NML
sed -e 's/run_time=5.0/n_steps=1000/' -e 's/thermo_interval=0.05/thermo_every=100/' \
    -e "s/thermo_file='cu_eam_es.csv'/thermo_file='thermo.csv'/" "$repo/input/cu_eam_es.nml" > cu_es.nml
cat > cluster_es.nml <<NML
&run units='metal', dimension=2, run_time=2.0e4, seed=1 /
&system atoms_file='$repo/input/argon_frozen_2d.atoms', periodic=.false.,.false., mass=39.951 /
&potential style='lj', epsilon=0.010323577, sigma=3.41, cutoff=0.0 /
&integrator style='energy_stepping', terrace_height=1.378775e-3 /
&output thermo_interval=100.0, thermo_file='thermo.csv' /
NML
run() {   # build np deck dir
  local exe=$1 np=$2 deck=$3 dir=$4
  rm -rf "$dir"; mkdir -p "$dir"; cp "$deck" "$dir/"
  [[ -f eq.atoms ]] && cp eq.atoms "$dir/argon_liquid_eq.atoms"
  (cd "$dir" && if [[ $np == 1 ]]; then "$exe" "$(basename "$deck")"; else mpirun --oversubscribe -np "$np" "$exe" "$(basename "$deck")"; fi > log.txt 2>&1) \
    || { echo "run failed: $exe $deck np=$np (see $dir/log.txt)"; return 1; }
}
# the equilibrated Rahman state both builds start their energy-stepping run from (made once)
sed -i "s/final_atoms_file='argon_liquid_eq.atoms'/final_atoms_file='eq.atoms'/" rahman_eq.nml
"$old" rahman_eq.nml > eq.log 2>&1
fail=0
for deck in lj_vv rahman_es cu_vv cu_es cluster_es; do
  for np in 1 4; do
    run "$old" $np $deck.nml old_${deck}_$np; run "$new" $np $deck.nml new_${deck}_$np
    if cmp -s old_${deck}_$np/thermo.csv new_${deck}_$np/thermo.csv; then res=identical; else res=DIFFERENT; fail=1; fi
    printf '%-11s np=%d  %5d thermo lines  %s\n' $deck $np "$(wc -l < new_${deck}_$np/thermo.csv)" $res
  done
done
echo "workdir: $work"
exit $fail
