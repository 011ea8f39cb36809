#!/usr/bin/env python3
"""Event-driven dynamics with Andersen's thermostat (collisions at exact times, calendar events).

N = 500 square wells (lambda = 1.5, n = 0.7) start at kT = 1 from an fcc lattice; the thermostat
(target kT = 2, damping 0.5: each atom gets a new Maxwell-Boltzmann velocity at rate 2 per time
unit) runs them for 12 time units. Asserted:
  1. the temperature reached: the mean of the thermo samples over t >= 4 within 4 block errors
     (and 2 %) of the target; it started 50 % away;
  2. the velocities Maxwellian at the target: the components of the frames at t >= 4 divided by
     sqrt(kT/m) of the *target* (not their own spread): kurtosis within 0.1 of 3, mean square
     within 3 % of 1, Kolmogorov-Smirnov distance from the unit normal below 0.02;
  3. econserve = etotal - ecouple (the energy the thermostat put in, summed at every collision)
     constant to 1e-12 relative: the event-driven dynamics between collisions is exact;
  4. rank invariance: the thermo CSVs of 1 and 4 ranks identical byte for byte (the collisions are
     keyed by seed, atom id and time, the same on any rank count).
Usage: edmd_andersen.py TERRACE OUTDIR
"""
import csv
import math
import os
import subprocess
import sys

import numpy as np

DECK = """&run units='lj', dimension=3, run_time=12.0, seed=4242 /
&system lattice='fcc', density=0.7, cells=5,5,5, mass=1.0, temperature=1.0 /
&potential style='square_well', diameter=1.0, well_depth=1.0, well_lambda=1.5 /
&integrator style='event_driven' /
&thermostat style='andersen', temperature=2.0, damping=0.5 /
&output thermo_interval=0.1, thermo_file='thermo.csv', trajectory_file='traj.h5', trajectory_interval=0.5,
        overwrite=.true. /
"""
TARGET = 2.0


def run(terrace, d, np_):
    os.makedirs(d, exist_ok=True)
    open(os.path.join(d, 'run.nml'), 'w').write(DECK)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT='1', OMPI_ALLOW_RUN_AS_ROOT_CONFIRM='1')
    cmd = [terrace, 'run.nml'] if np_ == 1 else ['mpirun', '--oversubscribe', '-np', str(np_), terrace, 'run.nml']
    p = subprocess.run(cmd, cwd=d, capture_output=True, text=True, timeout=600, env=env)
    open(os.path.join(d, 'log.txt'), 'w').write(p.stdout + p.stderr)
    if p.returncode != 0:
        print(p.stdout[-2000:], p.stderr[-2000:])
        raise SystemExit('FAIL: ' + ' '.join(cmd))


def read_thermo(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def block_error(x, nblocks=8):
    m = len(x)//nblocks*nblocks
    b = x[:m].reshape(nblocks, -1).mean(axis=1)
    return b.std(ddof=1)/math.sqrt(nblocks)


def main():
    if len(sys.argv) != 3:
        raise SystemExit(__doc__)
    terrace, out = os.path.abspath(sys.argv[1]), sys.argv[2]
    ok = True
    run(terrace, os.path.join(out, 'np1'), 1)
    th = read_thermo(os.path.join(out, 'np1', 'thermo.csv'))
    late = th['time'] >= 4.0
    t_mean, t_err = th['temp'][late].mean(), block_error(th['temp'][late])
    dev = t_mean - TARGET
    good = abs(dev) <= 4*t_err and abs(dev) <= 0.02*TARGET
    ok &= good
    print('temperature: start %.4f, mean over t >= 4: %.4f +- %.4f (target %.1f, deviation %.2f errors) %s'
          % (th['temp'][0], t_mean, t_err, TARGET, dev/t_err, 'ok' if good else 'FAIL'))

    import h5py
    with h5py.File(os.path.join(out, 'np1', 'traj.h5'), 'r') as h:
        times = h['particles/all/velocity/time'][...]
        v = h['particles/all/velocity/value'][...]
    v = v[times >= 4.0].reshape(-1)/math.sqrt(TARGET)          # kT/m of the target, m = 1
    msq = np.mean(v**2)
    kurt = np.mean(v**4)/msq**2
    s = np.sort(v)
    cdf = 0.5*(1 + np.array([math.erf(t/math.sqrt(2)) for t in s]))
    k = np.arange(1, len(s) + 1)/len(s)
    ks = max(np.max(np.abs(cdf - k)), np.max(np.abs(cdf - (k - 1.0/len(s)))))
    good = abs(kurt - 3) <= 0.1 and abs(msq - 1) <= 0.03 and ks < 0.02
    ok &= good
    print('velocity components (%d, frames at t >= 4) over sqrt(kT_target/m): mean square %.4f, kurtosis %.4f, '
          'KS distance from the unit normal %.4f %s' % (len(v), msq, kurt, ks, 'ok' if good else 'FAIL'))

    ec = th['econserve']
    drift = np.max(np.abs(ec - ec[0]))/abs(ec[0])
    good = drift < 1e-12 and np.max(np.abs(th['ecouple'])) > 100
    ok &= good
    print('econserve = etotal - ecouple: largest change %.2e relative (ecouple reaches %.1f) %s'
          % (drift, th['ecouple'][-1], 'ok' if good else 'FAIL'))

    run(terrace, os.path.join(out, 'np4'), 4)
    same = open(os.path.join(out, 'np1', 'thermo.csv'), 'rb').read() == \
        open(os.path.join(out, 'np4', 'thermo.csv'), 'rb').read()
    ok &= same
    print('1 vs 4 ranks: thermo.csv (%d lines) %s' % (len(th['time']), 'identical' if same else 'DIFFERENT: FAIL'))
    print('edmd_andersen: ' + ('PASS' if ok else 'FAIL'))
    sys.exit(0 if ok else 1)


if __name__ == '__main__':
    main()
