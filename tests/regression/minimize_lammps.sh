#!/usr/bin/env bash
# Minimization against LAMMPS: the vacancy formation energy of Cu (Cu_u3.eam, fcc 4x4x4 at a =
# 3.615 A, box fixed), E_f = E_vac - (N-1)/N E_perfect, with Terrace's CG and FIRE against LAMMPS's
# `minimize` (min_style cg and fire) on the same data file, each within 1e-6 eV; the relaxed
# energy of Terrace's CG on 1 and 4 ranks within 1e-9 eV of each other; and the 0 K lattice
# constant from a = 3.6 A with &minimize box_relax = 'iso' (CG and FIRE; CG on 4 ranks) against
# LAMMPS's `fix box/relax iso 0.0` with min_style cg, within 1e-6 A. Exit 77 without LAMMPS.
# usage: minimize_lammps.sh TERRACE OUTDIR
set -euo pipefail
terrace=$1 out=$2
pot=/usr/share/lammps/potentials/Cu_u3.eam
command -v lmp >/dev/null 2>&1 || { echo "SKIP: no lmp on PATH"; exit 77; }
[ -f "$pot" ] || { echo "SKIP: no $pot"; exit 77; }
rm -rf "$out"; mkdir -p "$out"; cd "$out"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1

cat > vac.in <<IN
units metal
atom_style atomic
boundary p p p
lattice fcc 3.615
region box block 0 4 0 4 0 4
create_box 1 box
create_atoms 1 box
mass 1 63.546
pair_style eam
pair_coeff * * $pot
thermo_style custom step pe fnorm
thermo_modify format float %20.12f
run 0
variable e0 equal pe
print "PERFECT \${e0}"
write_data perfect.data
group gone id 1
delete_atoms group gone
write_data vac.data
min_style \${style}
minimize 0.0 1.0e-10 100000 1000000
variable e1 equal pe
print "RELAXED \${e1}"
IN
for style in cg fire; do
    lmp -in vac.in -var style $style -log lmp_$style.log > /dev/null
done
cat > lat.in <<IN
units metal
atom_style atomic
boundary p p p
lattice fcc 3.6
region box block 0 4 0 4 0 4
create_box 1 box
create_atoms 1 box
mass 1 63.546
pair_style eam
pair_coeff * * $pot
fix 1 all box/relax iso 0.0
min_style cg
minimize 0.0 1.0e-10 100000 1000000
variable a equal lx/4
print "LATTICE \${a}"
IN
lmp -in lat.in -log lmp_lat.log > /dev/null
for style in cg fire; do
cat > lat_$style.nml <<NML
&run units='metal', n_steps=0 /
&system lattice='fcc', lattice_constant=3.6, cells=4,4,4, periodic=.true.,.true.,.true. /
&potential style='eam', file='$pot' /
&integrator style='velocity_verlet', dt=0.002 /
&neighbor skin=1.0 /
&minimize style='$style', etol=0.0, ftol=1.0e-10, box_relax='iso', pressure=0.0 /
&output thermo_file='lat_$style.csv', overwrite=.true. /
NML
"$terrace" lat_$style.nml > lat_$style.log
done
mpirun --oversubscribe -np 4 "$terrace" lat_cg.nml > lat_cg_np4.log

deck() {   # deck NAME DATA STYLE
cat > "$1.nml" <<NML
&run units='metal', n_steps=0 /
&system read_data='$2' /
&potential style='eam', file='$pot' /
&integrator style='velocity_verlet', dt=0.002 /
&neighbor skin=1.0 /
&minimize style='$3', etol=0.0, ftol=1.0e-10, max_iterations=100000, max_evaluations=1000000 /
&output thermo_file='$1.csv', overwrite=.true. /
NML
}
deck perfect perfect.data cg
deck vac_cg vac.data cg
deck vac_fire vac.data fire
"$terrace" perfect.nml > perfect.log
"$terrace" vac_cg.nml > vac_cg.log
"$terrace" vac_fire.nml > vac_fire.log
mpirun --oversubscribe -np 4 "$terrace" vac_cg.nml > vac_cg_np4.log
cp vac_cg.min.csv vac_cg_np4.min.csv 2>/dev/null || true

python3 - <<'PY'
import re, sys
def lmp(style, key):
    for line in open(f"lmp_{style}.log"):
        if line.startswith(key + " "):
            return float(line.split()[1])
    sys.exit(f"FAIL: no {key} in lmp_{style}.log")
def terr(name):
    text = open(name + ".log").read()
    crit = re.search(r"stopping criterion = (.*)", text).group(1)
    ei, ef = map(float, re.search(r"energy initial, final = +(\S+) +(\S+)", text).groups())
    return crit, ef
n = 256
ok = True
_, ep = terr("perfect")
print(f"{'':10s} {'E_f Terrace (eV)':>20s} {'E_f LAMMPS (eV)':>20s} {'difference':>12s}  criterion")
for style in ("cg", "fire"):
    lp, lv = lmp(style, "PERFECT"), lmp(style, "RELAXED")
    crit, ev = terr("vac_" + style)
    ef_l = lv - (n - 1) / n * lp
    ef_t = ev - (n - 1) / n * ep
    d = ef_t - ef_l
    print(f"{style:10s} {ef_t:20.10f} {ef_l:20.10f} {d:12.3e}  {crit}")
    if abs(d) > 1e-6:
        ok = False
        print(f"FAIL: {style}: vacancy formation energy differs from LAMMPS by {d:.3e} eV (> 1e-6)")
_, e1 = terr("vac_cg"); _, e4 = terr("vac_cg_np4")
print(f"CG relaxed energy, 1 vs 4 ranks: {e1:.12f} {e4:.12f} (difference {e4 - e1:.2e})")
if abs(e4 - e1) > 1e-9:
    ok = False
    print("FAIL: 1 and 4 ranks differ by more than 1e-9 eV")
def lattice(name):
    text = open(name + ".log").read()
    return float(re.search(r"box lengths +(\S+)", text).group(1)) / 4
a_l = lmp("lat", "LATTICE")
for name in ("lat_cg", "lat_fire", "lat_cg_np4"):
    a_t = lattice(name)
    print(f"0 K lattice constant, {name}: Terrace {a_t:.12f} A, LAMMPS box/relax {a_l:.12f} A, "
          f"difference {a_t - a_l:.2e}")
    if abs(a_t - a_l) > 1e-6:
        ok = False
        print(f"FAIL: {name}: lattice constant differs from LAMMPS's by more than 1e-6 A")
sys.exit(0 if ok else 1)
PY
