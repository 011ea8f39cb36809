#!/usr/bin/env python3
"""Energy stepping with EAM against velocity Verlet: cost at comparable energy error (one rank).

Scene: fcc Cu with Foiles' Cu_u3.eam (LAMMPS's potentials directory), N = 4 n^3 atoms (n = --cells,
default 3: 108 atoms, the smallest periodic box the 4.95 A cutoff allows), skin 1 A. Velocity Verlet
at 2 fs melts nothing but equipartitions the lattice start (600 K -> ~300 K) for 2 ps and writes the
state; from that state
  - velocity Verlet runs 10 x --length ps at each dt of --dts (fs), sampling every step (a Verlet
    step of 108 atoms takes ~0.1 ms: the longer run makes its loop time measurable);
  - energy stepping runs --length ps at each h of --hs (eV), sampling every 10 fs.
For each run: mean step (Verlet dt, or the mean event interval), max |E(t) - E0| over the samples
(E = K + V; for energy stepping the band |K + V - E0| <= h of the method), ray evaluations and force
passes per event, the loop time per step or event (the "Output" phase of the run log subtracted:
Verlet writes a line every step here), and the wall time per simulated ps. An event's cost in
Verlet steps is its loop time over that of a Verlet step at 2 fs.

Usage:  /usr/bin/python3 scripts/bench/eam_es_cost.py [--terrace PATH] [--cells 3] [--length 1.0]
            [--dts 1,2,5] [--hs 1.5e-3,3e-3,6e-3] [--repeat N]
Run time: about 2 minutes on the 2-vCPU dev box at the defaults. --repeat N repeats each timed run
and keeps the fastest (the machine may be shared).
"""
import argparse
import csv
import datetime
import os
import platform
import re
import shutil
import subprocess
import sys
import tempfile

import es_cost                      # (shared run-figure reader and shell helper)
from es_cost import sh

REPO = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..'))
POT = '/usr/share/lammps/potentials/Cu_u3.eam'
A0 = 3.615
KB = 8.617343e-5

EQ = """\
&run units='metal', dimension=3, run_time=2.0, seed=2021 /
&system lattice='fcc', lattice_constant={a0}, cells={n},{n},{n}, periodic=.true.,.true.,.true., temperature=600.0 /
&potential style='eam', file='{pot}' /
&integrator style='velocity_verlet', dt=0.002 /
&neighbor skin=1.0 /
&output thermo_interval=0.5, thermo_file='eq.csv', final_atoms_file='eq.atoms', overwrite=.true. /
"""
RUN = """\
&run units='metal', dimension=3, run_time={length}, seed=1 /
&system atoms_file='eq.atoms', box_lo=0.0,0.0,0.0, box_hi={L!r},{L!r},{L!r}, periodic=.true.,.true.,.true. /
&potential style='eam', file='{pot}' /
&neighbor skin=1.0 /
{integrator}
&output {sampling}, thermo_file='{name}.csv', overwrite=.true. /
"""


def parse_log(out, summary_path):
    """es_cost.py's figures (loop time, phases, event statistics: the run summary's)."""
    return es_cost.parse_log(out, summary_path)


