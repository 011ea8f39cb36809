#!/usr/bin/env bash
# Speed of two builds by instruction count (issue 11, must-show 2, on a machine too loaded for wall
# times): the scenes of old_new_speed.sh (LAMMPS LJ and Cu EAM benchmarks, 32,000 atoms, one rank),
# each run once per build under `valgrind --tool=callgrind`, whose instruction counts repeat to the
# instruction whatever else the machine does. Counts cover the whole process (set-up included), so
# a step count large enough for the steps to dominate is used (default LJ 100, EAM 20 steps).
# Prints each count and new/old.
# Usage: scripts/bench/old_new_instructions.sh OLD_TERRACE NEW_TERRACE [NSTEPS_LJ [NSTEPS_EAM]]
set -euo pipefail
old="$(realpath "$1")"; new="$(realpath "$2")"
nlj="${3:-100}"; neam="${4:-20}"
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
command -v valgrind > /dev/null || { echo "old_new_instructions: valgrind is not installed (apt-get install valgrind)" >&2; exit 2; }
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT; cd "$work"
sed -e "s/n_steps=1000/n_steps=$nlj/" "$repo/input/lj_bench.nml" > lj.nml
cat > eam.nml <<NML
&run units='metal', dimension=3, n_steps=$neam, seed=87287 /
&system lattice='fcc', lattice_constant=3.615, cells=20,20,20, periodic=.true.,.true.,.true., temperature=1600.0 /
&potential style='eam', file='/usr/share/lammps/potentials/Cu_u3.eam' /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=1.0 /
&output thermo_every=50, thermo_file='' /
NML
echo "old: $old"; echo "new: $new"
echo "machine: $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1); date: $(date -u '+%Y-%m-%d %H:%M UTC')"
count() {  # instructions executed by the whole run
  valgrind --tool=callgrind --callgrind-out-file=cg.out "$1" "$2" > /dev/null 2>cg.err
  sed -n 's/^summary: *\([0-9]*\).*/\1/p' cg.out | head -1
}
for scene in lj eam; do
  io=$(count "$old" $scene.nml); in=$(count "$new" $scene.nml)
  awk -v s=$scene -v o="$io" -v n="$in" 'BEGIN{printf "%-4s old %.4e, new %.4e instructions, new/old = %.4f\n", s, o, n, n/o}'
done
