"""Stiffness sweeps of the mesh scenes (scene `stiffness` of scripts/bench/study.py): how each
integrator's cost follows a stiffer contact and a nearly incompressible material.

  - contact stiffness k = 1x to 1024x the default E h_b on the two colliding balls (refine 3, 3.5 cm
    gap, 0.065 s: the whole collision);
  - Poisson's ratio 0.3 to 0.4999 on the spinning 4 x 4 x 4 cube (mu fixed at 0.3 MPa, lambda =
    2 nu mu / (1 - 2 nu); 0.05 s).
Per point: velocity Verlet's largest stable step (bisection of dt = t_end / N, to 3 %; failure as in
solids.py), the CPU time of the Verlet run at the largest stable step and at 0.5 of it; energy
stepping at one h: events, mean interval, share of reflections, CPU time, max |E - E0|. Writes
bench_data/stiffness_<mode>.json and .csv, figures/bench_stiffness.png and the page section between
<!-- stiffness:begin --> and <!-- stiffness:end --> of benchmarks.md.
"""
import csv
import json
import os
import re

import numpy as np

from . import solids
from .common import splice_section

PARAMS = {
    'quick': dict(k_factors=[1, 4, 16, 64, 256, 1024], nus=[0.3, 0.4, 0.45, 0.49, 0.499, 0.4999], h=1e-3,
                  balls=dict(refine=3, gap=0.035, t_long=0.065, thermo=0.0005, dt_ref=2e-6),
                  cube=dict(cells=4, t_long=0.05, thermo=0.0005, dt_ref=1e-6),
                  bisect=(None, 1e-3), es_timeout=300),
    'full': dict(k_factors=[1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024], nus=[0.3, 0.4, 0.45, 0.49, 0.499, 0.4999],
                 h=1e-3, balls=dict(refine=4, gap=0.035, t_long=0.065, thermo=0.0005, dt_ref=1e-6),
                 cube=dict(cells=8, t_long=0.05, thermo=0.0005, dt_ref=1e-6),
                 bisect=(None, 1e-3), es_timeout=3600),
}
MU = 3.0e5
LAM = 2.7e6


def _material(lam, mu, k=None):
    return ("&potential style='neohookean', lambda=%r, mu=%r%s /"
            % (lam, mu, (', contact_stiffness=%r' % k) if k else ''))


def _young(lam, mu):
    return mu * (3 * lam + 2 * mu) / (lam + mu)


def _point(ctx, scene, work, mesh, p, P, material, label, guess):
    """Bisection, Verlet at the limit and at half of it, energy stepping at h: one row. GUESS: an estimate
    of the largest stable step (the bisection starts at half of it, halved again while that fails)."""
    saved = solids.MATERIAL
    solids.MATERIAL = material            # the decks of solids.py with this material
    try:
        lo, hi = 0.5 * guess, P['bisect'][1]
        for _ in range(4):
            try:
                bs = solids.bisect_dt(ctx, scene, work, mesh, p, lo, hi, p['t_long'])
                break
            except RuntimeError:
                lo *= 0.25
        else:
            raise RuntimeError('%s: no stable Verlet step found down to %g s' % (label, lo))
        row = dict(label=label, stable=bs['stable'], fail=bs.get('fail'), fail_why=bs.get('fail_why', ''))
        for tag, f in (('vv', 1.0), ('vv_half', 0.5)):
            r, _ = solids.one_run(ctx, scene, work, mesh, 'verlet', f * bs['stable'], p)
            row[tag] = dict(dt=r['param'], rc=r['rc'], cpu=r['cpu'], n=r.get('n'), max_de=r.get('max_de'),
                            error=r['error'])
        old = ctx.timeout
        ctx.timeout = P['es_timeout']
        try:
            r, _ = solids.one_run(ctx, scene, work, mesh, 'stepping', P['h'], p)
        finally:
            ctx.timeout = old
        row['es'] = dict(h=P['h'], rc=r['rc'], cpu=r['cpu'], events=r.get('events'), mean_dt=r.get('mean_dt'),
                         refl=r.get('refl'), max_de=r.get('max_de'), e0=r.get('e0'),
                         error=r['error'] if r['rc'] != 124 else 'over %d s' % P['es_timeout'])
    finally:
        solids.MATERIAL = saved
    es = row['es']
    print('    stiffness %-28s Verlet stable dt %.3g s (cpu %.3g s)  energy stepping h = %g: %s'
          % (label, row['stable'], row['vv']['cpu'], P['h'],
             ('%d events, mean %.3g s, %.1f %% reflections, cpu %.3g s'
              % (es['events'], es['mean_dt'], 100.0 * es['refl'] / max(1, es['events']), es['cpu']))
             if es['rc'] == 0 else 'failed: ' + es['error']), flush=True)
    return row


