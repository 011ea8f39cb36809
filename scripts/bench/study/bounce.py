"""The many-collision run of the study (scene `bounce` of scripts/bench/study.py): one rubber ball
bouncing inside a closed box of rigid walls, both integrators, over 10^2 to 10^3 collisions.

The ball: scripts/make_ball_mesh.py --refine 3 (R = 0.1 m, 208 nodes, 672 tetrahedra; one of its
two balls, moved to the origin), rho = 1100 kg/m^3, lambda = 2.7 MPa, mu = 0.3 MPa, thrown at
(1.5, 1.0, 0.7) m/s without spin inside the box -0.15 .. 0.15 m (&potential walls = 'box', the
default wall stiffness E h_b and distance h_b/2), so that it hits all six walls.
  - velocity Verlet's largest stable step: bisection of dt (geometric, to 3 %) on runs of
    t_bisect (a third of the long run, or all of it); a run fails when the engine stops it or
    max |E - E0| exceeds 10 % of E0 (solids.py);
  - velocity Verlet at 0.9, 0.5 and a smaller fraction of that step, energy stepping at several h,
    each for t_long
    (and energy stepping at the smaller h for t_short, its cost growing as h falls);
  - from each run's thermo (every `thermo` s): E(t) - E0 (for energy stepping also K + k h, the
    thermo column e_terraced), the translational kinetic energy of the centre of mass in free
    flight (per axis the last velocity no wall of that axis was changing) against E0, and per
    collision the restitution. The box's walls are axis-aligned,
    so a wall acts on P along its own axis only (the elements conserve P): a collision with an x
    wall is an interval where P_x changes (intervals joined while v_x has not reversed, or when
    closer than `merge` s), its normal
    speeds are v_x before and after, e = -v_out / v_in where the ball came in at more than
    `v_min` m/s (slower touches are counted, not rated).
Writes bench_data/bounce_<mode>.json and .csv, figures/bench_bounce.png and the page section between
<!-- bounce:begin --> and <!-- bounce:end --> of benchmarks.md.
"""
import csv
import json
import math
import os
import re
import subprocess
import sys

import numpy as np

from .common import REPO, exact_dt, read_thermo, splice_section
from . import solids

PARAMS = {
    'quick': dict(refine=3, half=0.15, v=(1.5, 1.0, 0.7), thermo=2.5e-4, t_bisect=10.0, bisect=(1e-4, 5e-4),
                  t_long=30.0, t_short=3.0, vv_factors=[0.9, 0.5, 0.125], hs_long=[1e-2], hs_short=[3e-3, 1e-3],
                  merge=5e-3, v_min=0.1, bin=0.05),
    'full': dict(refine=3, half=0.15, v=(1.5, 1.0, 0.7), thermo=2.5e-4, t_bisect=30.0, bisect=(1e-4, 5e-4),
                 t_long=30.0, t_short=30.0, vv_factors=[0.9, 0.5, 0.25, 0.125], hs_long=[1e-2, 3e-3, 1e-3],
                 hs_short=[3e-4], merge=5e-3, v_min=0.1, bin=0.05),
}
DENSITY = 1100.0
MATERIAL = "&potential style='neohookean', lambda=2.7e6, mu=3.0e5, walls='box' /"
_BASE = {}


