#!/usr/bin/env bash
# read_h5md: a run that starts from frame 3 (step 40) of another run's H5MD trajectory, on 2 ranks,
# reaches the same thermo at its step 60 as the original at step 100 (1e-10 relative). The same
# file rewritten with a time-independent box/edges dataset (the form of earlier Terrace files, also
# allowed by H5MD 1.1) gives a bitwise identical continuation.
# Usage: tests/regression/h5md_continue.sh TERRACE_BINARY OUTDIR
set -euo pipefail
[[ $# -eq 2 ]] || { echo "usage: $0 TERRACE_BINARY OUTDIR" >&2; exit 2; }
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
terrace="$(realpath "$1")"; out="$2"
PYTHON="${PYTHON:-/usr/bin/python3}"; [[ -x "$PYTHON" ]] || PYTHON=python3
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
rm -rf "$out"; mkdir -p "$out"; cd "$out"
sed "s/thermo_file='thermo.csv'/thermo_file='orig.csv', trajectory_file='orig.h5', trajectory_every=20/" \
    "$here/decks/liquid_2048.nml" > orig.nml
cat > cont.nml <<'NML'
&run units='lj', dimension=3, n_steps=60, seed=1 /
&system read_h5md='orig.h5', h5md_frame=3, periodic=.true.,.true.,.true., mass=1.0 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&output thermo_every=10, thermo_file='cont.csv' /
NML
timeout 300 "$terrace" orig.nml > orig.log 2>&1 || { echo "FAIL: original run"; tail -3 orig.log; exit 1; }
timeout 300 mpirun --oversubscribe -np 2 "$terrace" cont.nml > cont.log 2>&1 || { echo "FAIL: continuation"; tail -3 cont.log; exit 1; }
"$PYTHON" - <<'PY'
import shutil, h5py
shutil.copy("orig.h5", "fixed_box.h5")
with h5py.File("fixed_box.h5", "r+") as f:
    box = f["particles/all/box"]
    edges = box["edges/value"][0]
    del box["edges"]
    box["edges"] = edges
PY
sed "s/orig.h5/fixed_box.h5/; s/cont.csv/cont_fixed.csv/" cont.nml > cont_fixed.nml
timeout 300 mpirun --oversubscribe -np 2 "$terrace" cont_fixed.nml > cont_fixed.log 2>&1 || {
    echo "FAIL: continuation from a fixed box/edges"; tail -3 cont_fixed.log; exit 1; }
if cmp -s cont.csv cont_fixed.csv; then
    echo "ok   the continuation from a time-independent box/edges is identical"
else
    echo "FAIL: the continuation from a time-independent box/edges differs"; diff cont.csv cont_fixed.csv | head; exit 1
fi
"$PYTHON" - <<'PY'
import csv, sys
a = {int(r["step"]): r for r in csv.DictReader(open("orig.csv"))}
b = {int(r["step"]): r for r in csv.DictReader(open("cont.csv"))}
ok = True
for sb, sa in ((0, 40), (60, 100)):
    for k in ("temp", "pe", "ke", "etotal", "press"):
        x, y = float(a[sa][k]), float(b[sb][k])
        rel = abs(x - y) / max(abs(x), 1e-300)
        good = rel <= 1e-10
        ok = ok and good
        print(f"{'ok  ' if good else 'FAIL'} {k:6} original step {sa:3}: {x: .16e}  continued step {sb:2}: {y: .16e}  rel {rel:.1e}")
print("PASS" if ok else "FAIL")
sys.exit(0 if ok else 1)
PY
