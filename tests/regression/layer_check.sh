#!/usr/bin/env bash
# The layer check (scripts/check_layers.py) passes on this tree, and fails, naming the file, line
# and both layers, on a copy of it with one planted wrong-way import (a potential that uses the
# deck's module) and on one with config_t named in the engine.
# usage: layer_check.sh REPO WORKDIR
set -u
repo=$1; work=$2
py=/usr/bin/python3; [ -x "$py" ] || py=python3
out=$("$py" "$repo/scripts/check_layers.py" "$repo"); rc=$?
echo "$out" | tail -3
[ $rc -eq 0 ] || { echo "FAIL: the layer check fails on the tree"; exit 1; }
rm -rf "$work"; mkdir -p "$work/tree"
cp -r "$repo/src" "$repo/doc" "$work/tree/"
sed -i '0,/^    use terrace_kinds/s//    use terrace_config, only: config_t\n    use terrace_kinds/' "$work/tree/src/potentials/lj.f90"
out=$("$py" "$repo/scripts/check_layers.py" "$work/tree"); rc=$?
echo "$out"
[ $rc -eq 1 ] || { echo "FAIL: a planted wrong-way import passed (exit $rc)"; exit 1; }
echo "$out" | grep -q "src/potentials/lj.f90:[0-9]*: uses terrace_config (layer 'input', src/input) from layer 'potentials'" \
  || { echo "FAIL: the wrong-way import is not reported with its file, line and layers"; exit 1; }
cp "$repo/src/potentials/lj.f90" "$work/tree/src/potentials/lj.f90"
sed -i 's/^\(        integer :: dimension = 3\)$/\1\n        type(config_t), pointer :: deck => null()/' "$work/tree/src/engine/engine.f90"
out=$("$py" "$repo/scripts/check_layers.py" "$work/tree"); rc=$?
[ $rc -eq 1 ] && echo "$out" | grep -q "src/engine/engine.f90:[0-9]*: names config_t" \
  || { echo "FAIL: config_t named in the engine passed (exit $rc)"; echo "$out"; exit 1; }
echo "layer check: passes on the tree, fails on both planted violations"