def make_mesh(p, work):
    """One ball of make_ball_mesh.py's pair, centred at the origin: (file name, info line, mass)."""
    two = os.path.join(work, 'two_balls.msh')
    r = subprocess.run([sys.executable, os.path.join(REPO, 'scripts', 'make_ball_mesh.py'), two, '--refine',
                        str(p['refine'])], cwd=work, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError('bounce: mesh: %s' % (r.stdout + r.stderr).strip()[-300:])
    lines = open(two).read().split('\n')
    i = lines.index('$Nodes')
    nodes = np.array([[float(v) for v in ln.split()[1:4]] for ln in lines[i + 2:i + 2 + int(lines[i + 1])]])
    j = lines.index('$Elements')
    tets = np.array([[int(v) for v in ln.split()[5:9]] for ln in lines[j + 2:j + 2 + int(lines[j + 1])]
                     if ln.split()[3] == '1']) - 1
    n = tets.max() + 1                      # ball 1's nodes come first (tags 1..N)
    x = nodes[:n] - nodes[:n].mean(axis=0)
    name = 'ball%d.msh' % p['refine']
    with open(os.path.join(work, name), 'w') as f:
        f.write('$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 1 "ball"\n$EndPhysicalNames\n')
        f.write('$Nodes\n%d\n' % n + ''.join('%d %.17g %.17g %.17g\n' % (k + 1, *q) for k, q in enumerate(x)))
        f.write('$EndNodes\n$Elements\n%d\n' % len(tets))
        f.write(''.join('%d 4 2 1 1 %d %d %d %d\n' % (e + 1, *(t + 1)) for e, t in enumerate(tets)))
        f.write('$EndElements\n')
    d = x[tets[:, 1:]] - x[tets[:, :1]]
    vol = float(np.sum(np.abs(np.einsum('ij,ij->i', d[:, 0], np.cross(d[:, 1], d[:, 2])))) / 6)
    info = ('one ball of `make_ball_mesh.py --refine %g` (%d nodes, %d tetrahedra, %.4g kg)'
            % (p['refine'], n, len(tets), DENSITY * vol))
    return name, info, DENSITY * vol


def deck(p, mesh, integrator, t_end, name, thermo=True):
    h = p['half']
    out = "thermo_interval=%r, thermo_file='%s.csv'" % (p['thermo'] if thermo else t_end, name)
    return ("&run units='si', dimension=3, run_time=%r, seed=1 /\n"
            "&system mesh_file='%s', mass_density=%r, periodic=.false.,.false.,.false.,\n"
            "        box_lo=%r,%r,%r, box_hi=%r,%r,%r, velocity(:,1)=%r,%r,%r /\n%s\n%s\n&output %s /\n"
            % (t_end, mesh, DENSITY, -h, -h, -h, h, h, h, *p['v'], MATERIAL, integrator, out))


def one_run(ctx, work, p, mesh, method, param, t_end, mass):
    if method == 'verlet':
        param = exact_dt(t_end, param)
        integ = solids.verlet(param)
    else:
        integ = solids.stepping(param)
    name = '%s_%s_%g_%g' % (os.path.splitext(mesh)[0], method, param, t_end)
    if mesh not in _BASE:               # the zero-length run's CPU time, best of 3
        bn = os.path.splitext(mesh)[0] + '_zero'
        _BASE[mesh] = min(solids._cpu_run(ctx, work, bn, deck(p, mesh, solids.verlet(1e-4), 0, bn, thermo=False)
                                          .replace('run_time=0,', 'n_steps=0,'))[1] for _ in range(3))
    r, cpu = solids._cpu_run(ctx, work, name, deck(p, mesh, integ, t_end, name))
    row = dict(method=method, param=param, t_end=t_end, rc=r['rc'], error=r['error'], cpu=cpu - _BASE[mesh],
               n=r.get('n'), events=r.get('events'), refl=r.get('refl'))
    th = read_thermo(os.path.join(work, name + '.csv')) if r['rc'] == 0 else {}
    if r['rc'] == 0 and th:
        row.update(analyse(th, mass, p))
    elif r['rc'] == 0:
        row['rc'], row['error'] = -1, 'no thermo output'
    return row


def collisions(t, P, mass, p):
    """Per collision (time, axis, incoming normal speed, restitution or None) from the momentum."""
    out = []

    def reversed_(s, e):
        """The normal velocity changed sign over samples s .. e (the ball left the wall it hit)."""
        return pa[s] * pa[e] < 0
    for a in range(3):
        pa = P[:, a]
        moving = np.abs(np.diff(pa)) > 1e-9 * max(1.0, np.max(np.abs(pa)))
        idx = np.flatnonzero(np.diff(np.r_[0, moving.astype(int), 0]))
        spans = []
        for s, e in zip(idx[::2], idx[1::2]):          # samples s .. e: P changes between them
            if spans and (t[s] - t[spans[-1][1]] < p['merge'] or not reversed_(*spans[-1])):
                spans[-1][1] = e                        # the same collision: a short gap, or not yet bounced
            else:
                spans.append([s, e])
        for s, e in spans:
            if e >= len(t) - 1:                        # still in contact when the run ends
                continue
            force = pa[e] - pa[s]                      # the wall's impulse: its sign says which wall
            vin, vout = pa[s] / mass, pa[e] / mass
            vn_in = -vin * np.sign(force)               # towards the wall
            rest = float(vout * np.sign(force) / vn_in) if vn_in > p['v_min'] else None
            out.append((float(t[s]), a, float(vn_in), rest))
    out.sort()
    return out


def analyse(th, mass, p):
    t = th['time']
    E = th['etotal']
    P = np.stack([th['px'], th['py'], th['pz']], 1)
    ktr = np.sum(P * P, axis=1) / (2 * mass)
    # the centre of mass's kinetic energy in free flight: along each axis the last velocity at which
    # no wall of that axis touched the ball (P_a not changing), so contacts do not dip it
    free = np.empty_like(P)
    for a in range(3):
        still = np.r_[True, np.abs(np.diff(P[:, a])) <= 1e-9 * max(1.0, np.max(np.abs(P[:, a])))]
        still &= np.r_[np.abs(np.diff(P[:, a])) <= 1e-9 * max(1.0, np.max(np.abs(P[:, a]))), True]
        last = np.maximum.accumulate(np.where(still, np.arange(len(t)), 0))
        free[:, a] = P[last, a]
    kfree = np.sum(free * free, axis=1) / (2 * mass)
    e0 = float(E[0])
    col = collisions(t, P, mass, p)
    rated = [c for c in col if c[3] is not None]
    nb = max(1, int(round(t[-1] / p['bin'])))
    edges = np.linspace(0, t[-1], nb + 1)
    which = np.clip(np.searchsorted(edges, t, side='right') - 1, 0, nb - 1)
    de = np.abs(E - e0)
    env = np.zeros(nb)
    np.maximum.at(env, which, de)
    kt = np.full(nb, np.nan)
    for b in range(nb):                         # the translational energy at each bin's end
        sel = np.flatnonzero(which == b)
        if len(sel):
            kt[b] = kfree[sel[-1]] / e0
    res = dict(e0=e0, max_de=float(de.max()), end_de=float(E[-1] - e0), ktr_end=float(kfree[-1] / e0),
               n_coll=len(col), n_rated=len(rated),
               bins=[float('%.5g' % x) for x in edges[1:]], env=[float('%.4g' % x) for x in env],
               ktr=[float('%.4g' % x) for x in kt],
               coll=[[float('%.6g' % c[0]), c[1], float('%.4g' % c[2]), None if c[3] is None else float('%.5g' % c[3])]
                     for c in col])
    half = len(t) // 2                          # the drift: a line through E - E0 over the second half
    res['drift'] = float(np.polyfit(t[half:], E[half:] - e0, 1)[0]) if len(t) > 4 else 0.0
    if 'e_terraced' in th:
        res['kh_spread'] = float(np.ptp(th['e_terraced']))
    return res


def bisect(ctx, work, p, mesh, mass):
    lo, hi = p['bisect']
    tried = []

    def test(dt):
        row = one_run(ctx, work, p, mesh, 'verlet', dt, p['t_bisect'], mass)
        ok = row['rc'] == 0 and row['max_de'] <= solids.FAIL_FRACTION * row['e0']
        why = ('ok (max |E - E0| = %.3g J)' % row['max_de']) if ok else (
            row['error'] if row['rc'] != 0 else 'max |E - E0| = %.3g J > %g E0' % (row['max_de'], solids.FAIL_FRACTION))
        tried.append(dict(dt=dt, ran=row['param'], ok=ok, why=why))
        print('      bounce bisection dt = %.4g s: %s' % (row['param'], why), flush=True)
        return ok
    if not test(lo):
        raise RuntimeError('bounce: Verlet dt = %g is not stable' % lo)
    if test(hi):
        return dict(stable=tried[-1]['ran'], fail=None, fail_why='', tried=tried)
    while hi / lo > 1.03:
        mid = math.sqrt(lo * hi)
        if test(mid):
            lo = mid
        else:
            hi = mid
    ran = {x['dt']: x['ran'] for x in tried}
    return dict(stable=ran[lo], fail=ran[hi], fail_why=solids.short_why([x['why'] for x in tried if x['dt'] == hi][0]),
                tried=tried)


def run(ctx):
    p = PARAMS[ctx.mode]
    work = os.path.join(ctx.work, 'bounce')
    os.makedirs(work, exist_ok=True)
    mesh, info, mass = make_mesh(p, work)
    print('    bounce: %s' % info, flush=True)
    res = dict(mode=ctx.mode, env=dict(ctx.env), params=p, mesh=info, mass=mass, runs=[])
    bs = bisect(ctx, work, p, mesh, mass)
    res['bisect'] = bs
    plan = ([('verlet', f * bs['stable'], p['t_long'], '%g x the largest stable dt' % f) for f in p['vv_factors']]
            + [('stepping', h, p['t_long'], '') for h in p['hs_long']]
            + [('stepping', h, p['t_short'], '') for h in p['hs_short']])
    for method, param, t_end, note in plan:
        row = one_run(ctx, work, p, mesh, method, param, t_end, mass)
        row['note'] = note
        res['runs'].append(row)
        print('    bounce %-8s %s = %.4g %s, %g s: %s' % (
            method, 'dt' if method == 'verlet' else 'h', row['param'], note, t_end,
            ('%d collisions, max |E - E0| = %.3g J, cpu %.3g s' % (row['n_coll'], row['max_de'], row['cpu']))
            if row['rc'] == 0 else 'failed: ' + row['error']), flush=True)
    for f in os.listdir(work):
        if f.endswith('.csv') and not ctx.keep:
            os.remove(os.path.join(work, f))
    save(ctx, res)
    return res


def save(ctx, res):
    base = os.path.join(ctx.data, 'bounce_%s' % res['mode'])
    with open(base + '.json', 'w') as f:
        json.dump(res, f, indent=None, separators=(',', ':'))
    with open(base + '.csv', 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['method', 'param', 't_end', 'rc', 'cpu', 'steps_or_events', 'collisions', 'rated', 'max_de',
                    'end_de', 'drift_J_per_s', 'kh_spread', 'e_mean_first20', 'e_mean_last100', 'e_std', 'ktr_end'])
        for r in res['runs']:
            s = stats(r)
            w.writerow([r['method'], r['param'], r['t_end'], r['rc'], r['cpu'], r.get('events') or r.get('n'),
                        r.get('n_coll'), r.get('n_rated'), r.get('max_de'), r.get('end_de'), r.get('drift'),
                        r.get('kh_spread'), s.get('first'), s.get('last'), s.get('std'), r.get('ktr_end')])


def load(ctx):
    path = os.path.join(ctx.data, 'bounce_%s.json' % ctx.mode)
    return json.load(open(path)) if os.path.exists(path) else None


def stats(r):
    e = np.array([c[3] for c in r.get('coll', []) if c[3] is not None], float)
    if not len(e):
        return {}
    return dict(first=float(np.mean(e[:20])), last=float(np.mean(e[-100:])), std=float(np.std(e)),
                lo=float(np.min(e)), hi=float(np.max(e)))


def ktr_at(r, t):
    """The centre of mass's free-flight kinetic energy over E0 in the sample bin nearest t."""
    bins, ktr = np.asarray(r['bins'], float), np.asarray(r['ktr'], float)
    return float(ktr[np.argmin(np.abs(bins - t))]) if len(bins) else np.nan


def _label(r):
    if r['method'] == 'verlet':
        return 'Verlet dt = %.3g s (%s)' % (r['param'], r['note'])
    return 'energy stepping h = %g J' % r['param']


def figure(res, path):
    from terrace_tools.plotting import plt, save as save_figure
    runs = [r for r in res['runs'] if r['rc'] == 0]
    colors = {}
    vv_c, es_c = ['tab:blue', 'tab:cyan', 'tab:purple'], ['tab:red', 'tab:orange', 'tab:brown', 'tab:olive']
    for r in runs:
        pool = vv_c if r['method'] == 'verlet' else es_c
        colors[id(r)] = pool[sum(1 for q in runs[:runs.index(r)] if q['method'] == r['method']) % len(pool)]
    short = min(r['t_end'] for r in runs) if runs else 1.0
    fig, axs = plt.subplots(3, 2, figsize=(14, 11), sharex='col', gridspec_kw=dict(width_ratios=[2.2, 1]))
    for col, t_max in ((0, None), (1, short)):
        for r in runs:
            c = colors[id(r)]
            t = np.array(r['bins'])
            keep = t <= (t_max or t[-1]) + 1e-9
            axs[0, col].semilogy(t[keep], np.maximum(np.array(r['env'])[keep], 1e-12), '-', color=c, lw=1,
                                 label=_label(r))
            if r['method'] == 'stepping':
                axs[0, col].axhline(r['param'], color=c, ls=':', lw=0.8)
            axs[1, col].plot(t[keep], np.array(r['ktr'])[keep], '-', color=c, lw=1.2)
            rated = [x for x in r['coll'] if x[3] is not None and x[0] <= (t_max or x[0])]
            tc, ec = np.array([x[0] for x in rated]), np.array([x[3] for x in rated])
            axs[2, col].plot(tc, ec, '.', color=c, ms=2.5, alpha=0.5)
            k = 20
            if len(ec) >= k:
                axs[2, col].plot(tc[k - 1:], np.convolve(ec, np.ones(k) / k, mode='valid'), '-', color=c, lw=1.5,
                                 label=_label(r) + ': mean of 20')
        axs[2, col].set_xlabel('time [s]')
        axs[2, col].set_ylim(0.75, 1.25)
        for ax in axs[:, col]:
            ax.grid(True, which='both', alpha=0.3)
    axs[0, 1].set_title('the first %g s' % short, fontsize=9)
    axs[0, 0].set_title('the whole run', fontsize=9)
    fig.suptitle('one rubber ball in a closed box of walls: %s, E0 = %.3g J (dotted: h)' %
                 (res['mesh'].replace('`', ''), runs[0]['e0'] if runs else 0), fontsize=10)
    axs[0, 0].set_ylabel('max |E(t) − E0| per %g s [J]' % res['params']['bin'])
    axs[1, 0].set_ylabel('centre-of-mass kinetic energy\nin free flight / E0')
    axs[2, 0].set_ylabel('restitution per collision\n(dots; lines: mean of 20)')
    handles, labels = axs[2, 0].get_legend_handles_labels()
    fig.legend(handles, labels, fontsize=8, loc='lower center', ncol=3, frameon=False)
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.11, top=0.93, hspace=0.1, wspace=0.14)
    save_figure(fig, path, dpi=100, tight=False)


