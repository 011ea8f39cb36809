#!/usr/bin/env python3
"""A dense square-well liquid against published liquid-vapour coexistence (event-driven, NVT).

Published value: the square well with lambda = 1.5 coexists at kT/eps = 1.15 as a vapour of
number density 0.09723 and a liquid of 0.5384 sigma^-3 (grand-canonical transition-matrix Monte
Carlo, NIST Standard Reference Simulation Website, "SAT-TMMC: liquid-vapor coexistence properties,
square-well fluid"; the values as reproduced to 1e-3 by FEASST's square-well tutorial).
Two coexisting phases have the same temperature and pressure. So 500 square wells are run at each
published density with Andersen's thermostat at kT = 1.15 (fcc start, the first 20 time units
dropped) and the collision-virial pressures must agree:
  |P(liquid) - P(vapour)| <= 4 standard errors (block averages, 20 blocks, errors added in
  quadrature).
The liquid's pressure (about 0.06) is the small difference of its kinetic part n kT = 0.62 and
its collision virial, about -0.56. Also checked: the mean kinetic temperature 2K/3N of each run within 4 block errors of the
target, and econserve = etotal - ecouple constant to 1e-10 relative (exact dynamics between the
thermostat's collisions).
Usage: edmd_sw_coexistence.py TERRACE OUTDIR [--time 1000] [--extra 0.52,0.56]
(--extra runs more liquid densities, prints their pressures and, from the slope dP/dn of the
liquid points, the density at which the liquid's pressure equals the vapour's; no checks.)
"""
import argparse
import math
import os
import sys

import numpy as np

from edmd_hard_spheres import block_error, run_deck   # (beside this script: on sys.path as its folder)

KT = 1.15
RHO_VAP = 0.09723
RHO_LIQ = 0.5384
DROP = 20.0


def run(terrace, d, rho, t_run, seed):
    th = run_deck(terrace, d, f"""&run units='lj', dimension=3, run_time={t_run:.17g}, seed={seed} /
&system lattice='fcc', density={rho:.17g}, cells=5,5,5, mass=1.0, temperature={KT} /
&potential style='square_well', diameter=1.0, well_depth=1.0, well_lambda=1.5 /
&integrator style='event_driven' /
&thermostat style='andersen', temperature={KT}, damping=1.0 /
&output thermo_interval=0.5, thermo_file='thermo.csv', overwrite=.true. /
""")
    natoms = 500
    keep = th['time'] > DROP + 1e-12
    p = th['press'][keep]
    kt = 2*th['ke'][keep]/(3*natoms)
    u = th['pe'][keep]/natoms
    ec = th['econserve']
    drift = float(np.max(np.abs(ec - ec[0]))/abs(ec[0]))
    return dict(rho=rho, p=p.mean(), pe=block_error(p, 20), kt=kt.mean(), kte=block_error(kt, 20),
                u=u.mean(), ue=block_error(u, 20), drift=drift, coll=th['collisions'][-1])


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('terrace')
    ap.add_argument('out')
    ap.add_argument('--time', type=float, default=1000.0, help='run_time of the liquid (the vapour: 400)')
    ap.add_argument('--extra', default='', help='more liquid densities to print, e.g. 0.52,0.56')
    a = ap.parse_args()
    terrace = os.path.abspath(a.terrace)
    cases = [('vapour', RHO_VAP, 400.0, 21), ('liquid', RHO_LIQ, a.time, 22)]
    cases += [('extra', float(s), a.time, 23) for s in a.extra.split(',') if s]
    ok = True
    res = {}
    extra = []
    print('%-7s %8s %8s %8s %8s %8s %8s %9s %9s %9s' % ('phase', 'n', 'P', 'err', 'kT', 'err', 'U/N',
                                                          'n kT', 'virial', 'econs'))
    for name, rho, t, seed in cases:
        r = run(terrace, os.path.join(a.out, '%s_%g' % (name, rho)), rho, t, seed)
        print('%-7s %8.5f %8.4f %8.4f %8.4f %8.4f %8.4f %9.4f %9.4f %9.1e' % (
            name, rho, r['p'], r['pe'], r['kt'], r['kte'], r['u'], rho*r['kt'], r['p'] - rho*r['kt'], r['drift']))
        if name == 'extra':
            extra.append(r)
            continue
        res[name] = r
        if abs(r['kt'] - KT) > 4*r['kte']:
            print('FAIL: %s: mean kT %.4f not within 4 errors of %.2f' % (name, r['kt'], KT)); ok = False
        if r['drift'] > 1e-10:
            print('FAIL: %s: econserve changed by %.1e relative' % (name, r['drift'])); ok = False
    dp = res['liquid']['p'] - res['vapour']['p']
    err = math.hypot(res['liquid']['pe'], res['vapour']['pe'])
    print('P(liquid) - P(vapour) = %.4f +- %.4f (%.1f standard errors)' % (dp, err, abs(dp)/err))
    ex = [r for r in extra] + [res['liquid']]
    if len(ex) > 1:
        slope = np.polyfit([r['rho'] for r in ex], [r['p'] for r in ex], 1)[0]
        print('dP/dn of the liquid %.3f: P(liquid) = P(vapour) at n = %.4f +- %.4f (published %.4f)' % (
            slope, RHO_LIQ - dp/slope, err/slope, RHO_LIQ))
    if abs(dp) > 4*err:
        print('FAIL: the published coexisting phases do not have equal pressures'); ok = False
    print('edmd_sw_coexistence: ' + ('PASS' if ok else 'FAIL'))
    return 0 if ok else 1


if __name__ == '__main__':
    sys.exit(main())
