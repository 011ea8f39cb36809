#!/usr/bin/env bash
# A deck that minimizes and then runs dynamics (Lennard-Jones): the 147-atom argon icosahedron
# (input/argon_ico147.atoms, neighbour distance 3.816 A, LJ cut and shifted at 2.5 sigma) relaxed
# with CG and with FIRE (etol 0, ftol 1e-8 eV/A), then 100 velocity-Verlet steps at 10 K from the
# relaxed positions. Checks: each stops on the force tolerance with a lower energy than the start;
# the CG rows (<thermo stem>.min.csv: one per iteration) never rise in energy and end at the
# printed energy; CG and FIRE reach the same minimum within 1e-8 eV; CG on 4 ranks the same
# energy within 1e-10 eV; the dynamics writes its 100 steps' thermo and starts at that energy.
# usage: minimize_then_run.sh TERRACE OUTDIR
set -euo pipefail
terrace=$(readlink -f "$1") out=$2
here=$(cd "$(dirname "$0")" && pwd); repo=$(cd "$here/../.." && pwd)
rm -rf "$out"; mkdir -p "$out"; cd "$out"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
for run in cg:1 fire:1 cg:4; do
    style=${run%:*} np=${run#*:}
    cat > ${style}_np$np.nml <<NML
&run units='metal', dimension=3, n_steps=100, seed=147 /
&system atoms_file='$repo/input/argon_ico147.atoms', periodic=.false.,.false.,.false., mass=39.951, temperature=10.0 /
&potential style='lj', epsilon=0.010323577, sigma=3.41, cutoff=8.525, shift=.true. /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=1.0 /
&minimize style='$style', etol=0.0, ftol=1.0e-8 /
&output thermo_every=10, thermo_file='${style}_np$np.csv' /
NML
    mpirun --oversubscribe -np "$np" "$terrace" ${style}_np$np.nml > ${style}_np$np.log
done
python3 - <<'PY'
import csv, re, sys
ok = True
def result(name):
    t = open(name + ".log").read()
    crit = re.search(r"stopping criterion = (.*)", t).group(1)
    e0, e1 = map(float, re.search(r"energy initial, final = +(\S+) +(\S+)", t).groups())
    return crit, e0, e1
res = {n: result(n) for n in ("cg_np1", "fire_np1", "cg_np4")}
for n, (crit, e0, e1) in res.items():
    print(f"{n}: {crit}, energy {e0:.10f} -> {e1:.10f} eV")
    if crit != "force tolerance" or not e1 < e0:
        ok = False; print(f"FAIL {n}: expected the force tolerance and a lower energy")
rows = list(csv.DictReader(open("cg_np1.min.csv")))
pe = [float(r["pe"]) for r in rows]
rises = sum(1 for a, b in zip(pe, pe[1:]) if b > a + 1e-12)
print(f"cg_np1.min.csv: {len(rows)} rows (iterations 0..{rows[-1]['iteration']}), energy rises: {rises}")
if rises or abs(pe[-1] - res["cg_np1"][2]) > 1e-9:
    ok = False; print("FAIL: CG rows rise in energy or do not end at the printed energy")
d = res["fire_np1"][2] - res["cg_np1"][2]
print(f"FIRE - CG minimum: {d:.2e} eV")
if abs(d) > 1e-8:
    ok = False; print("FAIL: CG and FIRE minima differ by more than 1e-8 eV")
d4 = res["cg_np4"][2] - res["cg_np1"][2]
print(f"CG 4 ranks - 1 rank: {d4:.2e} eV")
if abs(d4) > 1e-10:
    ok = False; print("FAIL: CG on 4 ranks differs by more than 1e-10 eV")
th = list(csv.DictReader(open("cg_np1.csv")))
print(f"dynamics: {len(th)} thermo rows, steps {th[0]['step']}..{th[-1]['step']}, pe at step 0 {float(th[0]['pe']):.10f}")
if th[-1]["step"] != "100" or abs(float(th[0]["pe"]) - res["cg_np1"][2]) > 1e-9:
    ok = False; print("FAIL: the dynamics did not start from the minimized state or did not run 100 steps")
sys.exit(0 if ok else 1)
PY
