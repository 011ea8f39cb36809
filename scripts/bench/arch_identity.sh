#!/usr/bin/env bash
# Bitwise identity of two builds on a fixed set of runs (a refactoring changes no behaviour):
# LJ liquid with velocity Verlet (1000 steps), Rahman argon with energy stepping (2000 events, from
# a Verlet-equilibrated state), Cu EAM with velocity Verlet and with energy stepping, the 256-atom
# Cu-Ni alloy (eam/alloy: the several-types EAM passes) with both, a free seven-atom cluster (all-pairs path, energy stepping), each thermostat with velocity Verlet
# (Langevin, CSVR, Nose-Hoover chains, Andersen with zero_momentum) and energy stepping's three
# (Andersen at exact times, CSVR and Andersen's global variant at intervals), a three-type LJ
# mixture with both integrators, mixed precision over cluster pairs and over the atom list, the spinning cube and
# the colliding balls with both integrators, the barostats' rank-invariance decks (C-rescale, Monte
# Carlo, MTTK; iso and aniso), event-driven square wells and hard spheres, and a checkpoint restart
# of each integrator (stopped
# at its first safe point by walltime_limit, continued by each build from its own checkpoint), on 1
# and 4 ranks. Prints one line per run and exits non-zero if any thermo file differs by a byte.
# The balls need the gmsh Python package (scripts/make_ball_mesh.py); without it they are skipped.
# Usage: scripts/bench/arch_identity.sh OLD_TERRACE NEW_TERRACE [WORKDIR]
#   ONLY=REGEX runs only the decks whose name matches; NPROCS='1 4' the rank counts.
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
# the several-types EAM passes: the Cu-Ni alloy of the energy-stepping tests, with both integrators
sed -e "s#@REPO@#$repo#" -e 's/run_time=0.04/run_time=0.02/' "$repo/tests/regression/decks/es_cuni_eam.nml" > cuni_es.nml
sed -e "s/style='energy_stepping', target_mean_dt=5.0e-4/style='velocity_verlet', dt=0.002/" \
    -e 's/run_time=0.02/run_time=0.4/' -e 's/thermo_interval=0.002/thermo_interval=0.02/' cuni_es.nml > cuni_vv.nml
grep -q "velocity_verlet" cuni_vv.nml || { echo "arch_identity: could not edit es_cuni_eam.nml" >&2; exit 1; }
cat > cluster_es.nml <<NML
&run units='metal', dimension=2, run_time=2.0e4, seed=1 /
&system atoms_file='$repo/input/argon_frozen_2d.atoms', periodic=.false.,.false., mass=39.951 /
&potential style='lj', epsilon=0.010323577, sigma=3.41, cutoff=0.0 /
&integrator style='energy_stepping', terrace_height=1.378775e-3 /
&output thermo_interval=100.0, thermo_file='thermo.csv' /
NML
# thermostats: LJ 4x4x4 with velocity Verlet; Rahman argon with energy stepping
for ts in "style='langevin', temperature=1.2, damping=0.5" "style='csvr', temperature=1.2, damping=0.5" \
          "style='nose_hoover', temperature=1.2, damping=0.5, chain_length=4" \
          "style='andersen', temperature=1.2, damping=0.5, zero_momentum=.true." ; do
  name=vv_$(echo "$ts" | sed -E "s/style='([a-z_]+)'.*/\1/")
  sed -e 's/n_steps=1000/n_steps=400/' -e 's/cells=8,8,8/cells=4,4,4/' lj_vv.nml > $name.nml
  echo "&thermostat $ts /" >> $name.nml
done
for ts in "style='andersen', temperature=94.4, damping=0.5" "style='csvr', temperature=94.4, damping=0.5, interval=0.05" \
          "style='andersen', temperature=94.4, damping=0.5, interval=0.1, zero_momentum=.true." ; do
  name=es_$(echo "$ts" | sed -E "s/style='([a-z_]+)'.*/\1/")$([[ $ts == *interval=0.1* ]] && echo _global || true)
  sed -e 's/n_steps=2000/n_steps=600/' rahman_es.nml > $name.nml
  echo "&thermostat $ts /" >> $name.nml
