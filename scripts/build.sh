#!/usr/bin/env bash
# Configure and build Terrace (Release) into build/. Uses pFUnit when it is installed under
# $PFUNIT_PREFIX (default /opt/pfunit) or anywhere CMake finds it by itself.
# Usage: scripts/build.sh [extra cmake arguments, e.g. -DTERRACE_PORTABLE=ON]
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
prefix_args=()
pf="${PFUNIT_PREFIX:-/opt/pfunit}"
[[ -d "$pf" ]] && prefix_args=(-DCMAKE_PREFIX_PATH="$pf")
cmake -S "$repo" -B "$repo/build" -DCMAKE_BUILD_TYPE=Release "${prefix_args[@]}" "$@" > "$repo/.cmake-configure.log" 2>&1 || {
  cat "$repo/.cmake-configure.log" >&2; exit 1; }
grep -E "^-- Terrace|Terrace:" "$repo/.cmake-configure.log" || true
cmake --build "$repo/build" -j "$(nproc)" ${BUILD_TARGET:+--target "$BUILD_TARGET"} > "$repo/.cmake-build.log" 2>&1 || { tail -40 "$repo/.cmake-build.log" >&2; exit 1; }
echo "build: $repo/build/terrace"
