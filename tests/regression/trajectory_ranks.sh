#!/usr/bin/env bash
# H5MD trajectory: the same deck on 1, 2 and 4 ranks writes the same frames in global id order
# (positions, velocities, forces, images to 1e-10 relative, ids 1..N, steps, times and box equal).
# Usage: tests/regression/trajectory_ranks.sh TERRACE_BINARY DECK OUTDIR
set -euo pipefail
[[ $# -eq 3 ]] || { echo "usage: $0 TERRACE_BINARY DECK OUTDIR" >&2; exit 2; }
terrace="$(realpath "$1")"; deck="$2"; out="$3"
PYTHON="${PYTHON:-/usr/bin/python3}"; [[ -x "$PYTHON" ]] || PYTHON=python3
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
rm -rf "$out"; mkdir -p "$out"
for np in 1 2 4; do
    sed "s/thermo_file='thermo.csv'/thermo_file='thermo$np.csv', trajectory_file='traj$np.h5', trajectory_every=20, trajectory_fields='position velocity force image'/" \
        "$deck" > "$out/deck$np.nml"
    (cd "$out" && timeout 300 mpirun --oversubscribe -np $np "$terrace" deck$np.nml > terrace$np.log 2>&1) || {
        echo "FAIL: terrace on $np rank(s)"; tail -5 "$out/terrace$np.log"; exit 1; }
done
"$PYTHON" - "$out/traj1.h5" "$out/traj2.h5" "$out/traj4.h5" <<'PY'
import sys
import h5py
import numpy as np
a = h5py.File(sys.argv[1], "r")
n = a["particles/all/id"].shape[0]
ok = True
def check(name, cond):
    global ok
    print(("ok   " if cond else "FAIL ") + name)
    ok = ok and cond
check("H5MD version 1.1", list(a["h5md"].attrs["version"]) == [1, 1])
obs = a["observables"]
check("observables have one value per frame, their step and time are the frames' (hard links)",
      all(obs[k]["step"] == a["particles/all/box/edges/step"] and obs[k]["time"] == a["particles/all/box/edges/time"]
          and obs[k]["value"].shape == a["particles/all/box/edges/step"].shape for k in obs))
for path, np_ in zip(sys.argv[2:], (2, 4)):
    b = h5py.File(path, "r")
    check(f"ids are 1..N in order on 1 and {np_} ranks", (a["particles/all/id"][:] == np.arange(1, n + 1)).all()
          and (b["particles/all/id"][:] == np.arange(1, n + 1)).all())
    for f in ("position", "velocity", "force"):
        va, vb = a[f"particles/all/{f}/value"][:], b[f"particles/all/{f}/value"][:]
        scale = np.abs(va).max()
        check(f"{f}: shape {va.shape}, max |1 rank - {np_} ranks| = {np.abs(va - vb).max():.2e} (scale {scale:.2e})",
              va.shape == vb.shape and np.abs(va - vb).max() <= 1e-10 * scale)
    check(f"images equal (1 and {np_} ranks)",
          (a["particles/all/image/value"][:] == b["particles/all/image/value"][:]).all())
    for k in ("step", "time", "value"):
        ea, eb = a[f"particles/all/box/edges/{k}"][:], b[f"particles/all/box/edges/{k}"][:]
        check(f"box/edges/{k} equal (1 and {np_} ranks)", ea.shape == eb.shape and (ea == eb).all())
    check(f"position steps and times equal (1 and {np_} ranks)",
          (a["particles/all/position/step"][:] == b["particles/all/position/step"][:]).all()
          and (a["particles/all/position/time"][:] == b["particles/all/position/time"][:]).all())
print("PASS" if ok else "FAIL")
sys.exit(0 if ok else 1)
PY
