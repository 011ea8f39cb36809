#!/usr/bin/env python3
"""Checks of the study's analysis code against independent references (CTest bench_study_analysis):

  - block_mean: the standard error of 10,000 independent N(0, 1) samples is 0.01 (within 30 %);
  - rdf/first_peak: an fcc lattice (a = 1.5) has its first g(r) peak at a/sqrt(2) and, in a bin of
    width dr, a height 12 / (4 pi r^2 dr rho);
  - diffusion: Brownian paths with step variance 2 D dt per dimension give D back (within 10 %);
  - vdos_peak: velocities cos(2 pi f t + phase) give the peak at f (within one frequency bin);
  - traj_error: a rigid shift of every atom by (0.3, 0.4, 0) gives 0.5;
  - energy_metrics: a linear energy ramp gives its slope as the drift;
  - exact_dt: dt = t_end / N ends every run at t_end and is never above the requested step;
  - convergence (the mesh scenes' order-of-convergence fit): errors 0.02 h^(1/2) give slope 1/2;
  - collisions (the many-collision run's restitution, bounce.py): a momentum history with three
    bounces of known restitution, one interrupted by a 20 ms gap before it reverses, one by a 1 ms
    gap, and a contact still on at the end, gives the three restitutions;
  - quality (the stiff-minority meshes): radius ratio 1 for a regular tetrahedron, ~0 for a flat
    one of altitude 1e-3 over its base (which it gives back); the unit right corner: V = 1/6,
    smallest altitude 1/sqrt(3);
  - with a build directory as argument that holds terrace-analyze: the study's adapter (Analyzer,
    which runs terrace-analyze on H5MD files written by write_h5md) on the same fcc lattice, Brownian
    paths and harmonic velocities: same first-peak position and height, D within 10 % and within
    3 of its block standard errors, VDOS peak within one resolution 1/(M dt).
Exit status 0 when all pass.
Usage (from scripts/bench, with scripts on PYTHONPATH or terrace_tools installed):
  python3 -m study.selftest [BUILD_DIR]"""
import os
import sys

import numpy as np

from . import analysis as A


def check(name, ok, detail):
    print('%-14s %s  %s' % (name, 'PASS' if ok else 'FAIL', detail))
    return ok


