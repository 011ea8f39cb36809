#!/usr/bin/env python3
"""Energy stepping in large thermal systems: why h must stay well below k_B T / 2 whatever N is
(doc/energy_stepping.md, "Transversality: when to worry").

Scene: the LAMMPS LJ benchmark liquid (fcc rho* = 0.8442 melted from T* = 1.44 by 500 Verlet steps,
shifted LJ rc = 2.5), at several sizes N = 4 c^3.

Part 1 (numpy, thermal states of a Verlet run, 21 frames per size): along the straight line
x + s v of energy stepping's free flight, V(s) = V + V' s + V'' s^2 / 2 + ..., with
  V'  = sum_pairs phi'(r) r',  V'' = sum_pairs phi''(r) r'^2 + phi'(r) r''
(r' = d.w/r, r'' = (|w|^2 - r'^2)/r, d and w the pair's separation and relative velocity).
Printed: V'/sqrt(N) and V''/N (both should be N-independent), the depth of the dip of the parabola,
V'^2/(2 V''), and the kinetic energy along the gradient, V'^2/(2 |F|^2/m) (m = 1), both in units
of k_B T (should be O(1) and N-independent), and their ratio |F|^2/V'' (-> 1 for large N: the
thermal means of |F|^2 and of V'' are both k_B T tr(H)/m). After a reflection V' changes sign and the
parabola dips by (normal KE) x |F|^2/V'' below the level; the normal KE was below h (that is why
it reflected), so with |F|^2/V'' <= 1 the state cannot reach the lower level in this approximation.

Part 2 (engine): energy-stepping runs from the prepared state at h / k_B T = 0.125 ... 1 (three
slightly different h per ratio, so that where V0 falls on the grid of levels averages out) for two
sizes; printed: reflection fraction, how many runs trapped (>90 % reflections), and the event rate
scaled by h / (k_B T sqrt(N)) (constant if the rate grows like sqrt(N)/h).

Usage: PYTHONPATH=scripts /usr/bin/python3 scripts/bench/es_trap_scaling.py [--build build] [--work DIR]
       [--sizes 3,6,10] [--es-sizes 3,4,6,10] [--t 0.1]   (2 min 7 s on the 2-vCPU dev box)
"""
import argparse
import os
import sys
import tempfile

import numpy as np

from study.common import run_terrace, read_h5md, read_atoms_file  # noqa: E402

RC = 2.5
POT = "&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.true. /"


def box_length(c):
    return c * (4.0 / 0.8442) ** (1.0 / 3.0)


def prepare(terrace, work, c):
    deck = ("&run units='lj', dimension=3, n_steps=500, seed=87287 /\n"
            "&system lattice='fcc', density=0.8442, cells=%d,%d,%d, periodic=.true.,.true.,.true., "
            "mass=1.0, temperature=1.44 /\n%s\n&integrator style='velocity_verlet', dt=0.005 /\n"
            "&neighbor skin=0.3 /\n&output thermo_every=100, thermo_file='', final_atoms_file='start.atoms' /\n"
            % (c, c, c, POT))
    r = run_terrace(terrace, work, 'prep', deck)
    if r['rc'] != 0:
        sys.exit('preparation failed: %s' % r['error'])


def deck(c, integrator, t_end, traj=0.0):
    L = box_length(c)
    out = "thermo_interval=%r, thermo_file=''" % t_end
    if traj:
        out += ", trajectory_file='frames.h5', trajectory_interval=%r, overwrite=.true." % traj
    return ("&run units='lj', dimension=3, run_time=%r, seed=1 /\n"
            "&system atoms_file='start.atoms', box_lo=0,0,0, box_hi=%r,%r,%r, periodic=.true.,.true.,.true., "
            "mass=1.0 /\n%s\n%s\n&neighbor skin=0.3 /\n&output %s /\n" % (t_end, L, L, L, POT, integrator, out))


def ray_terms(x, v, L):
    """V', V'' along x + s v and |F|^2 (shifted LJ, minimum image, all pairs within RC)."""
    n = len(x)
    d1 = d2 = 0.0
    F = np.zeros_like(x)
    for i0 in range(0, n, 400):
        i1 = min(n, i0 + 400)
        d = x[i0:i1, None, :] - x[None, :, :]
        d -= L * np.round(d / L)
        w = v[i0:i1, None, :] - v[None, :, :]
        r2 = np.sum(d * d, axis=2)
        ii = np.arange(i0, i1)
        r2[ii - i0, ii] = np.inf
        m = r2 < RC * RC
        r = np.sqrt(np.where(m, r2, 1.0))
        ir6 = r ** -6
        p1 = np.where(m, 4 * (-12 * ir6 * ir6 + 6 * ir6) / r, 0.0)           # phi'(r)
        p2 = np.where(m, 4 * (156 * ir6 * ir6 - 42 * ir6) / (r * r), 0.0)     # phi''(r)
        rp = np.sum(d * w, axis=2) / r
        rpp = (np.sum(w * w, axis=2) - rp * rp) / r
        d1 += 0.5 * np.sum(p1 * rp)                   # each pair appears twice over the rows
        d2 += 0.5 * np.sum(p2 * rp * rp + p1 * rpp)
        F[i0:i1] -= np.sum((p1 / r)[:, :, None] * d, axis=1)
    return d1, d2, float(np.sum(F * F))


