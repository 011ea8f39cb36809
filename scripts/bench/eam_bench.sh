#!/usr/bin/env bash
# EAM benchmark: LAMMPS's in.eam scene (32,000 Cu atoms, Cu_u3.eam, 1600 K, dt 5 fs, skin 1 A) in
# LAMMPS (scripts/bench/in.eam_bench) and in Terrace (the same scene as a namelist), one rank each.
# LAMMPS's bench input rebuilds every 5 steps when needed; here both rebuild on the skin/2 check.
# Usage: scripts/bench/eam_bench.sh [NSTEPS [TERRACE_BINARY]]   (defaults 1000, build/terrace)
# REPEAT=N runs the pair (LAMMPS then Terrace, back to back) N times and compares the best loop time
# of each (for shared, noisy machines; default 1). With GNU time (/usr/bin/time) each run also shows
# the user CPU time of the process, and the ratio of the best user times is printed too (less
# sensitive to other load than wall time; it includes the set-up of both codes).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
# the run summary's figures (scripts/terrace_tools)
figure() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get "$@"; }
nsteps="${1:-1000}"; terrace="$(realpath "${2:-$repo/build/terrace}")"; repeat="${REPEAT:-1}"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
cd "$work"
ncores="$(nproc)"; export OMP_NUM_THREADS=1
cat > eam.nml <<NML
&run units='metal', dimension=3, n_steps=$nsteps, seed=376847 /
&system lattice='fcc', lattice_constant=3.615, cells=20,20,20, periodic=.true.,.true.,.true., temperature=1600.0 /
&potential style='eam', file='/usr/share/lammps/potentials/Cu_u3.eam' /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=1.0 /
&output thermo_every=50 /
NML
echo "EAM benchmark: 32000 Cu atoms, $nsteps steps, 1 rank, best of $repeat"
echo "machine : $(lscpu | sed -n 's/^Model name: *//p' | head -1) ($ncores cores visible)"
echo "date    : $(date -u '+%Y-%m-%d %H:%M:%S UTC')"
echo "commit  : $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "load    : $(cut -d' ' -f1-3 /proc/loadavg) (load average at start)"
timer=(); if [[ -x /usr/bin/time ]]; then timer=(/usr/bin/time -f '%U' -o user.txt); fi
user() { if [[ -s user.txt ]]; then tail -n 1 user.txt; else echo 0; fi; }
: > runs.txt
for ((rep = 1; rep <= repeat; rep++)); do
    rm -f user.txt
    "${timer[@]}" lmp -in "$here/in.eam_bench" -var nsteps "$nsteps" -log lammps.log -screen none
    tl=$(sed -n 's/^Loop time of \([0-9.eE+-]*\).*/\1/p' lammps.log | tail -1); ul=$(user)
    rm -f user.txt
    "${timer[@]}" "$terrace" eam.nml > terrace.log
    tt=$(figure eam.summary.json timing/loop_time_s); ut=$(user)
    echo "$tl $tt $ul $ut" >> runs.txt
    if [[ $rep == 1 ]] || awk -v a="$tt" -v b="$(cat best_t 2>/dev/null || echo 1e30)" 'BEGIN{exit !(a < b)}'; then
        echo "$tt" > best_t; cp terrace.log best_terrace.log; cp eam.summary.json best_terrace.summary.json
    fi
done
python3 - "$nsteps" <<'PY'
import sys
n = int(sys.argv[1])
runs = [[float(x) for x in line.split()] for line in open('runs.txt')]
for k, (tl, tt, ul, ut) in enumerate(runs, 1):
    print(f"run {k}   : LAMMPS loop {tl:9.3f} s (user {ul:7.2f} s)   Terrace loop {tt:9.3f} s (user {ut:7.2f} s)"
          f"   ratio {tl/tt:.3f}")
tl, tt = min(r[0] for r in runs), min(r[1] for r in runs)
print(f"LAMMPS  : loop time {tl:10.4f} s   {32000*n/tl:.4e} atom-steps/s (best)")
print(f"Terrace : loop time {tt:10.4f} s   {32000*n/tt:.4e} atom-steps/s (best)")
print(f"ratio   : Terrace/LAMMPS = {tl/tt:.3f} (best loop times; >1 means Terrace is faster)")
ul, ut = min(r[2] for r in runs), min(r[3] for r in runs)
if ul > 0 and ut > 0:
    print(f"ratio   : Terrace/LAMMPS = {ul/ut:.3f} (best user CPU times of the whole processes)")
PY
PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary show best_terrace.summary.json \
    timing/phases/Pair timing/phases/Neigh timing/phases/Comm timing/phases/Other neighbor/builds
