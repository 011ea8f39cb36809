#!/usr/bin/env bash
# Time and memory of terrace-analyze on a 100 ns trajectory: the talk's seven-atom 2-D argon cluster
# (input/argon_frozen_2d.nml, energy stepping, 100 ns) with a frame (positions and velocities) every
# ps: 100001 frames. Prints the run's and the analysis's wall time and maximum resident set size
# (/usr/bin/time -v) for the VDOS (20 ps correlation), the pair-distance histogram of the free
# cluster and the MSD, on 1 rank and on NP ranks.
#
# usage: bash scripts/bench/analysis_100ns.sh [BUILD_DIR] [WORK_DIR] [NP]
#        REUSE=1 ... : keep WORK_DIR/cluster_100ns.h5 from an earlier run (skip the engine run)
set -euo pipefail
here=$(cd "$(dirname "$0")/../.." && pwd)
build=$(readlink -f "${1:-$here/build}")
work=${2:-/tmp/terrace_analysis_100ns}
np=${3:-2}
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
mkdir -p "$work"
cd "$work"
cp "$here/input/argon_frozen_2d.atoms" .
sed -e "s|thermo_file='argon_frozen_2d.csv'|thermo_file='cluster.csv', trajectory_file='cluster_100ns.h5', trajectory_interval=1.0, trajectory_fields='position velocity', overwrite=.true.|" \
    "$here/input/argon_frozen_2d.nml" > cluster_100ns.nml
if [ "${REUSE:-0}" != 1 ] || [ ! -f cluster_100ns.h5 ]; then
    /usr/bin/time -v "$build/terrace" cluster_100ns.nml > run.log 2> run.time
fi
echo "run:      $(grep -E 'Elapsed' run.time | sed 's/.*: //') wall, max RSS $(grep 'Maximum resident' run.time | awk '{print $NF}') KiB; loop time" \
     "$(PYTHONPATH="$here/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get cluster_100ns.summary.json timing/loop_time_s) s"
ls -l cluster_100ns.h5 | awk '{printf "trajectory: %s bytes\n", $5}'
for n in 1 "$np"; do
    launcher=()
    [ "$n" -gt 1 ] && launcher=(mpirun --oversubscribe -np "$n")
    /usr/bin/time -v "${launcher[@]}" "$build/terrace-analyze" --trajectory_file=cluster_100ns.h5 \
        --compute=vdos,rdf,msd --correlation_time=20 --rdf_bins=400 --output_prefix=cluster_np$n > analyze_np$n.log 2> analyze_np$n.time
    echo "analysis on $n rank(s): $(grep -E 'Elapsed' analyze_np$n.time | sed 's/.*: //') wall, max RSS $(grep 'Maximum resident' analyze_np$n.time | awk '{print $NF}') KiB (largest process); $(grep 'Analysis time' analyze_np$n.log)"
done
grep -E "frames:|peak|D =" analyze_np1.log
