"""The mesh scenes of the study: the talk's spinning neo-Hookean cube and the two
colliding rubber balls, both integrators.

Per scene:
  - velocity Verlet's largest stable step, found by a bisection of dt (geometric, to 3 %) on short
    runs; a run fails when the engine stops it (energy blow-up, inverted element) or when
    max |E - E0| exceeds 10 % of the initial energy;
  - energy stepping's mean event interval against h (the cube also on the talk's 8 x 8 x 8 mesh);
  - run time against error: Verlet over dt and energy stepping over h, each against a Verlet
    reference with a much finer step: max |E(t) - E0|, max |L(t) - L0| / |L0|, and the largest
    node-position difference from the reference at the end of the run (final-state files);
  - balls: the event intervals of one energy-stepping run (a thermo line per event) before, during
    and after the contact (contact start and end from scripts/balls_analysis.py on its trajectory).
Writes bench_data/solids_<scene>_<mode>.json and .csv, figures/bench_<scene>_wp.png,
figures/bench_<scene>_intervals.png, and the page section (section(ctx)).
"""
import csv
import json
import math
import os
import re
import resource
import subprocess
import sys

import numpy as np

from .common import REPO, exact_dt, run_terrace, read_thermo

SOLID_KEYS = ['cube', 'balls']
FAIL_FRACTION = 0.1          # a Verlet run fails when max |E - E0| > 10 % of E0 (or the engine stops it)
# The cost measure: the CPU time (user + system) of the run's process less that of a zero-length run on
# the same mesh (start-up, mesh reading, final output). On this shared 2-vCPU machine under a load of
# 10-20 the loop's wall time varied by up to 9x between two runs of the same deck; the CPU time does
# not count the time the process waited for a core. The loop wall time is kept in the CSV ('wall').
COST = 'cpu'
_BASE = {}
MATERIAL = "&potential style='neohookean', lambda=2.7e6, mu=3.0e5 /"

PARAMS = {
    'cube': {
        'quick': dict(cells=4, t_long=0.05, thermo=0.0005, dt_ref=1.0e-6,
                      dts=[5e-6, 1e-5, 2e-5, 5e-5, 1e-4], hs=[1e-2, 3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5],
                      bisect=(1e-5, 1e-3), bisect_time=0.05,
                      talk=dict(cells=8, t=0.01, hs=[1e-2, 3e-3, 1e-3, 3e-4, 1e-4], bisect=(1e-5, 4e-4),
                                bisect_time=0.01)),
        'full': dict(cells=8, t_long=0.05, thermo=0.0005, dt_ref=1.0e-6,
                     dts=[5e-6, 1e-5, 2e-5, 5e-5], hs=[1e-2, 3e-3, 1e-3, 3e-4, 1e-4],
                     bisect=(1e-5, 1e-3), bisect_time=0.1,
                     talk=dict(cells=8, t=0.01, hs=[1e-2, 3e-3, 1e-3, 3e-4, 1e-4], bisect=(1e-5, 4e-4),
                               bisect_time=0.02)),
    },
    'balls': {
        'quick': dict(refine=3, gap=0.035, t_long=0.065, thermo=0.0005, dt_ref=2.0e-6, traj=2.5e-4,
                      dts=[5e-6, 1e-5, 2e-5, 4e-5], hs=[3e-3, 1e-3, 3e-4, 1e-4, 3e-5, 1e-5], h_events=1e-3,
                      bisect=(1e-5, 1e-3), bisect_time=0.065,
                      # the deck's mesh and gap (input/balls_es.nml: refine 4, 5 cm), its 0.1 s
                      deck=dict(refine=4, gap=None, t_long=0.1, hs=[1e-3], bisect=(1e-5, 1e-3))),
        'full': dict(refine=4, gap=0.035, t_long=0.065, thermo=0.0005, dt_ref=1.0e-6, traj=2.5e-4,
                     dts=[5e-6, 1e-5, 2e-5, 4e-5], hs=[3e-3, 1e-3, 3e-4, 1e-4, 3e-5], h_events=1e-3,
                     bisect=(1e-5, 1e-3), bisect_time=0.065),
    },
}
TITLES = {'cube': "the talk's spinning neo-Hookean cube (rubber, 0.1 m, 100 rad/s)",
          'balls': 'two colliding rubber balls with contact (R = 0.1 m, 1 m/s, 10 rad/s)'}


# ------------------------------------------------------------------------------------ decks
def _deck(scene, mesh, integrator, t_end, thermo, name, traj=0.0, every=0):
    if scene == 'cube':
        motion = "angular_velocity(:,1)=0.0,0.0,100.0"
    else:
        motion = "velocity(:,2)=-1.0,0.0,0.0, angular_velocity(:,2)=0.0,0.0,10.0"
    out = ("thermo_every=%d" % every) if every else ("thermo_interval=%r" % thermo)
    out += ", thermo_file='%s.csv', final_atoms_file='%s.final'" % (name, name)
    if traj:
        out += ", trajectory_file='%s.h5', trajectory_interval=%r, overwrite=.true." % (name, traj)
    return ("&run units='si', dimension=3, run_time=%r, seed=1 /\n"
            "&system mesh_file='%s', mass_density=1100.0, periodic=.false.,.false.,.false., %s /\n%s\n%s\n"
            "&output %s /\n" % (t_end, mesh, motion, MATERIAL, integrator, out))


def verlet(dt):
    return "&integrator style='velocity_verlet', dt=%r /" % dt


def stepping(h):
    return "&integrator style='energy_stepping', terrace_height=%r /" % h