def run(terrace, work, name, text, repeat=1):
    path = os.path.join(work, name + '.nml')
    with open(path, 'w') as f:
        f.write(text)
    best = None
    for _ in range(max(1, repeat)):
        p = subprocess.run([terrace, name + '.nml'], cwd=work, capture_output=True, text=True, timeout=3600)
        with open(os.path.join(work, name + '.log'), 'w') as f:
            f.write(p.stdout + p.stderr)
        if p.returncode != 0:
            sys.exit('terrace failed on %s (exit %d), deck %s:\n%s\n%s'
                     % (name, p.returncode, path, p.stdout[-2000:], p.stderr[-2000:]))
        r = parse_log(p.stdout, os.path.join(work, name + '.summary.json'))
        if r['loop'] is None:
            sys.exit('no run summary (loop time) for %s (%s)' % (name, path))
        r['work'] = r['loop'] - r['output']
        if best is None or r['work'] < best['work']:
            best = r
    rows = list(csv.DictReader(open(os.path.join(work, name + '.csv'))))
    val = lambda row, k: float(row[k].replace('D', 'E'))
    e0 = val(rows[0], 'etotal')
    best['de'] = max(abs(val(row, 'etotal') - e0) for row in rows)
    best['temp'] = sum(val(row, 'temp') for row in rows) / len(rows)
    if 'e_terraced' in rows[0]:
        eh0 = val(rows[0], 'e_terraced')
        best['deh'] = max(abs(val(row, 'e_terraced') - eh0) for row in rows)
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--terrace', default=os.path.join(REPO, 'build', 'terrace'))
    ap.add_argument('--cells', type=int, default=3)
    ap.add_argument('--length', type=float, default=1.0, help='simulated ps per run')
    ap.add_argument('--dts', default='1,2,5', help='Verlet steps (fs)')
    ap.add_argument('--hs', default='1.5e-3,3e-3,6e-3', help='terrace heights (eV)')
    ap.add_argument('--repeat', type=int, default=1)
    ap.add_argument('--keep', action='store_true')
    a = ap.parse_args()
    if not os.path.exists(POT):
        sys.exit('%s not found (Debian package lammps-data)' % POT)
    src = os.path.abspath(a.terrace)
    work = tempfile.mkdtemp(prefix='eam_es_cost.')
    terrace = os.path.join(work, 'terrace')
    shutil.copy2(src, terrace)
    n = a.cells
    natoms = 4 * n ** 3
    L = n * A0
    model = re.search(r'^Model name:\s*(.+)$', sh(['lscpu']), re.M)
    dirty = sh(['git', '-C', REPO, 'status', '--porcelain', '--untracked-files=no'])
    print('Energy stepping vs velocity Verlet with EAM (Cu_u3.eam, fcc Cu, %d atoms), 1 rank' % natoms)
    print('command : %s' % ' '.join([os.path.relpath(os.path.abspath(sys.argv[0]), REPO)] + sys.argv[1:]))
    print('machine : %s (%s cores visible), %s' % (model.group(1).strip() if model else '?', os.cpu_count(),
                                                  platform.platform()))
    print('date    : %s' % datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC'))
    print('commit  : %s%s' % (sh(['git', '-C', REPO, 'rev-parse', '--short', 'HEAD']),
                              ' (+ uncommitted changes)' if dirty else ''))
    try:
        print('load    : %.2f %.2f %.2f (load average at start)' % os.getloadavg())
    except OSError:
        pass
    sys.stdout.flush()
    eq = run(terrace, work, 'eq', EQ.format(a0=A0, n=n, pot=POT))
    print('start   : Verlet 2 ps at 2 fs from the lattice at 600 K; mean T %.0f K' % eq['temp'])
    print()
    results = []
    for dt in [float(x) for x in a.dts.split(',') if x.strip()]:
        name = 'vv%g' % dt
        r = run(terrace, work, name, RUN.format(length=10 * a.length, L=L, pot=POT, name=name, sampling='thermo_every=1',
                integrator="&integrator style='velocity_verlet', dt=%r /" % (dt / 1000)), a.repeat)
        r.update(kind='Verlet', param='dt = %g fs' % dt, step=dt / 1000, per=r['work'] / r['n'])
        results.append(r)
    for h in [float(x) for x in a.hs.split(',') if x.strip()]:
        name = 'es%g' % h
        r = run(terrace, work, name, RUN.format(length=a.length, L=L, pot=POT, name=name,
                sampling='thermo_interval=0.01',
                integrator="&integrator style='energy_stepping', terrace_height=%r /" % h), a.repeat)
        r.update(kind='ES', param='h = %.3g eV (%.0f K)' % (h, h / KB), step=r['mean_dt'], per=r['work'] / r['events'])
        results.append(r)
    ref = [r for r in results if r['kind'] == 'Verlet' and abs(r['step'] - 0.002) < 1e-12]
    t_ref = ref[0]['per'] if ref else None
    print('%-7s %-20s %10s %11s %9s %8s %9s %7s %11s %10s %11s' % (
        'method', 'parameter', 'step (fs)', 'max|dE| eV', 'dE/atom', 'T (K)', 'evals/ev', 'refl', 'us/step|ev',
        'ev/VVstep', 'wall s/ps'))
    for r in results:
        es = r['kind'] == 'ES'
        print('%-7s %-20s %10.4g %11.3e %9.2e %8.1f %9s %7s %11.1f %10s %11.3f' % (
            r['kind'], r['param'], 1000 * r['step'], r['de'], r['de'] / natoms, r['temp'],
            '%.3f' % r['evals'] if es else '-', '%.1f%%' % (100.0 * r['refl'] / r['events']) if es else '-',
            1e6 * r['per'], ('%.2f' % (r['per'] / t_ref)) if (es and t_ref) else '-', r['per'] / r['step']))
    print()
    for r in results:
        if r['kind'] == 'ES':
            print('ES %-20s %d events (%d up, %d down, %d reflections), force passes/event %.3f, '
                  'max |E_h - E_h0| = %.2e eV' % (r['param'], r['events'], r['up'], r['down'], r['refl'], r['passes'],
                                                  r['deh']))
    print()
    print('step = Verlet dt or mean event interval; max|dE| over samples (Verlet: every step of %g ps; ES: every'
          ' 10 fs of %g ps);' % (10 * a.length, a.length))
    print('us/step|ev = loop time without output per step or event; ev/VVstep = one event in Verlet steps (dt 2 fs);')
    print('wall s/ps = loop seconds per simulated ps.')
    if a.keep:
        print('work dir kept: %s' % work)
    else:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == '__main__':
    main()
