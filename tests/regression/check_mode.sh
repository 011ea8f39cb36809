#!/usr/bin/env bash
# `terrace --check DECK` must print the scene plan and 'check: OK', exit 0 and write no file.
set -euo pipefail
[[ $# -eq 3 ]] || { echo "usage: $0 TERRACE_BINARY DECK OUTDIR" >&2; exit 2; }
terrace="$(realpath "$1")"; out="$3"
rm -rf "$out"; mkdir -p "$out"; cp "$2" "$out/deck.nml"
cd "$out"
"$terrace" --check deck.nml > ../check_mode.log 2>&1 || { echo "FAIL: --check exited non-zero"; cat ../check_mode.log; exit 1; }
grep -q "^scene plan:" ../check_mode.log || { echo "FAIL: no scene plan printed"; exit 1; }
grep -q "^check: OK" ../check_mode.log || { echo "FAIL: no 'check: OK'"; exit 1; }
extra=$(ls -A | grep -v '^deck.nml$' || true)
[[ -z "$extra" ]] || { echo "FAIL: --check wrote files: $extra"; exit 1; }
cat ../check_mode.log
echo "PASS"
