#!/usr/bin/env bash
# How a core's speed depends on how many other cores are busy: independent one-rank runs of the LJ
# bench scene (input/lj_bench.nml, NS steps, default 300), one pinned to each CPU of a set, started
# together; prints each copy's Pair seconds. No MPI traffic at all, so a slower Pair with more busy
# CPUs is the machine's (shared cores, caches, memory or clock), not the code's communication.
# Sets: 0 alone; 0 1; 0 8; 0-3; the even CPUs; all 16. Two repeats. Needs 16 CPUs.
#
# Usage: scripts/bench/busy_cores.sh      Environment: TERRACE (binary, default build/terrace), NS,
#   MPIRUN (default mpirun). On the device machine: scripts/bench/bundle.sh run .device bash scripts/bench/busy_cores.sh
set -uo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
terrace="$(realpath "${TERRACE:-$repo/build/terrace}")"; mpirun="${MPIRUN:-mpirun}"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1
w="$(mktemp -d)"
pair_s() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" python3 -m terrace_tools.summary get "$1" timing/phases/Pair/avg_s; }
sed -e "s/n_steps=1000/n_steps=${NS:-300}/" "$repo/input/lj_bench.nml" > "$w/lj.nml"
echo "machine: $(lscpu | sed -n 's/^Model name: *//p' | head -1); $(getconf _NPROCESSORS_ONLN) CPUs; date $(date -u '+%F %T UTC'); $terrace"
echo "CPU 0's siblings: $(cat /sys/devices/system/cpu/cpu0/topology/thread_siblings_list 2>/dev/null); CPU 1's: $(cat /sys/devices/system/cpu/cpu1/topology/thread_siblings_list 2>/dev/null)"
for rep in 1 2; do
    for set in "0" "0 1" "0 8" "0 1 2 3" "$(seq -s ' ' 0 2 15)" "$(seq -s ' ' 0 15)"; do
        for c in $set; do
            mkdir -p "$w/$c"; cp "$w/lj.nml" "$w/$c/"
            (cd "$w/$c" && "$mpirun" --bind-to none -np 1 taskset -c "$c" "$terrace" lj.nml > log 2>&1) &
        done
        wait
        printf 'repeat %d, CPUs [%s]: Pair s' "$rep" "$set"
        for c in $set; do printf ' %.4f' "$(pair_s "$w/$c/lj.summary.json")"; done
        echo
    done
done
rm -rf "$w"
