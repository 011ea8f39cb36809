#!/usr/bin/env bash
# Failure detection: an unstable run must stop on every rank with exit status 1 and one clear error
# line on stderr (no hang, no crash, no garbage written as if all were well).
# Usage: tests/regression/failure_detection.sh TERRACE_BINARY DECK OUTDIR NP 'expected text'
set -uo pipefail
[[ $# -eq 5 ]] || { echo "usage: $0 TERRACE_BINARY DECK OUTDIR NP 'expected text'" >&2; exit 2; }
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
terrace="$(realpath "$1")"; deck="$2"; out="$3"; np="$4"; want="$5"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
rm -rf "$out"; mkdir -p "$out"
sed "s#@REPO@#$repo#g" "$deck" > "$out/deck.nml"
(cd "$out" && timeout 60 mpirun --oversubscribe -np "$np" "$terrace" deck.nml > terrace.log 2> terrace.err)
rc=$?
fail=0
[[ $rc -eq 1 ]] || { echo "FAIL: exit status $rc (want 1; 124 = hang)"; fail=1; }
errs=$(grep -c '^terrace: error: ' "$out/terrace.err")
[[ $errs -eq 1 ]] || { echo "FAIL: $errs 'terrace: error:' lines on stderr (want exactly 1)"; fail=1; }
grep -q -- "$want" "$out/terrace.err" || { echo "FAIL: the error does not say '$want'"; fail=1; }
if grep -Eqi 'backtrace|segmentation|sigsegv|floating-point exception' "$out/terrace.err" "$out/terrace.log"; then
    echo "FAIL: crash output"; fail=1
fi
echo "exit $rc; stderr:"; cat "$out/terrace.err"
[[ $fail -eq 0 ]] && echo PASS
exit $fail
