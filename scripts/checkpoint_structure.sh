#!/usr/bin/env bash
# Write a small checkpoint (the seven-atom cluster, energy stepping, stopped by walltime_limit at
# its first safe point) and print its structure with `h5dump -H` and the /state values with h5py
# (the listings in doc/checkpoints.md come from this script).
# Usage: scripts/checkpoint_structure.sh [TERRACE_BINARY]
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
terrace="$(realpath "${1:-$repo/build/terrace}")"
PYTHON="${PYTHON:-/usr/bin/python3}"; [[ -x "$PYTHON" ]] || PYTHON=python3
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
cd "$work"
sed "s#@REPO@#$repo#g; s#&run #\&run walltime_limit=1e-6, #" "$repo/tests/regression/decks/ckpt_es_frozen7.nml" > c.nml
set +e; "$terrace" c.nml > /dev/null; rc=$?; set -e
echo "# exit status $rc"
h5dump -H restart.h5
"$PYTHON" - <<'PY'
import h5py
f = h5py.File("restart.h5", "r")
print("# root attributes:", {k: (v.decode() if isinstance(v, bytes) else v) for k, v in f.attrs.items()})
print("# /state attributes:")
for k, v in f["state"].attrs.items():
    print(f"#   {k} = {v}")
PY
