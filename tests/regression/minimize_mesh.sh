#!/usr/bin/env bash
# Minimization of a neo-Hookean mesh: the talk's cube (scripts/make_cube_mesh.py, 2,969 nodes),
# deformed by 10 ms of its spinning run (input/cube_spin_verlet.nml; elastic energy about 0.05 J),
# relaxed with CG and FIRE on 1 rank and CG on 4 ranks: each stops on the force tolerance with an
# elastic energy below 1e-9 of the start's (a free body relaxes to its rest shape: zero energy).
# usage: minimize_mesh.sh TERRACE OUTDIR
set -euo pipefail
terrace=$(readlink -f "$1") out=$2
here=$(cd "$(dirname "$0")" && pwd); repo=$(cd "$here/../.." && pwd)
rm -rf "$out"; mkdir -p "$out"; cd "$out"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
/usr/bin/python3 "$repo/scripts/make_cube_mesh.py" cube.msh --size 0.1 --center > /dev/null
sed -e "s/run_time=0.1/run_time=0.01/" -e "s|thermo_file='cube_spin_verlet.csv'|thermo_file='spin.csv', final_atoms_file='spun.atoms'|" \
    "$repo/input/cube_spin_verlet.nml" > spin.nml
"$terrace" spin.nml > spin.log
status=0
for run in cg:1 fire:1 cg:4; do
    style=${run%:*} np=${run#*:}
    cat > min_${style}_np$np.nml <<NML
&run        units='si', dimension=3, n_steps=0, seed=1 /
&system     mesh_file='cube.msh', atoms_file='spun.atoms', mass_density=1100.0, periodic=.false.,.false.,.false. /
&potential  style='neohookean', lambda=2.7e6, mu=3.0e5 /
&integrator style='velocity_verlet', dt=2.5e-5 /
&minimize   style='$style', etol=0.0, ftol=1.0e-8, max_iterations=20000 /
&output     thermo_file='min_${style}_np$np.csv' /
NML
    mpirun --oversubscribe -np "$np" "$terrace" min_${style}_np$np.nml > min_${style}_np$np.log
    read -r crit e0 e1 < <(python3 - min_${style}_np$np.log <<'PY'
import re, sys
t = open(sys.argv[1]).read()
c = re.search(r"stopping criterion = (.*)", t).group(1).replace(" ", "_")
e0, e1 = re.search(r"energy initial, final = +(\S+) +(\S+)", t).groups()
print(c, e0, e1)
PY
)
    if [ "$crit" = force_tolerance ] && python3 -c "import sys; sys.exit(0 if $e1 < 1e-9 * $e0 and $e0 > 1e-3 else 1)"; then
        echo "ok   $style on $np rank(s): $crit, elastic energy $e0 -> $e1 J"
    else
        echo "FAIL $style on $np rank(s): $crit, elastic energy $e0 -> $e1 J"; status=1
    fi
done
exit $status
