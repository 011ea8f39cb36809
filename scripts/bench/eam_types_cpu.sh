#!/usr/bin/env bash
# EAM cost per pair of the multi-type paths against the one-type path, in CPU time (issue 16): the
# scenes of anchors.sh part "types" (fcc Cu with Cu_u3.eam; random 50/50 Cu-Ni, all-Cu fcc with
# CuNi.eam.alloy, with one element and with both declared; 5 % Ni at random; bcc Fe with Fe_mm.eam.fs; fcc Cu with
# Cu_mishin1.eam.alloy), each Terrace binary
# given, alternating, REPEAT rounds. The cost is the CPU time that `perf record -e cpu-clock` samples
# (1 kHz) in the EAM kernels (symbols __terrace_eam_MOD_*: density, embedding, force passes) per step
# and per pair within rc + skin (LAMMPS's half list, from anchors.sh's LAMMPS runs). Unlike the
# "Pair" phase's wall time, CPU samples do not count the time another process holds the core, so
# the ratios hold under load (what remains is the sharing of caches and of the core's other thread).
#
# Usage: scripts/bench/eam_types_cpu.sh NSTEPS TERRACE_BINARY...   (REPEAT rounds, default 3)
# Needs perf, lmp and the lammps-data potentials (as anchors.sh).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
[[ $# -ge 2 && "$1" =~ ^[1-9][0-9]*$ ]] || { echo "usage: $0 NSTEPS TERRACE_BINARY..." >&2; exit 2; }
nsteps=$1; shift
bins=(); for b in "$@"; do bins+=("$(realpath "$b")"); done
repeat="${REPEAT:-3}"
command -v perf > /dev/null || { echo "eam_types_cpu: perf not found" >&2; exit 2; }
# the scenes and pair counts: one round of anchors.sh part types (kept work directory)
log="$(mktemp)"
KEEP=1 REPEAT=1 PARTS=types bash "$here/anchors.sh" 1 "$nsteps" "${bins[0]}" > "$log"
work="$(sed -n 's/^work dir: //p' "$log")"
[[ -d "$work" ]] || { echo "eam_types_cpu: anchors.sh failed:" >&2; cat "$log" >&2; exit 1; }
trap 'rm -rf "$work" "$log"' EXIT
sed -n '/^machine\|^date\|^load\|^compiler/p' "$log"
echo "commit  : $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
cd "$work"
: > cpu.txt
for ((rep = 1; rep <= repeat; rep++)); do
    for k in "${!bins[@]}"; do
        while read -r name style file; do
            perf record -q -F 1000 -e cpu-clock -o perf.data "${bins[$k]}" "$name.nml" > perf.out 2>&1 \
                || { echo "eam_types_cpu: $name failed" >&2; tail perf.out >&2; exit 1; }
            ms=$(perf report -i perf.data --stdio -n --sort symbol 2> /dev/null \
                 | awk '/__terrace_eam_MOD_/ {s += $2} END {print s + 0}')
            echo "$k $name $ms" >> cpu.txt
        done < types.txt
    done
done
python3 - "$nsteps" "${bins[@]}" <<'PY'
import sys, re, statistics as st
nsteps, bins = int(sys.argv[1]), sys.argv[2:]
ms = {}
for line in open('cpu.txt'):
    k, name, v = line.split()
    ms.setdefault((int(k), name), []).append(float(v))
names = [l.split()[0] for l in open('types.txt')]
pairs = {}
for name in names:
    log = open('l_%s.best.log' % name).read()
    nb = [int(x) for x in re.findall(r'^Total # of neighbors = (\d+)', log, re.M)]
    pairs[name] = 0.5 * (nb[-2] + nb[-1])
print('EAM kernels, CPU ns per step per pair within rc + skin (best / median of %d rounds); vs Cu = / cu_u3' % len(ms[(0, names[0])]))
for k, b in enumerate(bins):
    print('binary %d: %s' % (k, b))
    print('  %-11s %10s %10s %8s %8s' % ('scene', 'ns best', 'ns median', 'vs Cu', 'vs Cu med'))
    ref = None
    for name in names:
        v = ms[(k, name)]
        best, med = (1e6 * x / (nsteps * pairs[name]) for x in (min(v), st.median(v)))
        if ref is None:
            ref = (best, med)
        print('  %-11s %10.3f %10.3f %8.2f %8.2f' % (name, best, med, best / ref[0], med / ref[1]))
PY
