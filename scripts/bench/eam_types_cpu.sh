#!/usr/bin/env bash
# EAM cost per pair of the multi-type paths against the one-type path, in CPU time: the
# scenes of anchors.sh part "types" (fcc Cu with Cu_u3.eam; random 50/50 Cu-Ni, all-Cu fcc with
# CuNi.eam.alloy, with one element and with both declared; 5 % Ni at random; bcc Fe with Fe_mm.eam.fs; fcc Cu with
# Cu_mishin1.eam.alloy), each Terrace binary
# given, alternating, REPEAT rounds. The cost is the CPU time that `perf record -e cpu-clock` samples
# (1 kHz) in the EAM kernels (symbols __terrace_eam_MOD_*: density, embedding, force passes) per step
# and per pair within rc + skin (LAMMPS's half list, from anchors.sh's LAMMPS runs). Unlike the
# "Pair" phase's wall time, CPU samples do not count the time another process holds the core, so
# the ratios hold under load (what remains is the sharing of caches and of the core's other thread).
# KIND=lj: the same for the LJ mixtures, the scenes of anchors.sh part "ljtypes" (one type, two and
# three identical types at random, the Kob-Andersen mixture), the samples in the LJ kernels (symbols
# __terrace_lj_MOD_*), against lj_one.
#
# Usage: [KIND=eam|lj] scripts/bench/eam_types_cpu.sh NSTEPS TERRACE_BINARY...   (REPEAT rounds, default 3)
# Needs perf, lmp and the lammps-data potentials (as anchors.sh).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
[[ $# -ge 2 && "$1" =~ ^[1-9][0-9]*$ ]] || { echo "usage: $0 NSTEPS TERRACE_BINARY..." >&2; exit 2; }
nsteps=$1; shift
bins=(); for b in "$@"; do bins+=("$(realpath "$b")"); done
repeat="${REPEAT:-3}"
case "${KIND:-eam}" in
    eam) part=types; sym=__terrace_eam_MOD_; steps=(1 "$nsteps"); what='EAM kernels'; label=Cu ;;
    lj)  part=ljtypes; sym=__terrace_lj_MOD_; steps=("$nsteps" 1); what='LJ kernels'; label=one ;;
    *)   echo "eam_types_cpu: KIND must be eam or lj, not '$KIND'" >&2; exit 2 ;;
esac
command -v perf > /dev/null || { echo "eam_types_cpu: perf not found" >&2; exit 2; }
# the scenes and pair counts: one round of anchors.sh part $part (kept work directory)
log="$(mktemp)"
KEEP=1 REPEAT=1 PARTS=$part bash "$here/anchors.sh" "${steps[@]}" "${bins[0]}" > "$log"
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
                 | awk -v sym="$sym" 'index($0, sym) {s += $2} END {print s + 0}')
            echo "$k $name $ms" >> cpu.txt
        done < $part.txt
    done
done
python3 - "$nsteps" "$part.txt" "$what" "$label" "${bins[@]}" <<'PY'
import sys, re, statistics as st
nsteps, listfile, what, label, bins = int(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5:]
ms = {}
for line in open('cpu.txt'):
    k, name, v = line.split()
    ms.setdefault((int(k), name), []).append(float(v))
names = [l.split()[0] for l in open(listfile)]
pairs = {}
for name in names:
    log = open('l_%s.best.log' % name).read()
    nb = [int(x) for x in re.findall(r'^Total # of neighbors = (\d+)', log, re.M)]
    pairs[name] = 0.5 * (nb[-2] + nb[-1])
print('%s, CPU ns per step per pair within rc + skin (best / median of %d rounds); vs %s = / %s'
      % (what, len(ms[(0, names[0])]), label, names[0]))
for k, b in enumerate(bins):
    print('binary %d: %s' % (k, b))
    print('  %-13s %10s %10s %8s %8s' % ('scene', 'ns best', 'ns median', 'vs ' + label, 'vs %s med' % label))
    ref = None
    for name in names:
        v = ms[(k, name)]
        best, med = (1e6 * x / (nsteps * pairs[name]) for x in (min(v), st.median(v)))
        if ref is None:
            ref = (best, med)
        print('  %-13s %10.3f %10.3f %8.2f %8.2f' % (name, best, med, best / ref[0], med / ref[1]))
PY
