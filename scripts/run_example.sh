#!/usr/bin/env bash
# Install missing packages, build, and run the default example (input/argon_liquid.nml: Rahman's
# liquid argon, 864 atoms) in out/example/. Pass another deck to run that instead; set NP to run on
# several ranks (NP=4 scripts/run_example.sh).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
deck="$(realpath "${1:-$repo/input/argon_liquid.nml}")"
bash "$repo/scripts/install_deps.sh"
BUILD_TARGET=terrace bash "$repo/scripts/build.sh"
mkdir -p "$repo/out/example"
cd "$repo/out/example"
cp "$(dirname "$deck")"/*.atoms . 2>/dev/null || true
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mpirun --oversubscribe -np "${NP:-1}" "$repo/build/terrace" "$deck"
echo "outputs in $repo/out/example"
