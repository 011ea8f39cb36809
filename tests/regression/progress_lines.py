#!/usr/bin/env python3
"""Progress lines on the screen between sparse thermo samples (&output progress_seconds).

A run whose thermo lines are far apart (or absent) still shows that it moves: when no screen line
has been printed for progress_seconds of wall time, rank 0 prints
'  progress: step N, time T UNIT  P%  eta S s'. Checked, for velocity Verlet and energy stepping on
NPROCS ranks:
  - lines appear in a run that lasts several progress intervals, and never more often than asked
    (at most loop time / progress_seconds + 1 of them), one per interval on one rank only;
  - their steps increase, their times are step x dt (Verlet) and increase, their percentages are
    time / run length;
  - progress_seconds = 0 prints none; the thermo file is byte-identical with and without them
    (printing changes nothing in the run).
usage: progress_lines.py TERRACE WORKDIR NPROCS
"""
import json
import os
import re
import shutil
import subprocess
import sys

terrace, work, nprocs = sys.argv[1], sys.argv[2], int(sys.argv[3])
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
os.chdir(work)
LINE = re.compile(r"^  progress: step (\d+), time (\S+) (\S+)\s+([\d.]+)%\s+eta\s+(\S+) s$")
DECKS = {
    'vv': ("&integrator style='velocity_verlet', dt=0.002 /", "n_steps=10000", 0.002),
    'es': ("&integrator style='energy_stepping', terrace_height=0.02 /", "run_time=2.0", None),
}


def deck(name, kind, progress):
    integ, length, _ = DECKS[kind]
    text = f"""&run units='lj', dimension=3, {length}, seed=5 /
&system lattice='fcc', density=0.8442, cells=3,3,3, mass=1.0, temperature=1.0 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.true. /
{integ}
&neighbor skin=0.3 /
&output thermo_every=1000000, thermo_file='{name}.csv', progress_seconds={progress} /
"""
    if kind == 'es':
        text = text.replace('thermo_every=1000000', 'thermo_interval=2.0')
    with open(name + '.nml', 'w') as f:
        f.write(text)


def run(name):
    cmd = ['mpirun', '--oversubscribe', '-np', str(nprocs), terrace, name + '.nml']
    p = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        sys.exit(f'{name}: exit {p.returncode}\n{p.stdout}\n{p.stderr}')
    with open(name + '.summary.json') as f:
        loop = json.load(f)['timing']['loop_time_s']
    return p.stdout, loop


fail = []
for kind, (_, length, dt) in DECKS.items():
    deck(kind + '_on', kind, 0.25)
    deck(kind + '_off', kind, 0)
    out_on, loop = run(kind + '_on')
    out_off, _ = run(kind + '_off')
    lines = [m for m in (LINE.match(s) for s in out_on.splitlines()) if m]
    other = [s for s in out_on.splitlines() if s.startswith('  progress:') and not LINE.match(s)]
    n = len(lines)
    print(f'{kind} on {nprocs} rank(s): loop {loop:.2f} s, {n} progress lines (interval 0.25 s)')
    if other:
        fail.append(f'{kind}: malformed progress lines: {other[:2]}')
    if loop > 1.5 and n < 1:
        fail.append(f'{kind}: no progress line in a {loop:.2f} s loop')
    if n > loop / 0.25 + 1:
        fail.append(f'{kind}: {n} progress lines in {loop:.2f} s, more than one per 0.25 s')
    steps = [int(m.group(1)) for m in lines]
    times = [float(m.group(2)) for m in lines]
    if steps != sorted(set(steps)) or times != sorted(times):
        fail.append(f'{kind}: steps or times do not increase: {steps} {times}')
    t_end = 2.0 if kind == 'es' else 10000 * dt
    for m, step, t in zip(lines, steps, times):
        if dt is not None and abs(t - step * dt) > 1e-5 * t:
            fail.append(f'{kind}: time {t} is not step x dt ({step} x {dt})')
        if abs(float(m.group(4)) - 100 * t / t_end) > 0.051:
            fail.append(f'{kind}: {m.group(4)} % for time {t} of {t_end}')
        if m.group(3) != 'tau':
            fail.append(f'{kind}: time unit {m.group(3)}, expected tau')
    if any(s.startswith('  progress:') for s in out_off.splitlines()):
        fail.append(f'{kind}: progress lines with progress_seconds = 0')
    with open(kind + '_on.csv', 'rb') as a, open(kind + '_off.csv', 'rb') as b:
        if a.read() != b.read():
            fail.append(f'{kind}: the thermo file differs with progress lines on')
for f in fail:
    print('FAIL:', f)
print('progress_lines:', 'FAIL' if fail else 'PASS')
sys.exit(1 if fail else 0)
