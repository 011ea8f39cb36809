#!/usr/bin/env bash
# The whole test suite: install missing packages, build, run every CTest test (unit tests with
# pFUnit when it is found, regression tests always).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$repo/scripts/install_deps.sh"
bash "$repo/scripts/build.sh"
if ! grep -q "unit tests enabled" "$repo/.cmake-configure.log"; then
  echo "test: pFUnit not found: UNIT TESTS SKIPPED (regression tests still run)"
fi
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
cd "$repo/build"
ctest --output-on-failure -j "$(nproc)" "$@"
