#!/usr/bin/env bash
# Install what Terrace needs from Debian/Ubuntu packages. As root it installs the missing ones
# (apt-get); otherwise it prints the exact command and exits 1. It also says how to make the Python
# package terrace_tools importable for the benchmark scripts (the tests do not need that).
# pFUnit is in no package registry: CMake finds an installed one or builds it from $TERRACE_PFUNIT_SOURCE (tests/pfunit_from_source.cmake);
# without either the unit tests are reported as skipped.
# Usage: scripts/install_deps.sh [--bench]   (--bench adds the optional benchmark anchors below; the
# build and the tests never need them)
set -euo pipefail
packages=(
  gfortran cmake make pkg-config            # build
  libopenmpi-dev openmpi-bin                 # MPI (mpi_f08)
  libhdf5-openmpi-dev hdf5-tools             # parallel HDF5 (H5MD trajectories)
  libfftw3-dev                               # FFTW 3 (analysis)
  python3 python3-numpy python3-h5py python3-matplotlib   # scripts, plots
  python3-venv                               # MDAnalysis test: a venv with PyPI's MDAnalysis
  python3-pytest python3-pip python3-setuptools python3-wheel   # terrace_tools: its tests; pip install -e
  lammps lammps-data                         # reference runs and EAM tables
)
bench=(
  gromacs                                    # optional: gmx, gmx_d for scripts/bench/anchors.sh only
  time                                       # GNU time (/usr/bin/time): anchors.sh's user CPU times
)
case "${1:-}" in
  --bench) packages+=("${bench[@]}") ;;
  "") ;;
  *) echo "usage: $0 [--bench]" >&2; exit 2 ;;
esac
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
# terrace_tools (scripts/terrace_tools) is not installed here: the tests put scripts/ on PYTHONPATH
# themselves, and installing it into the system's python would tie that python to one checkout
tools() {
  if ! /usr/bin/python3 -c 'import terrace_tools' > /dev/null 2>&1; then
    echo "install_deps: note: for the benchmark scripts, make terrace_tools importable:" \
         "pip install -e $repo/scripts (in a virtual environment), or PYTHONPATH=$repo/scripts"
  fi
}
if [[ ${#missing[@]} -eq 0 ]]; then
  echo "install_deps: all Debian packages present"
  tools
  exit 0
fi
if [[ $(id -u) -eq 0 ]]; then
  echo "install_deps: installing ${missing[*]}"
  export DEBIAN_FRONTEND=noninteractive
  apt-get update -qq
  apt-get install -y -qq --no-install-recommends "${missing[@]}" > /tmp/terrace-apt.log 2>&1 || {
    echo "install_deps: apt-get failed, see /tmp/terrace-apt.log" >&2; tail -20 /tmp/terrace-apt.log >&2; exit 1; }
else
  echo "install_deps: missing packages; run as root:" >&2
  echo "  sudo apt-get update && sudo apt-get install -y ${missing[*]}" >&2
  exit 1
fi
tools