def run(ctx):
    P = PARAMS[ctx.mode]
    work = os.path.join(ctx.work, 'stiffness')
    os.makedirs(work, exist_ok=True)
    res = dict(mode=ctx.mode, env=dict(ctx.env), params={k: v for k, v in P.items()}, contact=[], poisson=[])
    pb = P['balls']
    mesh, info = solids.make_mesh('balls', pb, work)
    hb = float(re.search(r'mean boundary edge ([0-9.eE+-]+) m', info).group(1))
    k0 = _young(LAM, MU) * hb
    res['balls_mesh'], res['k0'] = info.splitlines()[0], k0
    print('    stiffness: %s; default contact stiffness E h_b = %.4g N/m' % (res['balls_mesh'], k0), flush=True)
    for f in P['k_factors']:
        row = _point(ctx, 'balls', work, mesh, pb, P, _material(LAM, MU, f * k0),
                     'balls, k = %g x E h_b' % f, 2.3e-4 / np.sqrt(f))
        row.update(factor=f, k=f * k0)
        res['contact'].append(row)
    pc = P['cube']
    mesh, info = solids.make_mesh('cube', pc, work)
    res['cube_mesh'] = info.splitlines()[0]
    for nu in P['nus']:
        lam = 2 * nu * MU / (1 - 2 * nu)
        row = _point(ctx, 'cube', work, mesh, pc, P, _material(lam, MU), 'cube, nu = %g' % nu,
                     1.8e-4 * np.sqrt((LAM + 2 * MU) / (lam + 2 * MU)))
        row.update(nu=nu, lam=lam)
        res['poisson'].append(row)
    for f in os.listdir(work):
        if f.endswith('.h5'):
            os.remove(os.path.join(work, f))
    save(ctx, res)
    return res


def save(ctx, res):
    base = os.path.join(ctx.data, 'stiffness_%s' % res['mode'])
    with open(base + '.json', 'w') as f:
        json.dump(res, f, indent=1)
    with open(base + '.csv', 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['sweep', 'value', 'vv_stable_dt', 'vv_cpu', 'vv_max_de', 'vv_half_cpu', 'vv_half_max_de', 'es_h',
                    'es_events', 'es_mean_dt', 'es_refl', 'es_cpu', 'es_max_de', 'es_error'])
        for sweep, key in (('contact', 'factor'), ('poisson', 'nu')):
            for r in res[sweep]:
                es = r['es']
                w.writerow([sweep, r[key], r['stable'], r['vv']['cpu'], r['vv'].get('max_de'), r['vv_half']['cpu'],
                            r['vv_half'].get('max_de'), es['h'], es.get('events'), es.get('mean_dt'), es.get('refl'),
                            es['cpu'] if es['rc'] == 0 else '', es.get('max_de'), es['error']])


def load(ctx):
    path = os.path.join(ctx.data, 'stiffness_%s.json' % ctx.mode)
    return json.load(open(path)) if os.path.exists(path) else None


def figure(res, path):
    import matplotlib
    from terrace_tools.plotting import plt, save as save_figure
    fig, axs = plt.subplots(1, 2, figsize=(12.5, 4.6))
    for ax, sweep, key, xl in ((axs[0], 'contact', 'factor', 'contact stiffness / (E h_b)'),
                               (axs[1], 'poisson', 'nu', "Poisson's ratio nu")):
        rows = res[sweep]
        x = np.array([r[key] for r in rows], float)
        xp = x if sweep == 'contact' else 1.0 / (1.0 - 2.0 * x)
        vv = [r['vv']['cpu'] if r['vv']['rc'] == 0 else np.nan for r in rows]
        vh = [r['vv_half']['cpu'] if r['vv_half']['rc'] == 0 else np.nan for r in rows]
        es = [r['es']['cpu'] if r['es']['rc'] == 0 else np.nan for r in rows]
        ax.loglog(xp, vv, 'o-', color='tab:blue', label='velocity Verlet at its largest stable dt')
        ax.loglog(xp, vh, 'o--', color='tab:cyan', label='velocity Verlet at half of it')
        ax.loglog(xp, es, 's-', color='tab:red', label='energy stepping, h = %g J' % res['params']['h'])
        for xi, r in zip(xp, rows):
            if r['es']['rc'] == 0 and r['es'].get('events'):
                ax.annotate('%.0f %%' % (100.0 * r['es']['refl'] / r['es']['events']), (xi, r['es']['cpu']),
                            textcoords='offset points', xytext=(4, 4), fontsize=7, color='tab:red')
        if sweep == 'poisson':
            ax.set_xticks(xp)
            ax.set_xticklabels(['%g' % v for v in x], fontsize=7)
            ax.minorticks_off()
            xl += ' (axis: 1 / (1 − 2 nu), the bulk-to-shear stiffness)'
        ax.set_xlabel(xl)
        ax.set_ylabel('CPU time [s] (run less a zero-length run)')
        ax.grid(True, which='both', alpha=0.3)
        ax.legend(fontsize=8, loc='upper left')
    axs[0].set_title('two colliding balls, %g s (labels: reflections)' % res['params']['balls']['t_long'], fontsize=9)
    axs[1].set_title('spinning cube, %g s (labels: reflections)' % res['params']['cube']['t_long'], fontsize=9)
    save_figure(fig, path, dpi=110)


