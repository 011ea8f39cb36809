#!/usr/bin/env bash
# The mixed-precision LJ kernel (&potential precision = 'mixed') against the double kernel on a
# liquid, and its energy conservation.
#   1. melts the 2048-atom fcc LJ scene (rho* 0.8442, T* 1.44 start, rc 2.5, 1000 steps, double)
#      into liquid.atoms (T* ~ 0.7);
#   2. forces, energy and pressure of that liquid at step 0 with both kernels, on NP ranks:
#        max over atoms and components |F_mixed - F_double| <= 1e-5 rms|F_double|  (measured 3e-6 to 5e-6)
#        median over atoms |F_mixed,i - F_double,i| / |F_double,i| <= 2e-6         (measured 6e-7 to 9e-7)
#        |pe_mixed - pe_double| <= 1e-6 |pe_double|                               (measured 1e-9 to 3e-8)
#        |press_mixed - press_double| <= 1e-5 |press_double|                       (measured 9e-9 to 8e-7)
#      (doc/bench_data/mixed_accuracy_6fc2854_xeon.txt: both lists, 1 and 3 ranks)
#      (single precision: unit round-off 6e-8 in the separations, amplified by up to 14 in the
#      r^-12 and r^-14 terms of the close pairs);
#   3. NVE from the liquid with the mixed kernel, 4000 steps of 0.005 tau: total momentum to 1e-10
#      (forces obey Newton's third law exactly: one double pair force for both atoms) and
#      max |E(t) - E0| <= 1e-3 |E0| (check_conservation.py; the double kernel gives 4e-4 there, the
#      energy jumps of the unshifted cutoff), drift per atom per tau printed.
# On one rank with the atom list the mixed runs read the periodic images as their owners at the
# nearest image (wrapped images, &neighbor images = 'auto'; the run log's halo line must say so), and
#   4. the same run with images = 'copies' (the images copied at every step), the two mixed runs
#      against each other with the bounds of 2. (they differ by their single-precision rounding,
#      measured 5.6e-6, 9e-7, 3e-8 and 8e-7; a pair read at a wrong image would differ by O(1)); a
#      liquid of 8 x 8 x 6 cells in a box 0.1234 longer along z (edges not in a power-of-two ratio)
#      against double with those bounds;
#      and 400 steps with the list pruned every 5 steps (the prunes read the ghosts, refreshed for
#      them): the potential energies of the two runs within 1e-4 relative at every sample (measured
#      2e-6, the runs' chaotic divergence; 1e-3 with the ghosts left stale for the prunes).
# With LIST = 'clusters' (fourth argument; default 'cells') the mixed runs use the cluster-pair list
# and kernel (&neighbor list = 'clusters'), the double reference the atom list, with the same bounds;
# the run log must then count cluster pairs.
# Usage: tests/regression/mixed_precision.sh TERRACE_BINARY OUTPUT_DIR [NP [LIST]]   (NP default 1)
set -euo pipefail
[[ $# -ge 2 ]] || { echo "usage: $0 TERRACE_BINARY OUTPUT_DIR [NP]" >&2; exit 2; }
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
terrace="$(realpath "$1")"; out="$2"; np="${3:-1}"; list="${4:-cells}"
PYTHON="${PYTHON:-/usr/bin/python3}"; [[ -x "$PYTHON" ]] || PYTHON=python3
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
rm -rf "$out"; mkdir -p "$out"; cd "$out"
run() {   # deck [np]
    local n="${2:-1}"
    if [[ $n == 1 ]]; then timeout 600 "$terrace" "$1" > "${1%.nml}.log" 2>&1
    else timeout 600 mpirun --oversubscribe -np "$n" "$terrace" "$1" > "${1%.nml}.log" 2>&1; fi || {
        echo "FAIL: terrace failed on $1"; tail -5 "${1%.nml}.log"; exit 1; }
}
L=$("$PYTHON" -c "print(repr(8*(4/0.8442)**(1/3)))"); Lz=$("$PYTHON" -c "print(repr(6*(4/0.8442)**(1/3) + 0.1234))")
cat > melt.nml <<EOF
&run units='lj', dimension=3, n_steps=1000, seed=4242 /
&system lattice='fcc', density=0.8442, cells=8,8,8, periodic=.true.,.true.,.true., mass=1.0, temperature=1.44 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&output thermo_every=100, thermo_file='', final_atoms_file='liquid.atoms' /
EOF
run melt.nml
deck() {   # FILE N_STEPS PRECISION NEIGHBOR_KEYS OUTPUT_KEYS: a run from the liquid
    cat > "$1" <<EOF
&run units='lj', dimension=3, n_steps=$2, seed=4242 /
&system atoms_file='liquid.atoms', box_lo=0,0,0, box_hi=$L,$L,$L, periodic=.true.,.true.,.true., mass=1.0 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, precision='$3' /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor $4 /
&output $5 /
EOF
}
for p in double mixed; do
    deck f_$p.nml 0 $p "skin=0.3, list='$([[ $p == mixed ]] && echo "$list" || echo cells)'" \
        "thermo_every=1, thermo_file='thermo_$p.csv', forces_file='forces_$p.txt'"
    run f_$p.nml "$np"
done
grep -q 'mixed precision' f_mixed.log || { echo "FAIL: the mixed run's log does not name the mixed kernel"; exit 1; }
# compare REF OTHER [N]: the forces (forces_REF.txt, forces_OTHER.txt) of N atoms (default 2048) and
# the first thermo sample's energy and pressure of two runs, against the bounds above
compare() {
    "$PYTHON" - "$1" "$2" "${3:-2048}" <<'PY'
import csv, math, sys
ref, other, natoms = sys.argv[1], sys.argv[2], int(sys.argv[3])
def forces(name):
    return {int(l.split()[0]): [float(v) for v in l.split()[1:4]] for l in open(name) if l.strip() and not l.startswith('#')}
fd, fm = forces('forces_%s.txt' % ref), forces('forces_%s.txt' % other)
assert fd.keys() == fm.keys() and len(fd) == natoms, 'atom ids differ'
rms = math.sqrt(sum(sum(c * c for c in f) for f in fd.values()) / len(fd))
dmax = max(max(abs(a - b) for a, b in zip(fd[i], fm[i])) for i in fd)
rel = sorted(math.dist(fd[i], fm[i]) / math.hypot(*fd[i]) for i in fd)
med = rel[len(rel) // 2]
td, tm = (list(csv.DictReader(open('thermo_%s.csv' % p)))[0] for p in (ref, other))
pe = abs(float(tm['pe']) - float(td['pe'])) / abs(float(td['pe']))
pr = abs(float(tm['press']) - float(td['press'])) / abs(float(td['press']))
checks = [('max |dF| / rms|F|', dmax / rms, 1e-5), ('median per-atom |dF|/|F|', med, 2e-6),
          ('|d pe| / |pe|', pe, 1e-6), ('|d press| / |press|', pr, 1e-5)]
ok = True
print('%s against %s:' % (other, ref))
for name, v, bound in checks:
    print('%-26s = %.3e   (bound %.0e)' % (name, v, bound))
    ok = ok and v <= bound
print('forces: rms|F| = %.4g, largest per-atom |dF|/|F| = %.3e (an atom with a small net force)' % (rms, rel[-1]))
sys.exit(0 if ok else 1)
PY
}
compare double mixed || exit 1
if [[ $list == cells && $np == 1 ]] && grep -Eq '(AVX-512|AVX2) pass' f_mixed.log; then
    grep -q 'halo .*as its owner at the nearest image' f_mixed.log || {
        echo "FAIL: the one-rank mixed run's halo line does not name the wrapped images"; grep 'halo' f_mixed.log; exit 1; }
    sed -e "s/list='cells' \//list='cells', images='copies' \//" -e 's/_mixed\./_copies./g' f_mixed.nml > f_copies.nml
    run f_copies.nml
    grep -q "halo .*periodic images copied on this rank (no MPI)" f_copies.log || {
        echo "FAIL: images = 'copies' did not copy the images"; grep 'halo' f_copies.log; exit 1; }
    compare copies mixed || exit 1
    # a box whose edges are not in a power-of-two ratio (the liquid of 8 x 8 x 6 cells in a box 0.1234
    # longer along z: the wrapped pass splits its grid step along z in two singles), mixed with
    # wrapped images against double
    sed -e "s/cells=8,8,8/cells=8,8,6/" -e "s/n_steps=1000/n_steps=200/" -e "s/liquid.atoms/liquid_z.atoms/" melt.nml > melt_z.nml
    run melt_z.nml
    for p in double mixed; do
        sed -e "s/liquid.atoms/liquid_z.atoms/" -e "s/box_hi=$L,$L,$L/box_hi=$L,$L,$Lz/" -e "s/_$p\./_z$p./g" f_$p.nml > fz_$p.nml
        run fz_$p.nml
    done
    grep -q 'halo .*as its owner at the nearest image' fz_mixed.log || { echo "FAIL: the 8 x 8 x 6 run has no wrapped images"; exit 1; }
    compare zdouble zmixed 1536 || exit 1
    for im in auto copies; do
        deck pruned_$im.nml 400 mixed "every=20, prune_every=5, buffer_tolerance=1e-3, images='$im'" \
            "thermo_every=10, thermo_file='pruned_$im.csv'"
        run pruned_$im.nml
    done
    "$PYTHON" - <<'PY' || exit 1
import csv, sys
a, c = (list(csv.DictReader(open('pruned_%s.csv' % p))) for p in ('auto', 'copies'))
d = max(abs(float(x['pe']) - float(y['pe'])) / abs(float(y['pe'])) for x, y in zip(a, c))
print('pruned every 5 steps, 400 steps, wrapped images against copies: max |d pe| / |pe| = %.3e (bound 1e-4)' % d)
sys.exit(0 if len(a) == len(c) == 41 and d <= 1e-4 else 1)
PY
fi
if [[ $list == clusters ]]; then
    n="$("$PYTHON" -m terrace_tools.summary get f_mixed.summary.json neighbor/list_pairs 2> /dev/null || echo 0)"
    [[ "$n" -gt 0 ]] || { echo "FAIL: the cluster run's summary counts no cluster pairs"; exit 1; }
fi
deck nve.nml 4000 mixed "skin=0.3, list='$list'" "thermo_every=20, thermo_file='thermo.csv'"
run nve.nml "$np"
"$PYTHON" -m terrace_tools.summary show nve.summary.json conservation timing/loop_time_s
"$PYTHON" "$here/check_conservation.py" thermo.csv 2048 --p-tol 1e-10 --e-tol 1e-3