def section(ctx, res):
    e = res['env']
    p = res['params']
    bs = res['bisect']
    L = ['<!-- bounce:begin -->', '## Many collisions: a rubber ball in a closed box of walls\n',
         '`%s` (commit %s%s), %s, load %s at the start; made by `scripts/bench/study/bounce.py`.\n'
         % (re.sub(r' --work \S+', '', e.get('command', '?')), e.get('commit', '?'),
            ' + uncommitted changes' if e.get('dirty') else '', e.get('date', '?'), e.get('load', '?')),
         '%s, rho = 1100 kg/m³, λ = 2.7 MPa, μ = 0.3 MPa, thrown at (%g, %g, %g) m/s without spin inside the '
         'box ±%g m (`&potential walls = \'box\'`, default wall stiffness E h_b and distance h_b/2). Velocity '
         'Verlet\'s largest stable step on %g s runs: **%.3g s** (%s). A collision with an x wall is an interval '
         'where P_x changes (walls act along their own axis only; intervals joined while v_x has not reversed, '
         'or closer than %g ms); its restitution '
         'e = −v_out/v_in of the centre of mass along that axis, rated where the ball came in faster than %g m/s. '
         'The centre of mass\'s kinetic energy in free flight: along each axis the last velocity at which no '
         'wall of that axis touched the ball. CPU time less a zero-length run. Drift: the slope of a line '
         'through E − E0 over the run\'s second half.\n'
         % (res['mesh'], *p['v'], p['half'], p['t_bisect'], bs['stable'],
            ('fails at %.3g s: %s' % (bs['fail'], bs['fail_why'])) if bs.get('fail')
            else 'no failure up to the bracket',
            1e3 * p['merge'], p['v_min']),
         '| run | length [s] | steps / events | CPU [s] | collisions (rated) | max \\|E − E0\\| [J] '
         '| E(end) − E0 [J] | drift [J/s] | spread of K + k h [J] | mean e, first 20 | mean e, last 100 | std e '
         '| e min – max | centre-of-mass K in free flight / E0 after 3 s | at the end |',
         '|---' * 15 + '|']
    for r in res['runs']:
        if r['rc'] != 0:
            L.append('| %s | %g | failed: %s |%s' % (_label(r), r['t_end'], r['error'].replace('|', '\\|')[:120],
                                                      ' |' * 12))
            continue
        s = stats(r)
        L.append('| %s | %g | %s | %.3g | %d (%d) | %.3g | %.3g | %.2g | %s | %.4f | %.4f | %.3f | %.2f – %.2f '
                 '| %.3f | %.3f |' % (
            _label(r), r['t_end'], r.get('events') or r.get('n'), r['cpu'], r['n_coll'], r['n_rated'], r['max_de'],
            r['end_de'], r['drift'], '%.2g' % r['kh_spread'] if 'kh_spread' in r else '–', s.get('first', np.nan),
            s.get('last', np.nan), s.get('std', np.nan), s.get('lo', np.nan), s.get('hi', np.nan), ktr_at(r, 3.0),
            r['ktr_end']))
    L.append('')
    L.append('![Energy error, centre-of-mass energy and restitution over many collisions](figures/bench_bounce.png)\n')
    L.append('<!-- bounce:end -->')
    return L


def write_report(ctx, res=None):
    res = res or load(ctx)
    if not res:
        return []
    figure(res, os.path.join(ctx.figs, 'bench_bounce.png'))
    return section(ctx, res)


def splice(path, lines):
    splice_section(path, lines, 'bounce', 'stiffness')