def section(ctx, res):
    if not res:
        return []
    e = res['env']
    P = res['params']
    L = ['<!-- stiffness:begin -->', '## Stiffness sweeps: a stiffer contact, a nearly incompressible material\n',
         '`%s` (commit %s%s), %s, load %s at the start; made by `scripts/bench/study/stiffness.py`.\n'
         % (re.sub(r' --work \S+', '', e.get('command', '?')), e.get('commit', '?'),
            ' + uncommitted changes' if e.get('dirty') else '', e.get('date', '?'), e.get('load', '?')),
         'Each point: velocity Verlet\'s largest stable step (bisection to 3 %% on runs of the whole length, '
         'failure as above), the CPU time of the Verlet run at that step and at half of it, and energy stepping '
         'at h = %g J (events, mean interval, share of reflections, CPU time; runs over %d s are stopped). The '
         'balls: %s, contact stiffness k in multiples of the default E h_b = %.4g N/m, %g s. The cube: %s, '
         'mu = 0.3 MPa and lambda = 2 nu mu / (1 − 2 nu), %g s.\n'
         % (P['h'], P['es_timeout'], res['balls_mesh'], res['k0'], P['balls']['t_long'], res['cube_mesh'],
            P['cube']['t_long'])]
    hdr = ('| %s | Verlet largest stable dt [s] | Verlet CPU [s] (max \\|E − E0\\| [J]) | Verlet at dt/2: CPU [s] '
           '(max \\|E − E0\\| [J]) | energy stepping: events | mean interval [s] | reflections | CPU [s] | '
           'max \\|E − E0\\| [J] | CPU energy stepping / Verlet |')
    for sweep, key, name in (('contact', 'factor', 'k / (E h_b)'), ('poisson', 'nu', "Poisson's ratio")):
        L.append(hdr % name)
        L.append('|---' * 10 + '|')
        for r in res[sweep]:
            es, vv, vh = r['es'], r['vv'], r['vv_half']
            ok = es['rc'] == 0
            L.append('| %g | %.3g | %s | %s | %s | %s | %s | %s | %s | %s |' % (
                r[key], r['stable'],
                '%.3g (%.2g)' % (vv['cpu'], vv['max_de']) if vv['rc'] == 0 else 'failed',
                '%.3g (%.2g)' % (vh['cpu'], vh['max_de']) if vh['rc'] == 0 else 'failed',
                es['events'] if ok else 'failed: %s' % es['error'].replace('|', '\\|')[:80],
                '%.3g' % es['mean_dt'] if ok else '', ('%.1f %%' % (100.0 * es['refl'] / es['events'])) if ok else '',
                '%.3g' % es['cpu'] if ok else '', '%.2g' % es['max_de'] if ok else '',
                '%.2g' % (es['cpu'] / vv['cpu']) if ok and vv['rc'] == 0 and vv['cpu'] > 0 else '–'))
        L.append('')
    L.append('![CPU time against stiffness](figures/bench_stiffness.png)\n')
    L.append('<!-- stiffness:end -->')
    return L


def write_report(ctx, res=None):
    res = res or load(ctx)
    if not res:
        return []
    figure(res, os.path.join(ctx.figs, 'bench_stiffness.png'))
    return section(ctx, res)


def splice(path, lines):
    splice_section(path, lines, 'stiffness', 'solids')
