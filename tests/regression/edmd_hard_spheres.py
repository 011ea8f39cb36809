#!/usr/bin/env python3
"""Hard spheres with event-driven dynamics against the Carnahan-Starling equation of state.

For packing fractions eta = 0.05 .. 0.45 (N = 864, fcc start at the target density, every atom
with the same speed in a random direction: far from Maxwellian), run, drop the first fifth, then
check over the rest of the run:
  - Z = PV/NkT from the collision virial (time-averaged over each sample interval) within 1 % of
    Carnahan-Starling Z = (1 + eta + eta^2 - eta^3)/(1 - eta)^3, with a standard error below
    0.25 % (so that the 1 % is beyond statistical error);
  - the collision rate per atom within 2 % of Enskog's 4 sigma^2 n g(sigma) sqrt(pi kT/m) with
    g(sigma) = (1 - eta/2)/(1 - eta)^3;
  - the total energy and momentum constant to round-off (1e-12 relative);
  - at eta = 0.25, the velocity components of 20 frames Maxwellian: kurtosis 3 within 0.05 (the
    start's is 1.8) and a Kolmogorov-Smirnov distance below 0.01.
kT is taken as 2K/3N (K the kinetic energy), so that the ideal part of Z is exactly 1.
Usage: edmd_hard_spheres.py TERRACE OUTDIR [--etas 0.05,0.45] [--collisions 300]
Prints a table; exit 0 when every check passes.
"""
import argparse
import csv
import math
import os
import subprocess
import sys

import numpy as np


def fcc_scene(cells, density, seed):
    """Positions of an fcc lattice at number density `density` and velocities of equal speed
    (kT = 1, m = 1: speed sqrt(3)) in random directions, total momentum removed."""
    a = (4.0/density)**(1.0/3.0)
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    g = np.array([[i, j, k] for i in range(cells) for j in range(cells) for k in range(cells)], dtype=float)
    x = ((g[:, None, :] + basis[None, :, :]).reshape(-1, 3) + 0.25)*a
    rng = np.random.default_rng(seed)
    u = rng.normal(size=x.shape)
    u /= np.linalg.norm(u, axis=1)[:, None]
    v = math.sqrt(3.0)*u
    v -= v.mean(axis=0)
    return x, v, cells*a


def write_case(d, eta, cells, collisions, seed, frames):
    n = 6*eta/math.pi
    x, v, box = fcc_scene(cells, n, seed)
    natoms = len(x)
    g = (1 - eta/2)/(1 - eta)**3
    rate = 4*n*g*math.sqrt(math.pi)           # per atom, sigma = m = kT = 1
    t_run = collisions/rate
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, 'atoms.txt'), 'w') as f:
        for p, q in zip(x, v):
            f.write('1 %.17g %.17g %.17g %.17g %.17g %.17g\n' % (*p, *q))
    traj = ''
    if frames:
        traj = ", trajectory_file='traj.h5', trajectory_interval=%.17g, trajectory_fields='velocity'" % (t_run/25)
    with open(os.path.join(d, 'run.nml'), 'w') as f:
        f.write(f"""&run units='lj', dimension=3, run_time={t_run:.17g}, seed=1 /
&system atoms_file='atoms.txt', box_lo=0,0,0, box_hi={box:.17g},{box:.17g},{box:.17g}, mass=1.0 /
&potential style='hard_sphere', diameter=1.0 /
&integrator style='event_driven' /
&output thermo_interval={t_run/50:.17g}, thermo_file='thermo.csv'{traj}, overwrite=.true. /
""")
    return natoms, box**3, n, g, t_run


def read_thermo(path):
    with open(path) as f:
        rows = list(csv.DictReader(f))
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def run_deck(terrace, d, deck):
    """Write deck as d/run.nml, run it in d (screen output to d/terrace.log) and return its thermo
    columns (thermo_file='thermo.csv'); a failed run raises with the end of its output."""
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, 'run.nml'), 'w') as f:
        f.write(deck)
    r = subprocess.run([terrace, 'run.nml'], cwd=d, capture_output=True, text=True, timeout=900)
    with open(os.path.join(d, 'terrace.log'), 'w') as f:
        f.write(r.stdout + r.stderr)
    if r.returncode != 0:
        raise RuntimeError('terrace failed:\n' + (r.stdout + r.stderr)[-2000:])
    return read_thermo(os.path.join(d, 'thermo.csv'))


