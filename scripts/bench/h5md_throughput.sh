#!/usr/bin/env bash
# H5MD output cost: the LAMMPS in.lj scene scaled to 256,000 atoms (fcc 40x40x40, rho* 0.8442,
# T* 1.44, lj/cut 2.5, skin 0.3, velocity Verlet dt 0.005) with a trajectory frame every 100 steps.
# For each field set and rank count it prints the file size, the Output timer of the run log (max
# over ranks: the frames are written collectively), the write throughput = file size / Output time
# (MB = 1e6 bytes) and the share of the loop time spent in Output; a run without a trajectory gives
# the baseline Output time (thermo sampling only) and loop time.
#
# Usage: scripts/bench/h5md_throughput.sh [NSTEPS [TERRACE_BINARY]]    (default 500 steps: 6 frames)
# Environment: NPS="1 2 4" (rank counts; default 1), REPEAT=N (best of N runs per row, default 1),
#              FIELDS="position,velocity;position,velocity,force,image" (field sets, ';'-separated),
#              CELLS=40 (fcc cells per edge: 4*CELLS^3 atoms), WORK=dir (default: a temporary
#              directory under $TMPDIR or /tmp, removed at the end; the files are large).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
# the run summary's figures (scripts/terrace_tools)
figure() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get "$@"; }
nsteps="${1:-500}"
terrace="$(realpath "${2:-$repo/build/terrace}")"
cells="${CELLS:-40}"
nps="${NPS:-1}"
repeat="${REPEAT:-1}"
fieldsets="${FIELDS:-position,velocity;position,velocity,force,image}"
natoms=$((4 * cells * cells * cells))
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1
if [[ -n "${WORK:-}" ]]; then work="$WORK"; mkdir -p "$work"; else
    work="$(mktemp -d "${TMPDIR:-/tmp}/h5md_throughput.XXXXXX")"; trap 'rm -rf "$work"' EXIT; fi

model="$(lscpu 2>/dev/null | sed -n 's/^Model name:[[:space:]]*//p' | head -n 1)"
echo "H5MD throughput: $natoms atoms, $nsteps steps, a frame every 100 steps ($((nsteps / 100 + 1)) frames)"
echo "machine : ${model:-unknown} ($(nproc) CPUs visible), $(df -h --output=source,fstype "$work" | tail -1)"
echo "date    : $(date -u '+%Y-%m-%d %H:%M:%S UTC')   commit $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "best of $repeat run(s) per row; Output = max over ranks of the run log's Output timer"
echo

deck() {   # deck FILE TRAJECTORY_LINE
    cat > "$1" <<NML
&run units='lj', dimension=3, n_steps=$nsteps, seed=87287 /
&system lattice='fcc', density=0.8442, cells=$cells,$cells,$cells, periodic=.true.,.true.,.true.,
        mass=1.0, temperature=1.44 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.false. /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&output thermo_every=100, thermo_file='' $2 /
NML
}

printf '%-32s %5s %10s %10s %10s %10s %8s\n' "fields" "ranks" "file (MB)" "loop (s)" "Output (s)" "MB/s" "Output %"
cd "$work"
for np in $nps; do
    launch=(); [[ "$np" -gt 1 ]] && launch=(mpirun --oversubscribe -np "$np")
    for fields in none ${fieldsets//;/ }; do
        if [[ "$fields" == none ]]; then
            deck run.nml ""
        else
            deck run.nml ", trajectory_file='traj.h5', trajectory_every=100, overwrite=.true., trajectory_fields='${fields//,/ }'"
        fi
        best=""
        for ((r = 1; r <= repeat; r++)); do
            rm -f traj.h5
            timeout 3000 "${launch[@]}" "$terrace" run.nml > run.log 2>&1 || { echo "terrace failed:"; tail -5 run.log; exit 1; }
            loop="$(figure run.summary.json timing/loop_time_s)"
            out="$(figure run.summary.json timing/phases/Output/max_s)"   # the slowest rank's
            if [[ -z "$best" ]] || awk -v a="$out" -v b="${best%% *}" 'BEGIN { exit !(a < b) }'; then
                best="$out $loop"
            fi
        done
        out="${best%% *}"; loop="${best##* }"
        size=0; [[ -f traj.h5 ]] && size="$(stat -c %s traj.h5)"
        awk -v f="${fields//,/ }" -v np="$np" -v s="$size" -v l="$loop" -v o="$out" 'BEGIN {
            mbs = (s > 0 && o > 0) ? sprintf("%10.1f", s / 1e6 / o) : sprintf("%10s", "-")
            printf "%-32s %5d %10.1f %10.2f %10.3f %s %8.1f\n", f, np, s / 1e6, l, o, mbs, 100 * o / l }'
    done
done
rm -f traj.h5
