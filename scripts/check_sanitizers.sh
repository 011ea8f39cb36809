#!/usr/bin/env bash
# The test suite under AddressSanitizer and UndefinedBehaviorSanitizer: a Release build (the same
# -O3 -march=native kernels, so the SIMD paths run) with -fsanitize=address,undefined on the C and
# the Fortran sources, then every CTest test but the two malformed-input sweeps, and those sweeps
# (tests/regression/check_bad_inputs.sh, its cases and the generated hostile ones) on one rank.
# Each process writes its sanitizer reports to a file of BUILD_DIR/reports; any report, or any test
# that fails, makes the exit status 1. Not part of scripts/test.sh: about 35 minutes on 2 vCPUs.
#
# Usage: scripts/check_sanitizers.sh [BUILD_DIR [CTEST_ARGS...]]   (default: build-sanitize beside build/;
#        CTEST_ARGS e.g. -R outer_list: only those tests, the two sweeps still)
# Needs what scripts/test.sh installs (libasan and libubsan come with gfortran); pFUnit as
# scripts/build.sh finds it (without it the unit tests are skipped, as there).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
dir="$(realpath -m "${1:-$repo/build-sanitize}")"
[[ $# -gt 0 ]] && shift
flags="-fsanitize=address,undefined -fno-omit-frame-pointer"
args=()
pf="${PFUNIT_PREFIX:-/opt/pfunit}"
[[ -d "$pf" ]] && args+=(-DCMAKE_PREFIX_PATH="$pf")
[[ -n "${TERRACE_PFUNIT_SOURCE:-}" ]] && args+=(-DTERRACE_PFUNIT_SOURCE="$TERRACE_PFUNIT_SOURCE")
mkdir -p "$dir"
cmake -S "$repo" -B "$dir" -DCMAKE_BUILD_TYPE=Release "${args[@]}" -DCMAKE_C_FLAGS="$flags" \
    -DCMAKE_Fortran_FLAGS="$flags" -DCMAKE_EXE_LINKER_FLAGS="-fsanitize=address,undefined" > "$dir/sanitize-configure.log" 2>&1 || {
    cat "$dir/sanitize-configure.log" >&2; exit 1; }
cmake --build "$dir" -j "$(nproc)" > "$dir/sanitize-build.log" 2>&1 || { tail -40 "$dir/sanitize-build.log" >&2; exit 1; }
reports="$dir/reports"
rm -rf "$reports"; mkdir -p "$reports"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# (Open MPI's own allocations are not this code's leaks; the hostile cases ask for more memory than
# the machine has, which the engine must refuse with its own error, not the sanitizer's)
export ASAN_OPTIONS="detect_leaks=0:allocator_may_return_null=1:log_path=$reports/asan"
export UBSAN_OPTIONS="print_stacktrace=1:log_path=$reports/ubsan"
rc=0
(cd "$dir" && ctest -j "$(nproc)" --timeout 1800 -E '^(hostile_inputs_.*|bad_inputs)$' --output-on-failure "$@") || rc=1
bash "$repo/tests/regression/check_bad_inputs.sh" "$dir/terrace" 1 | tail -1 || rc=1
bash "$repo/tests/regression/check_bad_inputs.sh" --hostile "$dir/terrace" 1 | tail -1 || rc=1
n=$(find "$reports" -type f | wc -l)
if [[ $n -gt 0 ]]; then
    echo "check_sanitizers: $n sanitizer report(s) in $reports:"
    find "$reports" -type f -exec head -20 {} \;
    rc=1
else
    echo "check_sanitizers: no sanitizer reports"
fi
exit $rc