def block_error(x, nblocks=8):
    m = len(x)//nblocks*nblocks
    if m < nblocks:
        return float('nan')
    b = x[:m].reshape(nblocks, -1).mean(axis=1)
    return b.std(ddof=1)/math.sqrt(nblocks)


def maxwell_check(path):
    import h5py
    with h5py.File(path, 'r') as h:
        v = h['particles/all/velocity/value'][...]
    v = v[5:].reshape(-1)          # frames after the first fifth of the run
    v = v/np.sqrt(np.mean(v**2))
    kurt = np.mean(v**4)/np.mean(v**2)**2
    s = np.sort(v)
    cdf = 0.5*(1 + np.array([math.erf(t/math.sqrt(2)) for t in s]))
    k = np.arange(1, len(s) + 1)/len(s)
    ks = max(np.max(np.abs(cdf - k)), np.max(np.abs(cdf - (k - 1.0/len(s)))))
    return kurt, ks, len(v)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('terrace')
    ap.add_argument('out')
    ap.add_argument('--etas', default='0.05,0.15,0.25,0.35,0.45')
    ap.add_argument('--collisions', type=float, default=1000.0)
    ap.add_argument('--cells', type=int, default=6)
    a = ap.parse_args()
    terrace = os.path.abspath(a.terrace)
    ok = True
    print('%6s %6s %9s %9s %8s %7s %9s %9s %7s %10s %10s' % ('eta', 'N', 'Z', 'Z_CS', 'err', 'dev%', 'rate',
                                                          'Enskog', 'dev%', 'dE/E', '|P|/sum|p|'))
    for k, eta in enumerate(float(e) for e in a.etas.split(',')):
        d = os.path.join(a.out, 'eta_%.2f' % eta)
        frames = abs(eta - 0.25) < 1e-9
        natoms, vol, n, g, t_run = write_case(d, eta, a.cells, a.collisions, 1000 + k, frames)
        r = subprocess.run([terrace, 'run.nml'], cwd=d, capture_output=True, text=True, timeout=600)
        with open(os.path.join(d, 'terrace.log'), 'w') as f:
            f.write(r.stdout + r.stderr)
        if r.returncode != 0:
            print('FAIL eta=%g: terrace failed:\n%s' % (eta, (r.stdout + r.stderr)[-2000:]))
            ok = False
            continue
        th = read_thermo(os.path.join(d, 'thermo.csv'))
        keep = th['time'] > 0.2*t_run + 1e-12
        kt = 2*th['ke']/(3*natoms)
        z = th['press'][keep]*vol/(natoms*kt[keep])
        zm, ze = z.mean(), block_error(z)
        zcs = (1 + eta + eta**2 - eta**3)/(1 - eta)**3
        rate = th['collision_rate'][keep]
        enskog = 4*n*g*np.sqrt(math.pi*kt[keep])
        rm = rate.mean()/enskog.mean()
        de = np.max(np.abs(th['etotal'] - th['etotal'][0]))/th['etotal'][0]
        pmax = np.max(np.sqrt(th['px']**2 + th['py']**2 + th['pz']**2))/(natoms*math.sqrt(3.0))
        dev = (zm - zcs)/zcs
        print('%6.2f %6d %9.5f %9.5f %8.5f %7.3f %9.4f %9.4f %7.3f %10.2e %10.2e' % (
            eta, natoms, zm, zcs, ze, 100*dev, rate.mean(), enskog.mean(), 100*(rm - 1), de, pmax))
        if abs(dev) > 0.01 or ze > 0.0025*zcs:     # within 1 %, measured to a quarter of that
            print('FAIL eta=%g: Z = %.5f +- %.5f, Carnahan-Starling %.5f' % (eta, zm, ze, zcs)); ok = False
        if abs(rm - 1) > 0.02:
            print('FAIL eta=%g: collision rate %.4f, Enskog %.4f' % (eta, rate.mean(), enskog.mean())); ok = False
        if de > 1e-12 or pmax > 1e-12:
            print('FAIL eta=%g: energy (%.2e) or momentum (%.2e) not conserved to round-off' % (eta, de, pmax))
            ok = False
        if frames:
            kurt, ks, m = maxwell_check(os.path.join(d, 'traj.h5'))
            print('       velocity components (%d): kurtosis %.4f (Maxwell 3, start 1.8), KS distance %.4f' %
                  (m, kurt, ks))
            if abs(kurt - 3) > 0.05 or ks > 0.01:
                print('FAIL: velocities not Maxwellian'); ok = False
    print('edmd_hard_spheres: ' + ('PASS' if ok else 'FAIL'))
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
