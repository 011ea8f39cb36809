#!/usr/bin/env python3
"""Event-driven dynamics: time reversal and rank invariance on a square-well liquid.

1. Time reversal: N = 500 square wells (lambda = 1.5, n = 0.5, kT = 1.5) run for T (final state
   written), the velocities reversed and run T again: the positions must come back to the start.
   Round-off grows with the chaos of the dynamics (about a factor e per few collisions per atom),
   so the error is tabulated against the events; asserted: max |x_back - x0| < 1e-9 sigma for the
   runs of at most --assert-events events. The round-off's growth goes with the events per atom,
   not their total: the same liquid of N = 32,000 atoms is also run forward and back over at least
   1e5 events (about 7 per atom), asserted to come back below 1e-9 sigma.
2. Rank invariance: the same deck (with a trajectory) on 1 and 4 ranks: the thermo CSVs and final
   atoms must be identical byte for byte (every rank runs the same events; no reduction enters the
   results); also a lattice deck whose velocities come from &system temperature.
Usage: edmd_reversal_ranks.py TERRACE OUTDIR
"""
import argparse
import filecmp
import math
import os
import subprocess
import sys

import numpy as np

from edmd_hard_spheres import fcc_scene   # (beside this script: on sys.path as its folder)
from terrace_tools import summary

DECK = """&run units='lj', dimension=3, run_time={T:.17g}, seed=1 /
&system atoms_file='{atoms}', box_lo=0,0,0, box_hi={L:.17g},{L:.17g},{L:.17g}, mass=1.0{rev} /
&potential style='square_well', diameter=1.0, well_depth=1.0, well_lambda=1.5 /
&integrator style='event_driven' /
&output thermo_interval={dt:.17g}, thermo_file='{thermo}', final_atoms_file='{out}'{traj}, overwrite=.true. /
"""


def read_atoms(path):
    rows = []
    for line in open(path):
        line = line.split('#')[0].split()
        if line:
            rows.append([float(x) for x in line[1:]])
    return np.array(rows)


def run(cmd, cwd):
    p = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=600)
    open(os.path.join(cwd, 'log_%d.txt' % len(os.listdir(cwd))), 'w').write(p.stdout + p.stderr)
    if p.returncode != 0:
        print(p.stdout[-2000:], p.stderr[-2000:])
        raise SystemExit('FAIL: ' + ' '.join(cmd))
    return p.stdout


def events(summary_path):
    """The run's event count, from its run summary."""
    return summary.get(summary_path, 'event_driven/events')


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('terrace')
    ap.add_argument('out')
    ap.add_argument('--assert-events', type=int, default=20000)
    a = ap.parse_args()
    terrace = os.path.abspath(a.terrace)
    os.makedirs(a.out, exist_ok=True)
    ok = True
    print('%7s %10s %10s %14s' % ('N', 'T', 'events', 'max |dx|'))
    for cells, times in ((20, [0.25]), (5, [0.5, 1.0, 2.0, 4.0])):
        x, v, L = fcc_scene(cells, 0.5, 7)
        v *= math.sqrt(1.5)
        with open(os.path.join(a.out, 'start.txt'), 'w') as f:
            for p, q in zip(x, v):
                f.write('1 %.17g %.17g %.17g %.17g %.17g %.17g\n' % (*p, *q))
        x0 = read_atoms(os.path.join(a.out, 'start.txt'))[:, :3]
        for T in times:
            kw = dict(T=T, L=L, dt=T, thermo='thermo.csv', traj='')
            open(os.path.join(a.out, 'fwd.nml'), 'w').write(DECK.format(atoms='start.txt', rev='', out='fwd.txt',
                                                                        **kw))
            run([terrace, 'fwd.nml'], a.out)
            ev = events(os.path.join(a.out, 'fwd.summary.json'))
            open(os.path.join(a.out, 'back.nml'), 'w').write(DECK.format(atoms='fwd.txt',
                                                                         rev=', reverse_velocities=.true.',
                                                                         out='back.txt', **kw))
            run([terrace, 'back.nml'], a.out)
            xb = read_atoms(os.path.join(a.out, 'back.txt'))[:, :3]
            d = xb - x0
            d -= L*np.round(d/L)
            err = np.abs(d).max()
            print('%7d %10.3g %10d %14.3e' % (len(x), T, ev, err))
            large = cells == 20
            if large and ev < 100000:
                print('FAIL: the large run had only %d events' % ev); ok = False
            if (large or ev <= a.assert_events) and not err < 1e-9:
                print('FAIL: time reversal error %.3e after %d events' % (err, ev)); ok = False
    # rank invariance
    kw = dict(T=4.0, L=L, dt=0.25, traj=", trajectory_file='traj.h5', trajectory_interval=1.0", rev='')
    for np_ in (1, 4):
        d = os.path.join(a.out, 'np%d' % np_)
        os.makedirs(d, exist_ok=True)
        open(os.path.join(d, 'run.nml'), 'w').write(DECK.format(atoms='../start.txt', out='final.txt',
                                                                thermo='thermo.csv', **kw))
        cmd = [terrace, 'run.nml'] if np_ == 1 else ['mpirun', '--oversubscribe', '-np', str(np_), terrace, 'run.nml']
        run(cmd, d)
    same = filecmp.cmp(os.path.join(a.out, 'np1', 'thermo.csv'), os.path.join(a.out, 'np4', 'thermo.csv'),
                       shallow=False)
    same_final = filecmp.cmp(os.path.join(a.out, 'np1', 'final.txt'), os.path.join(a.out, 'np4', 'final.txt'),
                             shallow=False)
    lines = len(open(os.path.join(a.out, 'np1', 'thermo.csv')).readlines())
    print('1 vs 4 ranks: thermo.csv (%d lines) %s, final atoms %s' % (lines, 'identical' if same else 'DIFFERENT',
                                                                       'identical' if same_final else 'DIFFERENT'))
    ok = ok and same and same_final
    # velocities drawn from &system temperature on a lattice: the same start on every rank count
    lat = """&run units='lj', dimension=3, run_time=4.0, seed=5 /
&system lattice='fcc', density=0.5, cells=5,5,5, mass=1.0, temperature=1.5 /
&potential style='square_well', diameter=1.0, well_depth=1.0, well_lambda=1.5 /
&integrator style='event_driven' /
&output thermo_interval=0.25, thermo_file='lattice.csv', overwrite=.true. /
"""
    for np_ in (1, 4):
        d = os.path.join(a.out, 'np%d' % np_)
        open(os.path.join(d, 'lattice.nml'), 'w').write(lat)
        cmd = [terrace, 'lattice.nml'] if np_ == 1 else ['mpirun', '--oversubscribe', '-np', str(np_), terrace,
                                                          'lattice.nml']
        run(cmd, d)
    same_lat = filecmp.cmp(os.path.join(a.out, 'np1', 'lattice.csv'), os.path.join(a.out, 'np4', 'lattice.csv'),
                           shallow=False)
    print('1 vs 4 ranks, lattice with velocities from temperature: thermo %s' %
          ('identical' if same_lat else 'DIFFERENT'))
    ok = ok and same_lat
    print('edmd_reversal_ranks: ' + ('PASS' if ok else 'FAIL'))
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
