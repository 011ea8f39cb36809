#!/usr/bin/env bash
# Configure and build Terrace (Release) into build/.
# pFUnit (unit tests): an installed pFUnit 4 under $PFUNIT_PREFIX (default /opt/pfunit) or anywhere
# CMake finds it; otherwise, when TERRACE_PFUNIT_SOURCE names pFUnit's source (an archive with its
# dependencies, or a git URL of its public repository), CMake builds it once into
# ~/.cache/terrace/pfunit-4.14.0 (or $TERRACE_PFUNIT_PREFIX) and later builds reuse it.
# Usage: scripts/build.sh [extra cmake arguments, e.g. -DTERRACE_PORTABLE=ON]
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
args=()
pf="${PFUNIT_PREFIX:-/opt/pfunit}"
[[ -d "$pf" ]] && args+=(-DCMAKE_PREFIX_PATH="$pf")
[[ -n "${TERRACE_PFUNIT_SOURCE:-}" ]] && args+=(-DTERRACE_PFUNIT_SOURCE="$TERRACE_PFUNIT_SOURCE")
[[ -n "${TERRACE_PFUNIT_PREFIX:-}" ]] && args+=(-DTERRACE_PFUNIT_PREFIX="$TERRACE_PFUNIT_PREFIX")
if [[ -n "${TERRACE_PFUNIT_SOURCE:-}" ]]; then
  echo "build: pFUnit source: $TERRACE_PFUNIT_SOURCE (built once if no installed pFUnit is found: ~10 min on one core)"
fi
cmake -S "$repo" -B "$repo/build" -DCMAKE_BUILD_TYPE=Release "${args[@]}" "$@" > "$repo/.cmake-configure.log" 2>&1 || {
  cat "$repo/.cmake-configure.log" >&2; exit 1; }
grep -E "^-- Terrace" "$repo/.cmake-configure.log" | sed 's/^-- //' || true
cmake --build "$repo/build" -j "$(nproc)" ${BUILD_TARGET:+--target "$BUILD_TARGET"} > "$repo/.cmake-build.log" 2>&1 || { tail -40 "$repo/.cmake-build.log" >&2; exit 1; }
echo "build: $repo/build/terrace"
