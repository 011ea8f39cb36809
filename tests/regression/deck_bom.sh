#!/usr/bin/env bash
# A deck saved with a UTF-8 byte-order mark (as editors on Windows save it) runs as the same deck
# without one: exit 0 and the same thermo CSV and forces file byte for byte.
# usage: deck_bom.sh TERRACE OUTDIR
set -u
terrace=$(readlink -f "$1"); out=$2
rm -rf "$out"; mkdir -p "$out/plain" "$out/bom"
deck=$(dirname "$0")/bad_inputs/control_ok/control_ok.nml
cp "$deck" "$out/plain/run.nml"
{ printf '\xef\xbb\xbf'; cat "$deck"; } > "$out/bom/run.nml"
[ "$(head -c 3 "$out/bom/run.nml" | od -An -tx1 | tr -d ' ')" = efbbbf ] || { echo "FAIL the deck has no BOM"; exit 1; }
for d in plain bom; do
    (cd "$out/$d" && "$terrace" run.nml > run.log 2>&1) || { echo "FAIL the $d deck exited $?:"; tail -3 "$out/$d/run.log"; exit 1; }
done
for f in thermo.csv forces.txt; do
    [ -s "$out/bom/$f" ] || { echo "FAIL the deck with a BOM wrote no $f"; exit 1; }
    cmp -s "$out/plain/$f" "$out/bom/$f" || { echo "FAIL $f differs between the decks with and without a BOM"; exit 1; }
done
echo "PASS a deck with a UTF-8 byte-order mark runs as without one (thermo.csv and forces.txt byte for byte)"
