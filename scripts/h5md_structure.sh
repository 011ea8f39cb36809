#!/usr/bin/env bash
# Write a small H5MD trajectory (the seven-atom cluster, 3 frames of velocity Verlet) and print its
# structure with `h5dump -H`. With --short, only groups, datasets, attributes, hard links and
# dataspaces (datatypes left out): the listing in doc/trajectories.md.
# Usage: scripts/h5md_structure.sh [--short] [TERRACE_BINARY]
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
short=0; [[ "${1:-}" == "--short" ]] && { short=1; shift; }
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
if [[ $short -eq 1 ]]; then
    h5dump -H cluster.h5 | grep -E 'GROUP|DATASET|DATASPACE|ATTRIBUTE|HARDLINK' | sed -E 's/^   ( *DATASPACE)/\1/'
else
    h5dump -H cluster.h5
fi