def main():
    rng = np.random.default_rng(7)
    good = True

    from .common import exact_dt
    from .solids import convergence
    worst = 0.0
    for t_end, dt in ((0.05, 1.6e-4), (0.065, 2.1e-4), (0.05, 1e-6), (2000.0, 0.08), (0.1, 8.9e-5)):
        d = exact_dt(t_end, dt)
        n = round(t_end / d)
        worst = max(worst, abs(n * d - t_end) / t_end)
        good &= d <= dt * (1 + 1e-12)
    good &= check('exact_dt', worst < 1e-12, 'N dt = t_end to %.1e, dt never above the requested' % worst)
    hs = [1e-5, 3e-5, 1e-4, 3e-4]
    fit = convergence({'rows': [dict(method='stepping', rc=0, param=h, pos_err=0.02 * h ** 0.5) for h in hs]},
                      'stepping', 'pos_err', n=None)
    good &= check('convergence', abs(fit['slope'] - 0.5) < 1e-9 and fit['lo'] == 1e-5 and fit['hi'] == 3e-4,
                  'slope %.3f over [%g, %g] (expect 0.5 over [1e-05, 0.0003])' % (fit['slope'], fit['lo'], fit['hi']))

    from .bounce import collisions
    mass, ms = 2.0, 1e-3
    t = np.arange(2000) * ms
    knots = [(0, 1.0), (100, 1.0), (120, -0.9), (500, -0.9), (520, -0.8), (540, -0.8), (560, 0.72), (1000, 0.72),
             (1009, 0.0), (1010, 0.0), (1020, -0.72), (1900, -0.72), (1999, 0.5)]
    vx = np.interp(np.arange(2000), [k for k, _ in knots], [v for _, v in knots])
    P = np.zeros((len(t), 3))
    P[:, 0] = mass * vx
    got = collisions(t, P, mass, dict(merge=5e-3, v_min=0.1))
    want = [(0.1, 1.0, 0.9), (0.5, 0.9, 0.8), (1.0, 0.72, 1.0)]
    good &= check('collisions', len(got) == 3 and all(
        g[1] == 0 and abs(g[0] - w[0]) < 1.5 * ms and abs(g[2] - w[1]) < 1e-9 and abs(g[3] - w[2]) < 1e-9
        for g, w in zip(got, want)),
        '%s (expect e = 0.9, 0.8 for a touch joined with its bounce 20 ms later, 1.0 across a 1 ms gap; '
        'the contact still on at the end left out)' % [tuple(round(v, 4) for v in g) for g in got])
    from .minority import quality          # the stiff-minority study's element quality
    reg = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float)
    right = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    flat = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1 / 3, 1 / 3, 1e-3]], float)     # altitude 1e-3 over the base
    vol, alt, rr = quality(np.vstack([reg, right, flat]), np.array([[0, 1, 2, 3], [4, 5, 6, 7], [8, 9, 10, 11]]))
    good &= check('quality', abs(rr[0] - 1) < 1e-12 and abs(vol[1] - 1 / 6) < 1e-15
                  and abs(alt[1] - 1 / np.sqrt(3)) < 1e-12 and rr[2] < 0.01 and abs(alt[2] - 1e-3) < 1e-12,
                  'radius ratio of a regular tetrahedron %.15f, of a flat one %.2g (altitude %.3g, expect 1e-3); right '
                  'corner: V = %.6f, smallest altitude %.6f (1/sqrt 3)' % (rr[0], rr[2], alt[2], vol[1], alt[1]))

    m, se = A.block_mean(rng.normal(size=10000))
    good &= check('block_mean', abs(se - 0.01) < 0.003 and abs(m) < 0.05, 'mean %.4f, SE %.4f (expect 0.01)' % (m, se))

    a, n = 1.5, 5
    base = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    cells = np.array([[i, j, k] for i in range(n) for j in range(n) for k in range(n)], float)
    x = ((cells[:, None, :] + base[None, :, :]).reshape(-1, 3)) * a
    box = np.full(3, n * a)
    r, gs = A.rdf(x[None], box, 3, rmax=0.5 * n * a, nbins=300)
    rp, pk, _ = A.first_peak(r, gs)
    dr = r[1] - r[0]
    rho = len(x) / box.prod()
    r_nn = a / np.sqrt(2)
    want = 12 / (4 * np.pi * r_nn ** 2 * dr * rho)
    good &= check('rdf', abs(rp - r_nn) <= dr and abs(pk / want - 1) < 0.05,
                  'peak at %.4f (expect %.4f), height %.1f (expect %.1f)' % (rp, r_nn, pk, want))

    D, dt, F, N = 0.7, 0.01, 400, 500
    steps = rng.normal(scale=np.sqrt(2 * D * dt), size=(F, N, 3))
    xs = np.cumsum(steps, axis=0)
    d, dse = A.diffusion(np.arange(F) * dt, xs, 3)
    good &= check('diffusion', abs(d / D - 1) < 0.1, 'D = %.3f +- %.3f (expect %.3f)' % (d, dse, D))

    f0, dt, F = 2.5, 0.02, 512
    t = np.arange(F) * dt
    ph = rng.uniform(0, 2 * np.pi, size=(1, 50, 3))
    v = np.cos(2 * np.pi * f0 * t[:, None, None] + ph)
    pk, _, freqs, _ = A.vdos_peak(t, v, 3)
    good &= check('vdos_peak', abs(pk - f0) <= freqs[1], 'peak %.3f (expect %.3f, bin %.3f)' % (pk, f0, freqs[1]))

    ref = rng.normal(size=(3, 20, 3))
    sh = ref + np.array([0.3, 0.4, 0.0])
    e = A.traj_error(np.array([0.0, 1.0, 2.0]), sh, np.array([0.0, 1.0, 2.0]), ref, 1.0)
    good &= check('traj_error', abs(e - 0.5) < 1e-12, '%.15f (expect 0.5)' % e)

    th = {'time': np.linspace(0, 10, 101), 'etotal': -5 + 0.02 * np.linspace(0, 10, 101),
          'px': np.zeros(101), 'py': np.zeros(101), 'pz': np.zeros(101)}
    em = A.energy_metrics(th, 4)
    good &= check('energy', abs(em['drift'] - 0.005) < 1e-12 and abs(em['max_de'] - 0.05) < 1e-12,
                  'drift %.6g (expect 0.005), max %.6g (expect 0.05)' % (em['drift'], em['max_de']))

    build = sys.argv[1] if len(sys.argv) > 1 else ''
    an = A.Analyzer(build) if build else None
    if an is None or an.exe is None:
        print('terrace-analyze: not checked (no BUILD_DIR/terrace-analyze)')
        return 0 if good else 1

    class Scene:
        dim, periodic, pot = 3, True, {'sigma': 1.0}

    sc = Scene()
    sc.observables = ['gr']
    frames = np.repeat(x[None], 4, axis=0)
    o = an.observables(sc, np.arange(4) * 0.1, frames, None, box)
    r_t = A.rdf(x[None], box, 3, rmax=min(0.5 * n * a, 3.0), nbins=200)[0]
    dr_t = r_t[1] - r_t[0]
    want_t = 12 / (4 * np.pi * r_nn ** 2 * dr_t * rho)
    good &= check('tool rdf', o['gr_method'] == 'terrace-analyze' and abs(o['gr_r'] - r_nn) <= dr_t
                  and abs(o['gr_peak'] / want_t - 1) < 0.05,
                  'peak at %.4f (expect %.4f), height %.1f (expect %.1f)' % (o['gr_r'], r_nn, o['gr_peak'], want_t))

    sc.observables = ['msd']
    D, dt = 0.7, 0.01
    o = an.observables(sc, np.arange(xs.shape[0]) * dt, xs, None, np.full(3, 1000.0))
    good &= check('tool D', abs(o['D'] / D - 1) < 0.1 and abs(o['D'] - D) < 3 * o['D_se'],
                  'D = %.3f +- %.3f (expect %.3f)' % (o['D'], o['D_se'], D))

    sc.observables = ['vdos']
    f0, dt = 2.5, 0.02
    o = an.observables(sc, t, np.zeros_like(v), v, np.full(3, 100.0))
    res = 1.0 / (0.5 * (len(t) - 1) * dt)
    good &= check('tool vdos', abs(o['vdos'] - f0) <= res, 'peak %.3f (expect %.3f, resolution %.3f)'
                  % (o['vdos'], f0, res))
    return 0 if good else 1


if __name__ == '__main__':
    sys.exit(main())