done
# LJ kernels: a three-type mixture (Verlet and energy stepping), one type in mixed precision over
# the cluster-pair list and over the half atom list
sed -e "s#@REPO@#$repo#" -e 's/n_steps=3000/n_steps=600/' "$repo/tests/regression/decks/es_mix3.nml" > mix3_es.nml
sed -e "s/style='energy_stepping', terrace_height=0.1/style='velocity_verlet', dt=0.004/" -e 's/n_steps=600/n_steps=300/' mix3_es.nml > mix3_vv.nml
sed -e "s/cutoff=2.5 \//cutoff=2.5, precision='mixed' \//" -e 's/n_steps=1000/n_steps=300/' lj_vv.nml > lj_mixed_any.nml
sed -e "s/skin=0.3 \//skin=0.3, list='clusters' \//" lj_mixed_any.nml > lj_mixed.nml
sed -e "s/skin=0.3 \//skin=0.3, list='cells' \//" lj_mixed_any.nml > lj_mixed_cells.nml
# meshes: the talk's cube (4 x 4 x 4 cells), and the two balls (refine 2) when gmsh is there
/usr/bin/python3 "$repo/scripts/make_cube_mesh.py" cube.msh --cells 4 --size 0.1 --center > /dev/null
sed -e "s/run_time=0.1/run_time=0.004/" -e 's/thermo_interval=0.002/thermo_interval=0.0005/' \
    -e "s/thermo_file='cube_spin_verlet.csv'/thermo_file='thermo.csv'/" "$repo/input/cube_spin_verlet.nml" > cube_vv.nml
sed -e "s/run_time=0.1/run_time=0.004/" -e 's/thermo_interval=0.002/thermo_interval=0.0005/' \
    -e "s/thermo_file='cube_spin_es.csv'/thermo_file='thermo.csv'/" "$repo/input/cube_spin_es.nml" > cube_es.nml
meshes="cube_vv cube_es"
if "${TERRACE_VENV:-$HOME/.cache/terrace-venv}/bin/python" -c 'import gmsh' 2> /dev/null \
   && /usr/bin/python3 "$repo/scripts/make_ball_mesh.py" balls.msh --refine 2 > /dev/null 2>&1; then
  for i in verlet es; do
    sed -e "s/run_time=0.1/run_time=0.06/" -e "s/thermo_file='balls_$i.csv'/thermo_file='thermo.csv'/" \
        -e "s/trajectory_file='balls_$i.h5'/trajectory_file=''/" -e 's/terrace_height=1.0e-4/terrace_height=1.0e-3/' \
        "$repo/input/balls_$i.nml" > balls_$i.nml
  done
  meshes="$meshes balls_verlet balls_es"
else
  echo "balls: skipped (no gmsh Python package; scripts/make_ball_mesh.py says how to install it)"
fi
# barostats (the rank-invariance decks: C-rescale, Monte Carlo with both integrators, MTTK; iso and
# aniso) and event-driven dynamics (a square-well liquid; hard spheres)
baros=""
for d in "$repo"/tests/regression/decks/baro_*_ranks.nml; do
  b=$(basename "$d" _ranks.nml); cp "$d" "$b.nml"; baros="$baros $b"
done
sed -e 's/run_time=5.0/run_time=2.0/' -e "s/, trajectory_file='traj.h5', trajectory_interval=0.2//" \
    -e "s/final_atoms_file='final.txt', checkpoint_file='restart.h5', checkpoint_interval=0.5 \//final_atoms_file='final.txt' \//" \
    "$repo/tests/regression/decks/ckpt_ed_sw.nml" > ed_sw.nml
grep -q "final_atoms_file='final.txt' /" ed_sw.nml || { echo "arch_identity: could not edit ckpt_ed_sw.nml" >&2; exit 1; }
sed -e "s/style='square_well', diameter=1.0, well_depth=1.0, well_lambda=1.5/style='hard_sphere', diameter=1.0/" \
    -e 's/density=0.7/density=0.85/' ed_sw.nml > ed_hs.nml
