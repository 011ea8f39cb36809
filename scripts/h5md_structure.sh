#!/usr/bin/env bash
# Write a small H5MD trajectory (the seven-atom cluster, 3 frames of velocity Verlet) and print its
# structure with `h5dump -H` (the listing in doc/trajectories.md comes from this script).
# Usage: scripts/h5md_structure.sh [TERRACE_BINARY]
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
terrace="$(realpath "${1:-$repo/build/terrace}")"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
cd "$work"
cat > h.nml <<NML
&run units='metal', dimension=2, n_steps=20, seed=1 /
&system atoms_file='$repo/input/argon_frozen_2d.atoms', periodic=.false.,.false., mass=39.951 /
&potential style='lj', epsilon=0.010323577, sigma=3.41, cutoff=0.0 /
&integrator style='velocity_verlet', dt=0.01 /
&output thermo_every=10, trajectory_file='cluster.h5', trajectory_every=10 /
NML
"$terrace" h.nml > /dev/null
h5dump -H cluster.h5
