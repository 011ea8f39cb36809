#!/usr/bin/env bash
# End-to-end runs with trajectories, as the decks in input/ are (their own sampling), on 1 rank:
#   frozen7       input/argon_frozen_2d.nml        seven-atom 2-D cluster, energy stepping, 100 ns
#   frozen7_vv    input/argon_frozen_2d_verlet.nml the same with Verlet 10 fs, 100 ns
#   ico147_vv     input/argon_ico147_verlet.nml    147-atom 3-D cluster, Verlet 10 fs, 100 ns
#   ico147_cold   input/argon_ico147_cold.nml      147-atom cluster at 10 K, energy stepping, 1 ns
#   ico147_warm   input/argon_ico147_warm.nml      147-atom cluster at 40 K, energy stepping, 1 ns
#   ico147_es100  input/argon_ico147_cold.nml run for 100 ns with a frame every 10 ps (not in the
#                 default set: about half an hour here)
#   argon864      input/argon_nvt_100ns.nml, Rahman's liquid argon (864 atoms, Verlet 10 fs, CSVR),
#                 100 ns from the liquid input/argon_nvt.nml leaves (run first, its time not counted);
#                 also prints the run log's energy drift (not in the default set: about 17 minutes)
# and prints, per run: simulated time, wall time of the process, loop time, the Output timer and its
# share, frames in the trajectory (checked to be at the requested times), file size, bytes per frame.
# For the 1 ns energy-stepping runs the line "100 ns estimate" scales the loop time by 100.
#
# Usage: scripts/bench/h5md_100ns.sh [RUN...] (default: all five, about 10 min on the 2-vCPU dev box)
# Environment: TERRACE (binary, default build/terrace), WORK (directory kept; default a temporary one).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
# the run summary's figures (scripts/terrace_tools)
figure() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get "$@"; }
terrace="$(realpath "${TERRACE:-$repo/build/terrace}")"
PYTHON="${PYTHON:-/usr/bin/python3}"
runs=("$@"); [[ ${#runs[@]} -gt 0 ]] || runs=(frozen7 frozen7_vv ico147_vv ico147_cold ico147_warm)
if [[ -n "${WORK:-}" ]]; then work="$WORK"; mkdir -p "$work"; else
    work="$(mktemp -d "${TMPDIR:-/tmp}/h5md_100ns.XXXXXX")"; trap 'rm -rf "$work"' EXIT; fi
cp "$repo/input/argon_frozen_2d.atoms" "$repo/input/argon_ico147.atoms" "$work/"

model="$(lscpu 2>/dev/null | sed -n 's/^Model name:[[:space:]]*//p' | head -n 1)"
echo "End-to-end runs with trajectories (1 rank)"
echo "machine : ${model:-unknown} ($(nproc) CPUs visible)"
echo "date    : $(date -u '+%Y-%m-%d %H:%M:%S UTC')   commit $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo
printf '%-12s %-10s %9s %9s %9s %8s %8s %10s %10s\n' run simulated "wall (s)" "loop (s)" "Output s" "Output%" frames "file (MB)" "B/frame"
cd "$work"
for run in "${runs[@]}"; do
    case "$run" in
        frozen7) deck=argon_frozen_2d ;;
        frozen7_vv) deck=argon_frozen_2d_verlet ;;
        ico147_vv) deck=argon_ico147_verlet ;;
        ico147_cold) deck=argon_ico147_cold ;;
        ico147_warm) deck=argon_ico147_warm ;;
        ico147_es100) deck=argon_ico147_cold_100ns ;;
        argon864) deck=argon_nvt_100ns ;;
        *) echo "unknown run $run" >&2; exit 2 ;;
    esac
    if [[ "$run" == ico147_es100 ]]; then
        sed "s/run_time=1000.0/run_time=100000.0/; s/thermo_interval=10.0/thermo_interval=1000.0/;
             s/trajectory_interval=1.0/trajectory_interval=10.0/; s/argon_ico147_cold\./$deck./g" \
            "$repo/input/argon_ico147_cold.nml" > "$deck.nml"
    else
        cp "$repo/input/$deck.nml" .
    fi
    if [[ "$run" == argon864 ]]; then      # the equilibrated liquid the deck starts from
        cp "$repo/input/argon_nvt.nml" .
        rm -f argon_nvt.csv argon_nvt_eq.atoms
        find . -maxdepth 1 -name "$deck.*" ! -name "$deck.nml" -delete    # (a kept WORK: outputs of a run before)
        "$terrace" argon_nvt.nml > argon_nvt.log 2>&1 || { echo "$run: input/argon_nvt.nml failed"; tail -3 argon_nvt.log; exit 1; }
    fi
    rm -f "$deck.h5"
    t0=$(date +%s.%N)
    "$terrace" "$deck.nml" > "$deck.log" 2>&1 || { echo "$run: terrace failed"; tail -3 "$deck.log"; exit 1; }
    t1=$(date +%s.%N)
    loop="$(figure "$deck.summary.json" timing/loop_time_s)"
    out="$(figure "$deck.summary.json" timing/phases/Output/max_s)"   # the slowest rank's
    "$PYTHON" - "$deck.nml" "$deck.h5" "$run" "$t0" "$t1" "$loop" "$out" <<'PY'
import os, re, sys
import h5py
import numpy as np
deck, path, run, t0, t1, loop, out = sys.argv[1:8]
text = open(deck).read()
run_time = float(re.search(r"run_time=([0-9.]+)", text).group(1))
interval = float(re.search(r"trajectory_interval=([0-9.]+)", text).group(1))
with h5py.File(path, "r") as f:
    t = f["particles/all/position/time"][:]
    nf = len(t)
expected = np.arange(0, run_time + interval / 2, interval)
ok = nf == len(expected) and np.allclose(t, expected, rtol=1e-12, atol=1e-9 * run_time)
size = os.path.getsize(path)
wall, loop, out = float(t1) - float(t0), float(loop), float(out)
sim = f"{run_time / 1000:g} ns"
print(f"{run:12s} {sim:10s} {wall:9.1f} {loop:9.1f} {out:9.2f} {100 * out / loop:8.1f} {nf:8d} {size / 1e6:10.2f} "
      f"{size / nf:10.0f}" + ("" if ok else "   FRAME TIMES WRONG"))
if run_time < 1e5:
    print(f"{'':12s} 100 ns estimate: {loop * 1e5 / run_time / 3600:.1f} h of loop time at this rate")
sys.exit(0 if ok else 1)
PY
    [[ "$run" == argon864 ]] && grep -E '^Energy drift' "$deck.log" | sed 's/^/             /'
done