def make_mesh(scene, p, work, cells=None):
    if scene == 'cube':
        n = cells or p['cells']
        name = 'cube%d.msh' % n
        cmd = [sys.executable, os.path.join(REPO, 'scripts', 'make_cube_mesh.py'), name, '--cells', str(n),
               '--size', '0.1', '--center']
    else:
        name = 'balls%d.msh' % p['refine']
        cmd = [sys.executable, os.path.join(REPO, 'scripts', 'make_ball_mesh.py'), name, '--refine',
               str(p['refine'])] + (['--gap', str(p['gap'])] if p.get('gap') else [])
    r = subprocess.run(cmd, cwd=work, capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError('%s: mesh: %s' % (scene, (r.stdout + r.stderr).strip()[-300:]))
    return name, r.stdout.strip()


def read_final(path):
    a = np.loadtxt(path, comments='#', ndmin=2)
    return a[:, 1:4]


# ------------------------------------------------------------------------------------ runs
def one_run(ctx, scene, work, mesh, method, param, p, ref=None, t_end=None, traj=0.0, every=0, contact=False):
    t_end = t_end or p['t_long']
    requested = param
    if method == 'verlet':          # dt = t_end / N: the run ends exactly at t_end
        param = exact_dt(t_end, param)
    name = '%s_%s_%g' % (os.path.splitext(mesh)[0], method, param)
    integ = verlet(param) if method == 'verlet' else stepping(param)
    if mesh not in _BASE:           # the zero-length run's CPU time, best of 3
        bn = os.path.splitext(mesh)[0] + '_zero'
        _BASE[mesh] = min(_cpu_run(ctx, work, bn, _deck(scene, mesh, verlet(p['dt_ref']), 0, p['thermo'], bn)
                                   .replace('run_time=0,', 'n_steps=0,'))[1] for _ in range(3))
    r, cpu = _cpu_run(ctx, work, name, _deck(scene, mesh, integ, t_end, p['thermo'], name, traj, every))
    row = dict(scene=scene, method=method, param=param, requested=requested, t_end=t_end, rc=r['rc'], error=r['error'],
               cpu=cpu - _BASE[mesh], cpu_base=_BASE[mesh])
    th = read_thermo(os.path.join(work, name + '.csv')) if r['rc'] == 0 else {}
    if r['rc'] == 0 and th:
        e = th['etotal']
        L = np.stack([th['lx'], th['ly'], th['lz']], 1)
        row.update(wall=(r['loop'] or 0.0) - (r.get('output') or 0.0), n=r['n'], e0=float(e[0]),
                   max_de=float(np.max(np.abs(e - e[0]))),
                   max_dl=float(np.max(np.linalg.norm(L - L[0], axis=1)) / np.linalg.norm(L[0])))
        if method == 'stepping':
            row.update(events=r.get('events'), mean_dt=r.get('mean_dt'), evals=r.get('evals'),
                       refl=r.get('refl'))
        x = read_final(os.path.join(work, name + '.final'))
        row['x'] = x
        row['k_hist'] = (th['time'], th['ke'])
        if method == 'stepping' and row.get('events'):
            row['refl_share'] = (row.get('refl') or 0) / row['events']
        if contact and traj:          # restitution and contact duration (balls_analysis.py)
            d, _ = contact_window(ctx, work, name)
            row.update(restitution=d['restitution'], contact=d['duration'], contact_start=d['t_start'])
        if ref is not None:
            row['pos_err'] = float(np.max(np.linalg.norm(x - ref['x'], axis=1)))
            tr, kr = ref['k_hist']            # kinetic energy history against the reference's, at its samples
            row['ke_err'] = float(np.max(np.abs(np.interp(tr, th['time'], th['ke']) - kr)))
            if 'restitution' in row and 'restitution' in ref:
                row['rest_err'] = abs(row['restitution'] - ref['restitution'])
                row['contact_err'] = abs(row['contact'] - ref['contact'])
    elif r['rc'] == 0:
        row['rc'], row['error'] = -1, 'no thermo output'
    row['name'] = name
    return row, th


def _cpu_run(ctx, work, name, deck):
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    r = run_terrace(ctx.terrace, work, name, deck, timeout=ctx.timeout)
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r, (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)


def stable(row):
    return row['rc'] == 0 and row.get('max_de') is not None and row['max_de'] <= FAIL_FRACTION * row['e0']


def bisect_dt(ctx, scene, work, mesh, p, lo, hi, t_end):
    """Largest stable Verlet dt within 3 %: lo must be stable and hi must fail (both checked)."""
    tried = []

    def test(dt):
        row, _ = one_run(ctx, scene, work, mesh, 'verlet', dt, p, t_end=t_end)
        ok = stable(row)
        why = ('ok (max |E - E0| = %.3g J)' % row['max_de']) if ok else (row['error'] if row['rc'] != 0 else
                               'max |E - E0| = %.3g J > %g E0' % (row['max_de'], FAIL_FRACTION))
        tried.append(dict(dt=dt, ran=row['param'], ok=ok, why=why, max_de=row.get('max_de')))
        print('      %s bisection dt = %.4g s (ran %.4g s, %g s / N): %s' % (mesh, dt, row['param'], t_end, why),
              flush=True)
        return ok
    if not test(lo):
        raise RuntimeError('%s: Verlet dt = %g is not stable' % (mesh, lo))
    if test(hi):
        return dict(stable=tried[-1]['ran'], fail=None, tried=tried, t_end=t_end)
    while hi / lo > 1.03:
        mid = math.sqrt(lo * hi)
        if test(mid):
            lo = mid
        else:
            hi = mid
    fail_why = short_why([t['why'] for t in tried if t['dt'] == hi][0])
    ran = {t['dt']: t['ran'] for t in tried}          # the steps that ran (t_end / N, at most the bracket's)
    return dict(stable=ran[lo], fail=ran[hi], fail_why=fail_why, tried=tried, t_end=t_end,
                stable_de=[t['max_de'] for t in tried if t['dt'] == lo][0])


def short_why(msg):
    """The engine's failure message in a few words."""
    m = re.search(r'at time\s+([0-9.Ee+-]+) \(step (\d+)\)', msg)
    if 'energy blow-up' in msg and m:
        return 'the engine stops it: energy blow-up at t = %.3g s, step %s' % (float(m.group(1)), m.group(2))
    m = re.search(r'at step (\d+), time\s+([0-9.Ee+-]+)', msg)
    if 'inside out' in msg and m:
        return 'the engine stops it: an element turned inside out at t = %.3g s, step %s' % (float(m.group(2)),
                                                                                           m.group(1))
    return re.sub(r'(?<!\\)\|', r'\\|', msg)      # (a message escaped before stays as it is)


def event_split(ctx, work, mesh, p, h):
    """One energy-stepping run with a thermo line per event and a trajectory: event times and intervals,
    the contact window (balls_analysis.py), the run's row."""
    row, th = one_run(ctx, 'balls', work, mesh, 'stepping', h, p, traj=0.0005, every=1)
    if row['rc'] != 0:
        raise RuntimeError('balls: %s h = %g: %s' % (mesh, h, row['error']))
    d, text = contact_window(ctx, work, row['name'])
    t = th['time']
    keep = np.r_[False, np.diff(th['events']) > 0]       # one line per event (and the start)
    te, dte = t[keep], np.diff(t)[keep[1:]]
    print('    balls  %s events at h = %g J: %d, contact %.4g to %.4g s' % (mesh, h, len(te), d['t_start'], d['t_end']),
          flush=True)
    row.pop('x', None)
    row.pop('k_hist', None)
    return dict(h=h, t=[float('%.7g' % x) for x in te], dt=[float('%.5g' % x) for x in dte], start=d['t_start'], end=d['t_end'], analysis=text.strip(),
                cpu=row['cpu'], max_de=row['max_de'], events=row['events'], refl=row.get('refl'))


def split_text(ev):
    t, dt = np.array(ev['t']), np.array(ev['dt'])
    s, e = ev['start'], ev['end']
    parts = []
    for lab, m in (('before', t < s), ('during', (t >= s) & (t <= e)), ('after', t > e)):
        if m.any():
            parts.append((lab, int(m.sum()), float(dt[m].mean()), float(np.median(dt[m])), float(dt[m].min())))
    return parts


def contact_window(ctx, work, name):
    """Contact start and end (s) from balls_analysis.py on the run's trajectory."""
    js = os.path.join(work, name + '.json')
    r = subprocess.run([sys.executable, os.path.join(REPO, 'scripts', 'balls_analysis.py'),
                        os.path.join(work, name + '.nml'), '--json', js], capture_output=True, text=True)
    if r.returncode != 0:
        raise RuntimeError('balls_analysis.py: %s' % r.stderr.strip()[-300:])
    d = json.load(open(js))
    return d, r.stdout


def run_scene(key, ctx):
    mode = ctx.mode
    p = PARAMS[key][mode]
    work = os.path.join(ctx.work, key)
    os.makedirs(work, exist_ok=True)
    mesh, mesh_info = make_mesh(key, p, work)
    print('    %s: %s' % (key, mesh_info.splitlines()[0] if mesh_info else mesh), flush=True)
    res = dict(scene=key, mode=mode, env=dict(ctx.env), params={k: v for k, v in p.items() if k != 'talk'}, mesh=mesh_info)
    # reference
    traj = p.get('traj', 0.0)          # balls: frames for restitution and contact duration
    ref_row, _ = one_run(ctx, key, work, mesh, 'verlet', p['dt_ref'], p, traj=traj, contact=bool(traj))
    if ref_row['rc'] != 0:
        raise RuntimeError('%s: reference failed: %s' % (key, ref_row['error']))
    xref = dict(x=ref_row.pop('x'), k_hist=ref_row.pop('k_hist'))
    for k in ('restitution', 'contact'):
        if k in ref_row:
            xref[k] = ref_row[k]
    res['reference'] = ref_row
    print('    %-6s reference  dt = %-8g cpu %7.2f s  max|dE| %9.3g J  |dL|/L %9.3g  (zero-length run: cpu %.2f s)'
          % (key, p['dt_ref'], ref_row['cpu'], ref_row['max_de'], ref_row['max_dl'], ref_row['cpu_base']), flush=True)
    # Verlet's stability limit first: the sweep adds a point at 90 % of it
    res['bisect'] = bisect_dt(ctx, key, work, mesh, p, p['bisect'][0], p['bisect'][1], p['bisect_time'])
    near = float('%.2g' % (0.9 * res['bisect']['stable']))
    rows = []
    for method, params in (('verlet', sorted(set(p['dts'] + [near]))), ('stepping', p['hs'])):
        for v in params:
            row, _ = one_run(ctx, key, work, mesh, method, v, p, ref=xref, traj=traj, contact=bool(traj))
            row.pop('x', None)
            row.pop('k_hist', None)
            rows.append(row)
            if row['rc'] == 0:
                print('    %-6s %-9s %-10g cpu %7.2f s (loop wall %6.2f s)  max|dE| %9.3g J  |dL|/L %9.3g  pos err %9.3g m%s'
                      % (key, method, v, row['cpu'], row['wall'], row['max_de'], row['max_dl'], row['pos_err'],
                         '  mean interval %.3g s (%d events)' % (row['mean_dt'], row['events'])
                         if method == 'stepping' else ''), flush=True)
            else:
                print('    %-6s %-9s %-10g FAILED: %s' % (key, method, v, row['error']), flush=True)
    res['rows'] = rows
    if getattr(ctx, 'reuse_extras', False):     # the talk's / the deck's mesh: keep the saved runs
        old = load(ctx, key) or {}
        for k in ('talk', 'deck'):
            if k in old:
                res[k] = old[k]
                res.setdefault('extras_from', old.get('env', {}))
    if key == 'cube' and 'talk' in PARAMS[key][mode] and 'talk' not in res:
        tk = PARAMS[key][mode]['talk']
        tmesh, info = make_mesh(key, p, work, cells=tk['cells'])
        talk = dict(mesh=info, t=tk['t'], rows=[])
        for h in tk['hs']:
            row, _ = one_run(ctx, key, work, tmesh, 'stepping', h, dict(p, thermo=tk['t']), t_end=tk['t'])
            row.pop('x', None)
            row.pop('k_hist', None)
            talk['rows'].append(row)
            print('    cube%d stepping h = %g J: %s events in %g s, mean interval %.3g s, cpu %.1f s'
                  % (tk['cells'], h, row.get('events'), tk['t'], row.get('mean_dt') or float('nan'),
                     row.get('cpu') or float('nan')), flush=True)
        talk['bisect'] = bisect_dt(ctx, key, work, tmesh, dict(p, thermo=tk['bisect_time'] / 20),
                                   tk['bisect'][0], tk['bisect'][1], tk['bisect_time'])
        # the bisection's runs are short: Verlet just below the limit over the talk deck's whole 0.1 s
        dtc = float('%.2g' % (0.97 * talk['bisect']['stable']))
        row, _ = one_run(ctx, key, work, tmesh, 'verlet', dtc, dict(p, thermo=0.002), t_end=0.1)
        row.pop('x', None)
        row.pop('k_hist', None)
        talk['confirm'] = row
        print('    cube%d verlet dt = %g s over 0.1 s: %s' % (tk['cells'], dtc, 'max |E - E0| = %.3g J, cpu %.2f s'
                                                           % (row['max_de'], row['cpu']) if row['rc'] == 0
                                                           else row['error']), flush=True)
        res['talk'] = talk
    if key == 'balls':
        res['events'] = event_split(ctx, work, mesh, p, p['h_events'])
        if p.get('deck') and 'deck' not in res:        # the deck's mesh (input/balls_es.nml): stability limit and event split only
            dk = dict(p, **p['deck'])
            dmesh, info = make_mesh(key, dk, work)
            deck = dict(mesh=info, refine=dk['refine'], t=dk['t_long'])
            deck['bisect'] = bisect_dt(ctx, key, work, dmesh, dk, dk['bisect'][0], dk['bisect'][1], dk['t_long'])
            deck['events'] = [event_split(ctx, work, dmesh, dk, h) for h in dk['hs']]
            res['deck'] = deck
    if not ctx.keep:
        for f in os.listdir(work):
            if f.endswith('.h5'):
                os.remove(os.path.join(work, f))
    save(ctx, res)
    return res


# ------------------------------------------------------------------------------------ output
def save(ctx, res):
    base = os.path.join(ctx.data, 'solids_%s_%s' % (res['scene'], res['mode']))
    with open(base + '.json', 'w') as f:
        json.dump(res, f, indent=1)
    fields = ['method', 'param', 'rc', 'cpu', 'cpu_base', 'wall', 'n', 'max_de', 'max_dl', 'pos_err', 'events', 'mean_dt', 'evals',
              'refl', 'refl_share', 'ke_err', 'restitution', 'rest_err', 'contact', 'contact_err', 'requested', 'error']
    with open(base + '.csv', 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(fields)
        for r in [dict(res['reference'], method='reference')] + res['rows']:
            w.writerow(['' if r.get(k) is None else ('%.6g' % r[k] if isinstance(r[k], float) else r[k])
                        for k in fields])


def load(ctx, key):
    path = os.path.join(ctx.data, 'solids_%s_%s.json' % (key, ctx.mode))
    return json.load(open(path)) if os.path.exists(path) else None


def _ok(rows, method, k):
    return sorted([r for r in rows if r['method'] == method and r['rc'] == 0 and r.get(k) and r.get(COST)],
                  key=lambda r: r['param'])


FIT_POINTS = 3      # the order of convergence: fitted over the runs with the 3 smallest dt or h


def convergence(res, method, k, n=FIT_POINTS):
    """Least-squares slope of log(error K) against log(dt or h) over the method's N finished runs with
    the smallest parameter (all with n=None); the fit range: the smallest and largest parameter used.
    None with fewer than 3 runs."""
    pts = sorted([r for r in res['rows'] if r['method'] == method and r['rc'] == 0 and r.get(k)],
                 key=lambda r: r['param'])
    if len(pts) < 3:
        return None
    pts = pts[:n] if n else pts
    x = np.array([r['param'] for r in pts])
    y = np.array([r[k] for r in pts])
    slope, icept = np.polyfit(np.log(x), np.log(y), 1)
    return dict(x=x.tolist(), y=y.tolist(), slope=float(slope), icept=float(icept), lo=float(x.min()),
                hi=float(x.max()), n=len(pts))


def fig_wp(res, path):
    import matplotlib
    import matplotlib.ticker
    from terrace_tools.plotting import plt, save as save_figure
    panels = [('pos_err', 'max node-position error at t = %g s  [m]' % res['params']['t_long'])] + \
        ([('rest_err', '|e − e_ref|: coefficient of restitution'), ('contact_err', '|t_c − t_c,ref|: contact duration  [s]')]
         if res['scene'] == 'balls' else [('ke_err', 'max |K(t) − K_ref(t)|: kinetic-energy history  [J]')])
    fig, axs = plt.subplots(1, len(panels) + 1, figsize=(4.7 * (len(panels) + 1), 4.6))
    for ax, (k, lab) in zip(axs, panels):
        for m, col, mk, name, unit in (('verlet', 'tab:blue', 'o', 'velocity Verlet (dt)', 's'),
                                       ('stepping', 'tab:red', 's', 'energy stepping (h)', 'J')):
            pts = _ok(res['rows'], m, k)
            if not pts:
                continue
            ax.loglog([r[k] for r in pts], [r[COST] for r in pts], '-', color=col, marker=mk, label=name)
            for r in pts:
                ax.annotate('%.3g' % r['param'], (r[k], r[COST]), textcoords='offset points', xytext=(4, 3),
                            fontsize=7, color=col)
        ax.set_xlabel(lab)
        ax.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
        ax.set_ylabel('CPU time [s] (run less a zero-length run)')
        ax.grid(True, which='both', alpha=0.3)
    axs[0].legend(fontsize=8, loc='lower left')
    ax = axs[-1]             # order of convergence: position error against dt and h, fitted slopes
    for m, col, mk, name in (('verlet', 'tab:blue', 'o', 'velocity Verlet: dt [s]'),
                             ('stepping', 'tab:red', 's', 'energy stepping: h [J]')):
        fit = convergence(res, m, 'pos_err')
        if not fit:
            continue
        allp = convergence(res, m, 'pos_err', n=None)
        ax.loglog(allp['x'], allp['y'], color=col, marker=mk, ls='none',
                  label='%s; slope %.2f (fit %.3g to %.3g)' % (name, fit['slope'], fit['lo'], fit['hi']))
        xs = np.array([fit['lo'], fit['hi']])
        ax.loglog(xs, np.exp(fit['icept']) * xs ** fit['slope'], '-', color=col, lw=1)
    ax.set_xlabel('dt [s] (Verlet) or h [J] (energy stepping)')
    ax.set_ylabel('max node-position error [m]')
    ax.set_title('order of convergence (least-squares fit)', fontsize=9)
    ax.legend(fontsize=7, loc='upper left')
    ax.grid(True, which='both', alpha=0.3)
    fig.suptitle('%s — %s, %g s per run; labels: dt in s, h in J' % (TITLES[res['scene']], _mesh_words(res),
                                                                      res['params']['t_long']), fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.94))
    save_figure(fig, path, dpi=110, tight=False)


def fig_intervals(res, path):
    import matplotlib
    from terrace_tools.plotting import plt, save as save_figure
    ev = res['events']
    t, dt = np.array(ev['t']), np.array(ev['dt'])
    s, e = ev['start'], ev['end']
    vv = res['bisect']['stable']
    fig, (a, b) = plt.subplots(1, 2, figsize=(13, 4.6))
    a.semilogy(t * 1e3, dt, '.', ms=2, color='tab:red', label='energy stepping, h = %g J: each event' % ev['h'])
    a.axvspan(s * 1e3, e * 1e3, color='0.85', label='contact (%.1f to %.1f ms)' % (s * 1e3, e * 1e3))
    a.axhline(vv, color='tab:blue', ls='--', label='velocity Verlet, largest stable dt = %.3g s' % vv)
    a.set_xlabel('time [ms]')
    a.set_ylabel('interval since the previous event [s]')
    a.legend(fontsize=8, loc='lower right')
    a.grid(True, which='both', alpha=0.3)
    bins = np.logspace(np.log10(max(dt[dt > 0].min(), 1e-12)), np.log10(dt.max()), 40)
    for lab, m, col in (('before', t < s, 'tab:green'), ('during', (t >= s) & (t <= e), 'tab:purple'),
                        ('after', t > e, 'tab:orange')):
        if m.any():
            b.hist(dt[m], bins=bins, histtype='step', lw=1.6, color=col,
                   label='%s contact: %d events, mean %.3g s' % (lab, m.sum(), dt[m].mean()))
    b.axvline(vv, color='tab:blue', ls='--', label='Verlet largest stable dt')
    b.set_xscale('log')
    b.set_yscale('log')
    b.set_xlabel('event interval [s]')
    b.set_ylabel('events')
    b.legend(fontsize=8, loc='upper right')
    b.grid(True, which='both', alpha=0.3)
    fig.suptitle('%s — %s: energy-stepping event intervals' % (TITLES['balls'], _mesh_words(res)), fontsize=10)
    fig.tight_layout(rect=(0, 0, 1, 0.94))
    save_figure(fig, path, dpi=110, tight=False)


def _mesh_words(res):
    m = res['mesh'].splitlines()[0] if res['mesh'] else ''
    if res['scene'] == 'cube':
        return '%d x %d x %d cells (%s)' % (res['params']['cells'], res['params']['cells'], res['params']['cells'],
                                            m.split(':', 1)[1].split(', volume')[0].strip() if ':' in m else m)
    return 'refine %d (%s per ball)' % (res['params']['refine'], m.split('): ', 1)[1].split(' per ball')[0]
                                         if '): ' in m else m)


def equal_error(res, k):
    """For each energy-stepping run: the cheapest Verlet run whose error K is no larger, and the wall-time
    ratio energy stepping / Verlet (>= 1: Verlet is that many times cheaper at no larger error). Rows
    (h, es error, es wall, dt, vv error, vv wall, ratio); dt None where no Verlet run is as accurate."""
    vv = _ok(res['rows'], 'verlet', k)
    out = []
    for r in _ok(res['rows'], 'stepping', k):
        good = [q for q in vv if q[k] <= r[k]]
        if good:
            q = min(good, key=lambda q: q[COST])
            out.append((r['param'], r[k], r[COST], q['param'], q[k], q[COST], r[COST] / q[COST], r['events'], q['n'],
                        r.get('refl')))
        else:
            out.append((r['param'], r[k], r[COST], None, None, None, None, r['events'], None, r.get('refl')))
    return out


def section(ctx, results, env):
    """The page section (markdown lines) from the solids results (this run's, or those saved before)."""
    L = ['<!-- solids:begin -->', '## Elastic solids: the spinning cube and the colliding balls\n']
    saved = [results.get(k) or load(ctx, k) for k in SOLID_KEYS]
    saved = [r for r in saved if r]
    if not saved:
        return []
    env = saved[0].get('env', env)
    L.append('Made by `scripts/bench/study/solids.py` (scenes `cube` and `balls` of `scripts/bench/study.py`; the '
             'command, date and load of each scene are under its heading), %s mode, on %s (%s CPUs). '
             'Each point is one run. Its cost is the **CPU time** of the run\'s '
             'process (user + system) less that of a zero-length run on the same mesh (start-up, mesh reading, '
             'final output): on this shared 2-vCPU machine, under a load of 10 to 20, the loop\'s wall time of '
             'the same deck varied up to 9-fold between two runs, the CPU time does not count the waits for a '
             'core (the loop wall time is in the tables too, and in the CSVs). CPU times under about 0.1 s (Verlet near its stable limit) still differ by up to 2 times '
             'between repeats; the ratio of energy-stepping events to Verlet steps in the equal-error tables does '
             'not depend on the machine. The error columns are exact. Velocity Verlet\'s largest stable step is a '
             'bisection of dt (geometric, to 3 %%): a run fails when the engine stops it (energy blow-up or an '
             'inverted element) or when max |E - E0| exceeds %g of the initial energy.\n'
             % (ctx.mode, env.get('cpu', '?'), env.get('nproc', '?'), FAIL_FRACTION))
    for key in SOLID_KEYS:
        res = results.get(key) or load(ctx, key)
        if not res:
            continue
        p = res['params']
        L.append('### %s\n' % TITLES[key])
        ev_ = res.get('env', env)
        L.append('`%s` (commit %s%s), %s, load %s at the start.\n'
                 % (re.sub(r' --work \S+', '', ev_.get('command', '?')), ev_.get('commit', '?'),
                    ' + uncommitted changes' if ev_.get('dirty') else '', ev_.get('date', '?'), ev_.get('load', '?')))
        if res.get('extras_from'):
            xf = res['extras_from']
            L.append('The runs on the %s are those of `%s` (commit %s, %s), kept by `--reuse-extras`.\n'
                     % ("talk's 8 x 8 x 8 mesh" if key == 'cube' else "deck's mesh",
                        re.sub(r' --work \S+', '', xf.get('command', '?')), xf.get('commit', '?'), xf.get('date', '?')))
        L.append('Mesh: %s. Reference: velocity Verlet at dt = %g s (max |E - E0| = %.2g J, initial energy '
                 '%.4g J). Runs of %g s.\n' % (_mesh_words(res), p['dt_ref'], res['reference']['max_de'],
                                                res['reference']['e0'], p['t_long']))
        bs = res['bisect']
        bs['fail_why'] = short_why(bs.get('fail_why', '-'))
        if res.get('talk'):
            res['talk']['bisect']['fail_why'] = short_why(res['talk']['bisect'].get('fail_why', '-'))
        if key == 'cube' and res.get('talk'):
            tk = res['talk']
            tb = tk['bisect']
            L.append("Energy stepping's mean event interval against h on the talk's 8 x 8 x 8 cube (%s; runs of "
                     "%g s from the deck's start, the cube at rest in its reference shape and spinning) and on the sweep's %d x %d x %d cube (runs of %g s), beside velocity "
                     "Verlet's largest stable step on each mesh:\n"
                     % (tk['mesh'].split(': ', 1)[1].split(', volume')[0] if ': ' in tk['mesh'] else '',
                        tk['t'], p['cells'], p['cells'], p['cells'], p['t_long']))
            L.append('| h [J] | 8x8x8: events | 8x8x8: reflections | 8x8x8: mean interval [s] | 8x8x8: ray passes/event | '
                     '8x8x8: max \\|E − E0\\| [J] | 8x8x8: CPU per simulated second [s] | %dx%dx%d: mean interval [s] |'
                     % (p['cells'], p['cells'], p['cells']))
            L.append('|---|---|---|---|---|---|---|---|')
            small = {r['param']: r for r in res['rows'] if r['method'] == 'stepping'}
            c = tk.get('confirm')
            for r in tk['rows']:
                sm = small.get(r['param'])
                L.append('| %g | %s | %s | %s | %s | %s | %s | %s |' % (
                    r['param'], r.get('events', '-'),
                    ('%.1f %%' % (100.0 * r['refl'] / r['events'])) if r.get('refl') is not None and r.get('events') else '–',
                    '%.3g' % r['mean_dt'] if r.get('mean_dt') else r.get('error'),
                    '%.3g' % r['evals'] if r.get('evals') else '-',
                    '%.2g' % r['max_de'] if r.get('max_de') is not None else '-',
                    ('%.3g (%.2g x Verlet\'s)' % (r['cpu'] / tk['t'], (r['cpu'] / tk['t']) / (c['cpu'] / 0.1))
                     if c and c['rc'] == 0 else '%.3g' % (r['cpu'] / tk['t'])) if r.get('cpu') else '-',
                    '%.3g' % sm['mean_dt'] if sm and sm.get('mean_dt') else '-'))
            c = tk.get('confirm')
            L.append('| **Verlet, largest stable dt** | | | **%.3g** (max \\|E − E0\\| %.2g J; fails at %.3g: %s; runs of '
                     '%g s) | | %s | %s | **%.3g** (max \\|E − E0\\| %.2g J; fails at %.3g: %s; runs of %g s) |\n'
                     % (tb['stable'], tb.get('stable_de', float('nan')), tb['fail'] or float('nan'),
                        tb.get('fail_why', '-'), tb['t_end'],
                        ('%.2g (at dt = %g s, over 0.1 s)' % (c['max_de'], c['param'])) if c and c['rc'] == 0 else '-',
                        ('%.3g (at dt = %g s, below)' % (c['cpu'] / 0.1, c['param'])) if c and c['rc'] == 0 else '-',
                        bs['stable'], bs.get('stable_de', float('nan')),
                        bs['fail'] or float('nan'), bs.get('fail_why', '-'), bs['t_end']))
            if c:
                L.append("On the talk's mesh, velocity Verlet at dt = %g s runs the deck's whole 0.1 s "
                         "(input/cube_spin_verlet.nml, which uses 2.5e-5 s): %s.\n"
                         % (c['param'], ('max |E − E0| = %.2g J, %d steps, %.2g s CPU' % (c['max_de'], c['n'], c['cpu']))
                            if c['rc'] == 0 else 'it fails: ' + short_why(c['error'])))
        else:
            L.append("Velocity Verlet's largest stable step on this mesh and contact stiffness: **%.3g s** "
                     "(max |E − E0| %.2g J there; fails at %.3g s: %s; runs of %g s through the whole collision).\n"
                     % (bs['stable'], bs.get('stable_de', float('nan')), bs['fail'] or float('nan'),
                        bs.get('fail_why', '-'), bs['t_end']))
        balls = key == 'balls'
        extra = (['restitution e (\\|e − e_ref\\|)', 'contact duration [ms] (\\|error\\| [s])'] if balls
                 else ['max \\|K − K_ref\\| [J]'])
        L.append('| method | parameter | CPU [s] | loop wall [s] | steps / events | mean interval [s] | reflections | '
                 'max \\|E − E0\\| [J] | max \\|L − L0\\|/\\|L0\\| | max position error [m] | ' + ' | '.join(extra) + ' |')
        L.append('|---' * (10 + len(extra)) + '|')
        ref = res['reference']
        if balls and ref.get('restitution') is not None:
            L.append('| reference: velocity Verlet | dt = %g s | | | %d | | | %.2g | | | %.5f | %.4f |'
                     % (ref['param'], ref['n'], ref['max_de'], ref['restitution'], ref['contact'] * 1e3))
        for r in res['rows']:
            if r['rc'] != 0:
                L.append('| %s | %s = %g | failed: %s |%s' % (r['method'], 'dt' if r['method'] == 'verlet'
                                                              else 'h', r['param'], r['error'], ' |' * (7 + len(extra))))
                continue
            if balls:
                ex = ['%.5f (%.2g)' % (r['restitution'], r['rest_err']) if r.get('rest_err') is not None else '-',
                      '%.4f (%.2g)' % (r['contact'] * 1e3, r['contact_err']) if r.get('contact_err') is not None else '-']
            else:
                ex = ['%.3g' % r['ke_err'] if r.get('ke_err') is not None else '-']
            L.append('| %s | %s = %.4g %s | %.3g | %.3g | %d | %.3g | %s | %.3g | %.2g | %.3g | %s |' % (
                'velocity Verlet' if r['method'] == 'verlet' else 'energy stepping',
                'dt' if r['method'] == 'verlet' else 'h', r['param'], 's' if r['method'] == 'verlet' else 'J',
                r[COST], r['wall'], r['events'] if r['method'] == 'stepping' else r['n'],
                r['mean_dt'] if r['method'] == 'stepping' else r['param'],
                ('%.1f %%' % (100 * r['refl'] / r['events'])) if r['method'] == 'stepping' and r.get('events')
                else '–', r['max_de'], r['max_dl'], r['pos_err'], ' | '.join(ex)))
        L.append('')
        L.append('Velocity Verlet runs use dt = t_end / N (N = the requested step rounded up), so every run ends '
                 'exactly at t = %g s; the table gives the step that ran. Energy stepping\'s max \\|E − E0\\| is '
                 'bounded by h by construction and \\|ΔL\\|/\\|L0\\| is round-off for both methods, so the figure '
                 'shows the measures that separate them: the position error%s, and the order of convergence.\n'
                 % (p['t_long'], ', the restitution and contact-duration errors against the reference' if balls
                    else ', the kinetic-energy history against the reference\'s'))
        L.append(conv_table(res))
        L.append('![run time against error, %s](figures/bench_%s_wp.png)\n' % (key, key))
        if key == 'balls' and res.get('events'):
            ev = res['events']
            t, dt = np.array(ev['t']), np.array(ev['dt'])
            s, e = ev['start'], ev['end']
            parts = []
            for lab, m in (('before', t < s), ('during', (t >= s) & (t <= e)), ('after', t > e)):
                if m.any():
                    parts.append('%s the contact %d events, mean interval %.3g s (median %.3g s, shortest %.3g s)'
                                 % (lab, m.sum(), dt[m].mean(), np.median(dt[m]), dt[m].min()))
            L.append('Event intervals of energy stepping at h = %g J (a thermo line per event; contact from %.2f to '
                     '%.2f ms by scripts/balls_analysis.py on the same run): %s; Verlet\'s largest stable dt on the '
                     'same mesh and contact stiffness is %.3g s.\n' % (ev['h'], s * 1e3, e * 1e3, '; '.join(parts),
                                                                      bs['stable']))
            L.append('![event intervals before, during and after the contact](figures/bench_balls_intervals.png)\n')
        if key == 'balls' and res.get('deck'):
            dk = res['deck']
            db = dk['bisect']
            L.append("On the deck's mesh (input/balls_es.nml: %s, the deck's 5 cm gap, runs of %g s): velocity "
                     "Verlet's largest stable step is **%.3g s** (max \\|E − E0\\| %.2g J there; fails at %.3g s: %s)."
                     % (dk['mesh'].split(': ', 1)[1].split('; mean')[0] if ': ' in dk['mesh'] else dk['mesh'], dk['t'],
                        db['stable'], db.get('stable_de', float('nan')), db['fail'] or float('nan'),
                        short_why(db.get('fail_why', '-'))))
            L.append('')
            L.append('| energy stepping h [J] | events | reflections | max \\|E − E0\\| [J] | CPU [s] | contact [ms] | before: events, '
                     'mean interval [s] | during: events, mean, median, shortest [s] | after: events, mean [s] | '
                     'Verlet stable dt / mean interval during the contact |')
            L.append('|---|---|---|---|---|---|---|---|---|---|')
            for ev in dk['events']:
                parts = {q[0]: q for q in split_text(ev)}
                b_, d_, a_ = parts.get('before'), parts.get('during'), parts.get('after')
                L.append('| %g | %d | %s | %.2g | %.3g | %.2f to %.2f | %s | %s | %s | %s |' % (
                    ev['h'], ev['events'],
                    ('%.1f %%' % (100.0 * ev['refl'] / ev['events'])) if ev.get('refl') is not None else '–', ev['max_de'], ev['cpu'], ev['start'] * 1e3, ev['end'] * 1e3,
                    '%d, %.3g' % (b_[1], b_[2]) if b_ else '-',
                    '%d, %.3g, %.3g, %.3g' % (d_[1], d_[2], d_[3], d_[4]) if d_ else '-',
                    '%d, %.3g' % (a_[1], a_[2]) if a_ else '-', '%.3g' % (db['stable'] / d_[2]) if d_ else '-'))
            L.append('')
        eq = {k: equal_error(res, k) for k in ('max_de', 'pos_err')}
        L.append(verdict_line(res, eq))
    L.append('<!-- solids:end -->')
    return L


def conv_table(res):
    """Markdown: fitted order of convergence of each error measure against dt (Verlet) and h (energy stepping)."""
    ks = [('pos_err', 'position error')] + ([('rest_err', 'restitution error'), ('contact_err', 'contact-duration error')]
                                           if res['scene'] == 'balls' else [('ke_err', 'kinetic-energy history error')])
    L = ['Order of convergence: least-squares slope of log(error) against log(dt) for velocity Verlet and log(h) for '
         'energy stepping, over the %d runs with the smallest dt or h (fit range in brackets; the errors there, '
         'smallest parameter first), and over all runs of the table:\n' % FIT_POINTS,
         '| error | velocity Verlet: slope in dt [range, s] | errors [range] | all runs | energy stepping: slope in h '
         '[range, J] | errors [range] | all runs |', '|---|---|---|---|---|---|---|']
    for k, word in ks:
        cells = []
        for m in ('verlet', 'stepping'):
            f = convergence(res, m, k)
            a = convergence(res, m, k, n=None)
            if f:
                cells += ['**%.2f** [%.3g, %.3g]' % (f['slope'], f['lo'], f['hi']),
                          ', '.join('%.2g' % y for y in f['y']),
                          '%.2f [%.3g, %.3g] (%d runs)' % (a['slope'], a['lo'], a['hi'], a['n'])]
            else:
                cells += ['-', '-', '-']
        L.append('| %s | %s |' % (word, ' | '.join(cells)))
    return '\n'.join(L) + '\n'


def verdict_line(res, eq):
    words = {'max_de': 'max \\|E − E0\\|', 'pos_err': 'position error'}
    eq = {k: eq[k] for k in words}
    L = ['| energy stepping h [J] | reflections | CPU [s] | ' + ' | '.join(
        'cheapest Verlet with no larger %s: dt [s], CPU [s] → CPU ratio (events / steps)' % words[k] for k in eq) + ' |',
        '|---|---|---|' + '---|' * len(eq)]
    hs = [q[0] for q in eq['max_de']]
    for i, h in enumerate(hs):
        cells = []
        for k in eq:
            q = eq[k][i]
            cells.append('none as accurate' if q[3] is None else '%.3g, %.3g → **%.2g x** (%d / %d = %.2g)'
                         % (q[3], q[5], q[6], q[7], q[8], q[7] / q[8]))
        q = eq['max_de'][i]
        L.append('| %g | %s | %.3g | %s |' % (h, ('%.1f %%' % (100.0 * q[9] / q[7])) if q[9] is not None and q[7] else '–',
                                             q[2], ' | '.join(cells)))
    ratios = [q[6] for k in ('max_de', 'pos_err') for q in eq[k] if q[6] is not None]
    if ratios and min(ratios) >= 1:
        win = ('**Velocity Verlet wins on this scene**: for every energy-stepping run there is a Verlet run with '
               'no larger energy and position error that is %.2g to %.2g times cheaper in CPU time (a lower '
               'bound where the Verlet run is far more accurate); the ratio of energy-stepping events to Verlet '
               'steps, which does not depend on the load of the machine, tells the same (each event costs a force '
               'pass and 1 to 3 ray passes, each step one force pass). Angular momentum is conserved to round-off '
               'by both (|ΔL|/|L| ~ 1e-15), so it does not separate them.'
               % (min(ratios), max(ratios)))
    elif ratios and max(ratios) < 1:
        win = ('**Energy stepping wins on this scene**: it is %.2g to %.2g times cheaper than the cheapest '
               'Verlet run with no larger error.' % (1 / max(ratios), 1 / min(ratios)))
    else:
        win = ('**Mixed**: ratios from %.2g to %.2g (energy stepping CPU / Verlet CPU at no larger error).'
               % (min(ratios), max(ratios))) if ratios else 'No comparison possible.'
    return '\n'.join(L) + '\n\n' + win + '\n'


def write_report(ctx, results, env):
    """Figures, and the section spliced into DOC/benchmarks.md between its markers (or appended)."""
    for key in SOLID_KEYS:
        res = results.get(key) or load(ctx, key)
        if not res:
            continue
        fig_wp(res, os.path.join(ctx.figs, 'bench_%s_wp.png' % key))
        if res.get('events'):
            fig_intervals(res, os.path.join(ctx.figs, 'bench_%s_intervals.png' % key))
    return section(ctx, results, env)


def splice(path, lines):
    if not lines:
        return
    text = open(path).read() if os.path.exists(path) else ''
    block = '\n'.join(lines)
    b, e = '<!-- solids:begin -->', '<!-- solids:end -->'
    head = '## Elastic solids: the spinning cube and the colliding balls'
    if e in text and (b not in text or text.index(b) > text.index(e)) and head in text \
            and text.index(head) < text.index(e):
        b = head                     # a page whose begin marker was lost: the section starts at its heading
    if b in text and e in text and text.index(b) < text.index(e):
        text = text[:text.index(b)] + block + text[text.index(e) + len(e):]
    else:
        anchor = '## Full mode and what is pending'
        if anchor in text:
            i = text.index(anchor)
            text = text[:i] + block + '\n\n' + text[i:]
        else:
            text = text.rstrip('\n') + '\n\n' + block + '\n'
    with open(path, 'w') as f:
        f.write(text)
