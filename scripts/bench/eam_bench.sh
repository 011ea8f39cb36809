#!/usr/bin/env bash
# EAM benchmark: LAMMPS's in.eam scene (32,000 Cu atoms, Cu_u3.eam, 1600 K, dt 5 fs, skin 1 A) in
# LAMMPS (scripts/bench/in.eam_bench) and in Terrace (the same scene as a namelist), one rank each.
# LAMMPS's bench input rebuilds every 5 steps when needed; here both rebuild on the skin/2 check.
# Usage: scripts/bench/eam_bench.sh [NSTEPS [TERRACE_BINARY]]   (defaults 1000, build/terrace)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
nsteps="${1:-1000}"; terrace="$(realpath "${2:-$repo/build/terrace}")"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
cd "$work"
cat > eam.nml <<NML
&run units='metal', dimension=3, n_steps=$nsteps, seed=376847 /
&system lattice='fcc', lattice_constant=3.615, cells=20,20,20, periodic=.true.,.true.,.true., temperature=1600.0 /
&potential style='eam', file='/usr/share/lammps/potentials/Cu_u3.eam' /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=1.0 /
&output thermo_every=50 /
NML
echo "EAM benchmark: 32000 Cu atoms, $nsteps steps, 1 rank"
echo "machine : $(lscpu | sed -n 's/^Model name: *//p' | head -1) ($(nproc) cores visible)"
echo "date    : $(date -u '+%Y-%m-%d %H:%M:%S UTC')"
echo "commit  : $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
lmp -in "$here/in.eam_bench" -var nsteps "$nsteps" -log lammps.log -screen none
tl=$(sed -n 's/^Loop time of \([0-9.eE+-]*\).*/\1/p' lammps.log | tail -1)
"$terrace" eam.nml > terrace.log
tt=$(sed -n 's/^Loop time: *\([0-9.eE+-]*\) s.*/\1/p' terrace.log | tail -1)
python3 - "$tl" "$tt" "$nsteps" <<'PY'
import sys
tl, tt, n = float(sys.argv[1]), float(sys.argv[2]), int(sys.argv[3])
print(f"LAMMPS  : loop time {tl:10.4f} s   {32000*n/tl:.4e} atom-steps/s")
print(f"Terrace : loop time {tt:10.4f} s   {32000*n/tt:.4e} atom-steps/s")
print(f"ratio   : Terrace/LAMMPS = {tl/tt:.3f} (>1 means Terrace is faster)")
PY
grep -E "^(Pair|Neigh|Comm|Other) |^Neighbour list builds" terrace.log
