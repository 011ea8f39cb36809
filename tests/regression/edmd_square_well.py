#!/usr/bin/env python3
"""Square wells with event-driven dynamics: the second virial coefficient, captures and escapes.

A square-well gas (lambda = 1.5, eps = 1, N = 2048, kT about 2) at four low densities n: from the
collision virial Z = PV/NkT (kT = 2K/3N per sample), (Z - 1)/n - B2(beta_n) with the closed form
    B2 = (2 pi sigma^3 / 3) [1 - (lambda^3 - 1)(exp(beps) - 1)]
at each run's mean beta is B3 n + ...: the weighted line through the four densities must meet 0
at n = 0 within 4 standard errors (block averages, propagated, and scaled up by the scatter of
the points about the line where it exceeds their error bars). Also checked: the
total energy K + U (U the sum of -eps over captured pairs) and the momentum constant to round-off
(1e-11 relative), and that pairs were captured, escaped and bounced at the well edge.
Usage: edmd_square_well.py TERRACE OUTDIR [--time 400]
"""
import argparse
import math
import os
import sys

import numpy as np

from edmd_hard_spheres import fcc_scene, block_error, run_deck   # (beside this script: on sys.path as its folder)

LAMBDA = 1.5


def run_case(terrace, d, n, t_run, cells, seed):
    x, v, box = fcc_scene(cells, n, seed)
    v *= math.sqrt(2.0)                      # kT = 2 at the start
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, 'atoms.txt'), 'w') as f:
        for p, q in zip(x, v):
            f.write('1 %.17g %.17g %.17g %.17g %.17g %.17g\n' % (*p, *q))
    th = run_deck(terrace, d, f"""&run units='lj', dimension=3, run_time={t_run:.17g}, seed=1 /
&system atoms_file='atoms.txt', box_lo=0,0,0, box_hi={box:.17g},{box:.17g},{box:.17g}, mass=1.0 /
&potential style='square_well', diameter=1.0, well_depth=1.0, well_lambda={LAMBDA} /
&integrator style='event_driven' /
&output thermo_interval={t_run/100:.17g}, thermo_file='thermo.csv', overwrite=.true. /
""")
    natoms = len(x)
    keep = th['time'] > 0.1*t_run + 1e-12
    kt = 2*th['ke']/(3*natoms)
    z = th['press']*box**3/(natoms*kt)
    y = (z[keep] - 1)/n
    return th, natoms, y.mean(), block_error(y), (1/kt[keep]).mean()


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('terrace')
    ap.add_argument('out')
    ap.add_argument('--time', type=float, default=400.0)
    ap.add_argument('--densities', default='0.01,0.02,0.035,0.05')
    a = ap.parse_args()
    terrace = os.path.abspath(a.terrace)
    ok = True
    res = []
    print('%8s %6s %10s %9s %7s %9s %9s %9s %9s %10s' % ('n', 'N', '(Z-1)/n', 'err', 'beta', 'captures', 'escapes',
                                                       'bounces', 'pairs', 'dE/E'))
    for k, n in enumerate(float(s) for s in a.densities.split(',')):
        th, natoms, y, ye, beta = run_case(terrace, os.path.join(a.out, 'n_%g' % n), n, a.time, 8, 2000 + k)
        de = np.max(np.abs(th['etotal'] - th['etotal'][0]))/abs(th['etotal'][0])
        pmax = np.max(np.sqrt(th['px']**2 + th['py']**2 + th['pz']**2))/(natoms*2.45)
        print('%8.4f %6d %10.4f %9.4f %7.4f %9d %9d %9d %9d %10.2e' % (n, natoms, y, ye, beta, th['captures'][-1],
                                                                     th['escapes'][-1], th['bounces'][-1],
                                                                     th['captured_pairs'][-1], de))
        res.append((n, y, ye, beta))
        if de > 1e-11 or pmax > 1e-12:
            print('FAIL: energy (%.2e) or momentum (%.2e) not conserved to round-off' % (de, pmax)); ok = False
        if min(th['captures'][-1], th['escapes'][-1], th['bounces'][-1]) < 100:
            print('FAIL: too few captures, escapes or bounces'); ok = False
    def b2_closed(beta):
        return 2*math.pi/3*(1 - (LAMBDA**3 - 1)*(math.exp(beta) - 1))
    # each density at its own mean beta: d_n = (Z - 1)/n - B2(beta_n) = B3 n + ...; the weighted
    # line through the densities must meet 0 at n = 0 (its error scaled up by the scatter of the
    # points about the line when that exceeds their error bars)
    n_ = np.array([r[0] for r in res])
    d_ = np.array([r[1] - b2_closed(r[3]) for r in res])
    e_ = np.array([r[2] for r in res])
    w_ = 1/e_**2
    A = np.vstack([np.ones_like(n_), n_]).T
    cov = np.linalg.inv(A.T @ (A*w_[:, None]))
    icpt, slope = cov @ (A.T @ (w_*d_))
    chi2 = float(np.sum(w_*(d_ - icpt - slope*n_)**2))
    scale = max(1.0, math.sqrt(chi2/max(1, len(n_) - 2)))
    err = math.sqrt(cov[0, 0])*scale
    beta = float(np.mean([r[3] for r in res]))
    for n1, d1, e1 in zip(n_, d_, e_):
        print('  n = %.4f: (Z - 1)/n - B2(beta_n) = %8.4f +- %.4f' % (n1, d1, e1))
    print('line: intercept %.4f +- %.4f (errors scaled by %.2f for the scatter), slope (B3) %.3f' %
          (icpt, err, scale, slope))
    print('B2 from the collision virial at beta eps = %.4f: %.4f +- %.4f sigma^3; closed form %.4f' %
          (beta, b2_closed(beta) + icpt, err, b2_closed(beta)))
    if abs(icpt) > 4*err:
        print('FAIL: B2 beyond 4 standard errors'); ok = False
    print('edmd_square_well: ' + ('PASS' if ok else 'FAIL'))
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