# restarts: the LJ liquid (Verlet) and Rahman argon (energy stepping) with a checkpoint file
sed -e "s/thermo_file='thermo.csv'/thermo_file='thermo.csv', checkpoint_file='ckpt.h5', checkpoint_every=200/" lj_vv.nml > restart_vv.nml
sed -e "s/thermo_file='thermo.csv'/thermo_file='thermo.csv', checkpoint_file='ckpt.h5', checkpoint_interval=0.5/" rahman_es.nml > restart_es.nml

run() {   # build np deck dir
  local exe=$1 np=$2 deck=$3 dir=$4
  rm -rf "$dir"; mkdir -p "$dir"; cp "$deck" "$dir/"; cp ./*.msh "$dir/" 2> /dev/null || true
  [[ -f eq.atoms ]] && cp eq.atoms "$dir/argon_liquid_eq.atoms"
  (cd "$dir" && if [[ $np == 1 ]]; then "$exe" "$(basename "$deck")"; else mpirun --oversubscribe -np "$np" "$exe" "$(basename "$deck")"; fi > log.txt 2>&1) \
    || { echo "run failed: $exe $deck np=$np (see $dir/log.txt)"; return 1; }
}
# the equilibrated Rahman state both builds start their energy-stepping run from (made once)
sed -i "s/final_atoms_file='argon_liquid_eq.atoms'/final_atoms_file='eq.atoms'/" rahman_eq.nml
"$old" rahman_eq.nml > eq.log 2>&1
# a restart: the first run stops at its first safe point with a checkpoint (exit 3), the second
# continues from it (each build from its own)
restart() {   # build np deck dir
  local exe=$1 np=$2 deck=$3 dir=$4 rc=0
  rm -rf "$dir"; mkdir -p "$dir"; cp "$deck" "$dir/"; cp eq.atoms "$dir/argon_liquid_eq.atoms"
  sed -i "s/^&run /\&run walltime_limit=1.0e-6, /" "$dir/$deck"
  local mpi=(); [[ $np == 1 ]] || mpi=(mpirun --oversubscribe -np "$np")
  (cd "$dir" && "${mpi[@]}" "$exe" "$deck" > log1.txt 2>&1) || rc=$?
  [[ $rc == 3 ]] || { echo "restart: the first run did not stop with a checkpoint: $exe $deck np=$np ($dir/log1.txt)"; return 1; }
  sed -i -e "s/walltime_limit=1.0e-6, //" -e "s/^&system /\&system read_checkpoint='ckpt.h5', /" "$dir/$deck"
  (cd "$dir" && "${mpi[@]}" "$exe" "$deck" > log.txt 2>&1) || { echo "restart failed: $exe $deck np=$np ($dir/log.txt)"; return 1; }
}
fail=0
for deck in lj_vv rahman_es cu_vv cu_es cuni_vv cuni_es cluster_es mix3_vv mix3_es lj_mixed lj_mixed_cells vv_langevin vv_csvr vv_nose_hoover vv_andersen \
            es_andersen es_csvr es_andersen_global $meshes $baros ed_sw ed_hs restart_vv restart_es; do
  [[ -n ${ONLY:-} && ! $deck =~ $ONLY ]] && continue
  for np in ${NPROCS:-1 4}; do
    if [[ $deck == restart_* ]]; then
      restart "$old" $np $deck.nml old_${deck}_$np; restart "$new" $np $deck.nml new_${deck}_$np
    else
      run "$old" $np $deck.nml old_${deck}_$np; run "$new" $np $deck.nml new_${deck}_$np
    fi
    if cmp -s old_${deck}_$np/thermo.csv new_${deck}_$np/thermo.csv; then res=identical; else res=DIFFERENT; fail=1; fi
    printf '%-20s np=%d  %5d thermo lines  %s\n' $deck $np "$(wc -l < new_${deck}_$np/thermo.csv)" $res
  done
done
echo "workdir: $work"
exit $fail
