#!/usr/bin/env bash
# Stress search of the event solver on random analytic rays (scripts/bench/solver/random_rays.f90: its
# header says which rays): builds the driver against a build's event-solver object and runs it.
# Usage: scripts/bench/solver_random_rays.sh [BUILD_DIR [NRAYS [SEED]]]   (defaults build, 20000, 12345)
# Or with an event_solver.f90 of another commit: SOLVER_SRC=FILE (compiled here with the build's modules,
# with SOLVER_FLAGS, default -O2: give the build's own, e.g. "-O3 -march=native -funroll-loops", to
# compare the checksum with the build's object).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
build="$(realpath "${1:-$repo/build}")"; nrays="${2:-20000}"; seed="${3:-12345}"
obj="$build/CMakeFiles/terrace_core.dir/src/integrators/event_solver.f90.o"
kinds="$build/CMakeFiles/terrace_core.dir/src/core/kinds.f90.o"
[[ -f "$obj" && -f "$kinds" ]] || { echo "solver_random_rays.sh: no build in $build (bash scripts/build.sh)" >&2; exit 1; }
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
if [[ -n "${SOLVER_SRC:-}" ]]; then
    gfortran ${SOLVER_FLAGS:--O2} -c -ffree-line-length-none -I"$build/modules" -J"$work" "$SOLVER_SRC" -o "$work/es.o"; obj="$work/es.o"
fi
gfortran -O2 -I"$work" -I"$build/modules" -J"$work" "$here/solver/random_rays.f90" "$obj" "$kinds" -o "$work/random_rays"
echo "event solver: $(realpath "${SOLVER_SRC:-$repo/src/integrators/event_solver.f90}") (commit $(git -C "$repo" rev-parse --short HEAD))"
"$work/random_rays" "$nrays" "$seed"
