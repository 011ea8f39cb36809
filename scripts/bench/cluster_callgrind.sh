#!/usr/bin/env bash
# Instruction counts of energy stepping's event loop on the talk's seven-atom cluster
# (input/argon_frozen_2d.nml, all pairs, one rank), per event and split by what the loop does:
# ray passes (the pair work of the search), the event solver's own work (interval tests, Taylor and
# Halley steps), the force pass at each kick, frames and thermo samples, and the rest (the event's
# bookkeeping: gradient sums, jump, drift, calendar, timers). Counted by callgrind inside
# run_energy_stepping only (start-up and close excluded). Needs a -DTERRACE_PORTABLE=ON build
# (valgrind cannot run AVX-512). Several binaries: one line each, same deck.
# Usage: scripts/bench/cluster_callgrind.sh TERRACE [TERRACE2 ...]
# Environment: NS (simulated ns, default 2), FRAME_PS (trajectory interval in ps, default 10).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
[[ $# -ge 1 ]] || { echo "usage: $0 TERRACE [TERRACE2 ...]  (portable builds)" >&2; exit 2; }
command -v valgrind > /dev/null || { echo "cluster_callgrind: valgrind is not installed" >&2; exit 2; }
ns="${NS:-2}"; frame="${FRAME_PS:-10}"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
cp "$repo/input/argon_frozen_2d.atoms" "$work/"
sed -e "s/run_time=100000.0/run_time=${ns}000.0/" -e "s/trajectory_interval=10.0/trajectory_interval=${frame}/" \
    "$repo/input/argon_frozen_2d.nml" > "$work/cluster.nml"
echo "deck: input/argon_frozen_2d.nml, $ns ns, a frame every $frame ps; $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1); $(date -u '+%Y-%m-%d %H:%M UTC')"
for bin in "$@"; do
    b="$(realpath "$bin")"
    (cd "$work" && rm -f argon_frozen_2d.h5 argon_frozen_2d.csv cluster.summary.json cg.out &&
        valgrind --tool=callgrind --toggle-collect='__terrace_energy_stepping_MOD_run_energy_stepping' \
            --callgrind-out-file=cg.out "$b" cluster.nml > run.log 2> cg.err) || {
        echo "cluster_callgrind: $b failed under valgrind (a -march=native build? use -DTERRACE_PORTABLE=ON)" >&2
        tail -3 "$work/cg.err" >&2; exit 2; }
    callgrind_annotate --inclusive=yes --threshold=100 "$work/cg.out" > "$work/incl.txt" 2> /dev/null
    /usr/bin/python3 - "$work/incl.txt" "$work/cluster.summary.json" "$b" <<'PY'
import json, re, sys
incl, summary, binary = sys.argv[1:4]
ir = {}
for line in open(incl):
    m = re.match(r'\s*([\d,]+)\s+\([^)]*\)\s+\S*?:(\S+)', line)
    if m:
        name = m.group(2)
        ir[name] = max(ir.get(name, 0), int(m.group(1).replace(',', '')))
def get(pattern):
    return sum(v for k, v in ir.items() if re.fullmatch(pattern, k))
es = json.load(open(summary))['energy_stepping']
events, evals = es['events'], round(es['ray_evaluations_per_event'], 3)
loop = get(r'__terrace_energy_stepping_MOD_run_energy_stepping')
ray = get(r'__terrace_engine_MOD_engine_ray_pass')
solver = get(r'__terrace_event_solver_MOD_solver_first_crossing') - get(r'__terrace_event_solver_MOD_ray_eval_counted')
classify = get(r'__terrace_event_solver_MOD_classify(\..*)?')
force = get(r'__terrace_engine_MOD_engine_compute_forces')
frames = get(r'__terrace_energy_stepping_MOD_write_frame(\..*)?')
samples = get(r'__terrace_energy_stepping_MOD_write_sample(\..*)?')
rest = loop - ray - solver - force - frames - samples
per = lambda x: '{:,.0f}'.format(x / events)
print(f'{binary}: {events} events, {evals} ray evaluations per event; Ir per event:')
print(f'  loop {per(loop)} = ray passes {per(ray)} ({per(ray / evals)} each) + event solver {per(solver)} '
      f'(interval tests {per(classify)}) + force pass {per(force)} + frames {per(frames)} + samples {per(samples)} '
      f'+ rest {per(rest)}')
PY
done