def part1(terrace, root, sizes):
    print('Part 1: Taylor terms of V along the free-flight line (21 thermal states per size, 0.1 tau apart; mean +- SE)')
    ratios = []
    print('%6s %8s %12s %12s %20s %20s %18s' % ('N', 'kT', "V'/sqrt(N)", "V''/N", "dip V'^2/(2V'')/kT",
                                              'normal KE / kT', "|F|^2/V''"))
    for c in sizes:
        work = os.path.join(root, 'p1_%d' % c)
        os.makedirs(work, exist_ok=True)
        prepare(terrace, work, c)
        r = run_terrace(terrace, work, 'frames', deck(c, "&integrator style='velocity_verlet', dt=0.005 /",
                                                      2.0, traj=0.1))
        if r['rc'] != 0:
            sys.exit('Verlet run failed: %s' % r['error'])
        t, X, V, _ = read_h5md(os.path.join(work, 'frames.h5'))
        L = box_length(c)
        n = X.shape[1]
        rows = []
        for x, v in zip(X, V):
            kT = np.sum(v * v) / (3 * n - 3)
            d1, d2, f2 = ray_terms(x, v, L)
            rows.append((kT, abs(d1) / np.sqrt(n), d2 / n, d1 * d1 / (2 * d2) / kT, d1 * d1 / (2 * f2) / kT, f2 / d2))
        a = np.array(rows)
        ms = lambda k: '%8.3g +- %-8.2g' % (a[:, k].mean(), a[:, k].std(ddof=1) / np.sqrt(len(a)))
        print('%6d %8.3f %12.3g %12.3g %20s %20s %18s' % (n, a[:, 0].mean(), a[:, 1].mean(), a[:, 2].mean(), ms(3), ms(4),
                                                     ms(5)))
        ratios.append((n, np.mean(a[:, 1] ** 2) / (2 * np.mean(a[:, 2])) / a[:, 0].mean(),
                       np.mean(a[:, 4]), len(a)))
    print('ratio of thermal means, <V\'^2>/(2<V\'\'>)/kT:  ' +
          ', '.join('N = %d: %.3g (%d states)' % (n, q, k) for n, q, _, k in ratios))
    print("(thermal averages: <dip> = sum F_i^2 / (2 sum H_ii) = kT/2 and <normal KE> = kT/2 by equipartition,\n"
          " to leading order in 1/N; V' is a sum of N random terms, V'' of N positive ones)\n")


def part2(terrace, root, sizes, t_end):
    print('Part 2: energy stepping from the prepared state, %g tau per run, h = ratio x kT x (1, 1.013, 1.029)' % t_end)
    print('%6s %7s %8s %10s %12s %9s %22s' % ('N', 'h/kT', 'runs', 'events', 'reflections', 'trapped',
                                              'rate*h/(kT sqrt N)'))
    for c in sizes:
        work = os.path.join(root, 'p2_%d' % c)
        os.makedirs(work, exist_ok=True)
        prepare(terrace, work, c)
        _, _, v = read_atoms_file(os.path.join(work, 'start.atoms'))
        n = len(v)
        kT = float(np.sum(v * v) / (3 * n - 3))
        for ratio in (0.125, 0.25, 0.5, 1.0):
            ev = rf = trapped = 0
            rates = []
            for k, off in enumerate((1.0, 1.013, 1.029)):
                h = ratio * kT * off
                r = run_terrace(terrace, work, 'es_%g_%d' % (ratio, k),
                                deck(c, "&integrator style='energy_stepping', terrace_height=%.10g /" % h, t_end))
                if r['rc'] != 0 or 'events' not in r:
                    print('    run failed: %s' % r['error'])
                    continue
                ev += r['events']
                rf += r['refl']
                tr = r['refl'] > 0.9 * r['events']
                trapped += tr
                if not tr:
                    rates.append(r['events'] / t_end * h / (kT * np.sqrt(n)))
            print('%6d %7.3g %8d %10d %11.1f%% %6d/3 %22s' % (n, ratio, 3, ev, 100.0 * rf / max(1, ev), trapped,
                                                         ('%.3g' % np.mean(rates)) if rates else '-'))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--build', default=os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', 'build'))
    ap.add_argument('--work', default='')
    ap.add_argument('--sizes', default='3,6,10', help='fcc cells per edge for part 1 (N = 4 c^3)')
    ap.add_argument('--es-sizes', default='3,4,6,10', help='cells per edge for part 2')
    ap.add_argument('--t', type=float, default=0.1, help='length of each energy-stepping run (tau)')
    a = ap.parse_args()
    terrace = os.path.abspath(os.path.join(a.build, 'terrace'))
    root = a.work or tempfile.mkdtemp(prefix='es_trap.')
    os.makedirs(root, exist_ok=True)
    print('work dir %s; load average %s' % (root, ' '.join(open('/proc/loadavg').read().split()[:3])))
    part1(terrace, root, [int(x) for x in a.sizes.split(',')])
    part2(terrace, root, [int(x) for x in a.es_sizes.split(',')], a.t)


if __name__ == '__main__':
    main()
