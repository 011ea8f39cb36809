"""Work-precision sweep of one scene: Terrace velocity Verlet over dt, Terrace energy stepping over
h, LAMMPS velocity Verlet over dt, all from the same start state and over the same simulated time,
against a Terrace Verlet reference with a much finer step."""
import csv
import os

import numpy as np

from . import analysis as A
from .common import exact_dt, run_terrace, run_lammps, read_thermo, read_h5md, read_lammps_dump, have_lammps

FIELDS = ['scene', 'method', 'param', 'param_label', 'status', 'wall', 'loop', 'output', 'n', 'natoms',
          't_long', 'max_de', 'drift', 'max_dp', 'traj_err', 'T', 'T_se', 'P', 'P_se', 'gr_r', 'gr_peak',
          'gr_peak_se', 'D', 'D_se', 'vdos', 'vdos_se', 'gr_method', 'de_over_h', 'events', 'refl_frac', 'evals', 'mean_dt',
          'search', 'comm', 'pair']


def _terrace_row(scene, r, method, param, label, p, natoms):
    row = dict(scene=scene.key, method=method, param=param, param_label=label, natoms=natoms, t_long=p['t_long'])
    if r['rc'] != 0:
        row['status'] = 'error: ' + r['error']
        return row
    row['status'] = 'ok'
    row.update(loop=r['loop'], output=r.get('output', 0.0), n=r['n'], search=r.get('search', 0.0),
               comm=r.get('comm', 0.0), pair=r.get('pair', 0.0))
    row['wall'] = (r['loop'] or 0.0) - (r.get('output') or 0.0)
    if 'events' in r:
        row.update(events=r['events'], refl_frac=r['refl'] / max(1, r['events']), evals=r.get('evals'),
                   mean_dt=r.get('mean_dt'))
        if r['trapped']:
            row['status'] = 'ok (trapped: >90 % reflections)'
    return row


def run_scene(scene, ctx):
    """Run the sweep of SCENE; returns (rows, curves) and writes bench_data/sweep_<scene>.csv."""
    mode = ctx.mode
    p = scene.params[mode]
    work = os.path.join(ctx.work, scene.key)
    os.makedirs(work, exist_ok=True)
    prep = scene.prepare(ctx.terrace, work, mode)
    if prep is not None:
        print('    %s: start state prepared (%s atoms, %.1f s)' % (scene.key, scene.natoms, prep['wall']), flush=True)
    N = scene.natoms
    box = (scene.hi - scene.lo)
    rows, curves = [], {}

    def analyse(row, th, times, x, v, traj_path, ref):
        row.update(A.energy_metrics(th, N))
        if row['method'] == 'terrace-es' and row.get('max_de') is not None:
            row['de_over_h'] = row['max_de'] * N / row['param']
            if row['de_over_h'] > 1 + 1e-6:       # |K + V - E0| <= h is the method's guarantee
                row['status'] = 'bound violated: max|E - E0| = %.3g h (a missed level crossing)' % row['de_over_h']
        row.update(A.thermo_observables(th, scene.periodic))
        if x is not None and ref is not None:
            row['traj_err'] = A.traj_error(times, x, ref['times'], ref['x'], p['t_short'])
        if x is not None:
            obs = ctx.analyzer.observables(scene, times, x, v, box, traj_path)
            for k in ('gr_curve', 'vdos_curve'):
                if k in obs:
                    curves[(row['method'], row['param'], k)] = obs.pop(k)
            row.update(obs)
        if th:
            curves[(row['method'], row['param'], 'energy')] = (th['time'], (th['etotal'] - th['etotal'][0]) / N)

    def timed_terrace(name, integrator):
        """The timing of a run: the same run without trajectory and with one thermo sample at the end
        (so that output does not dominate short runs), best of ctx.repeat; its loop minus output time."""
        best = None
        for k in range(ctx.repeat):
            tn = name + '_timed'
            r = run_terrace(ctx.terrace, work, tn, scene.terrace_deck(tn, integrator, p['t_long'], p['t_long'], 0),
                            timeout=ctx.timeout)
            if r['rc'] != 0 or r['loop'] is None:
                return None
            w = r['loop'] - (r.get('output') or 0.0)
            best = w if best is None else min(best, w)
        return best

    def timed_lammps(name, dt):
        best = None
        for k in range(ctx.repeat):
            tn = name + '_timed'
            r = run_lammps(work, tn, scene.lammps_input(tn, dt, p['t_long'], p['t_long'], 0), timeout=ctx.timeout)
            if r['error'] or r['loop'] is None:
                return None
            w = r['loop'] - r['output']
            best = w if best is None else min(best, w)
        return best

    def terrace_run(method, param, label, integrator, ref=None):
        name = '%s_%g' % (method, param)
        deck = scene.terrace_deck(name, integrator, p['t_long'], p['thermo'], p['traj'])
        r = run_terrace(ctx.terrace, work, name, deck, timeout=ctx.timeout)
        row = _terrace_row(scene, r, method, param, label, p, N)
        times = x = v = None
        th = read_thermo(os.path.join(work, name + '.csv')) if r['rc'] == 0 else {}
        h5 = os.path.join(work, name + '.h5')
        if r['rc'] == 0 and os.path.exists(h5):
            times, x, v, _ = read_h5md(h5)
        analyse(row, th, times, x, v, h5, ref)
        if row['status'].startswith('ok') and method != 'reference':
            row['wall'] = timed_terrace(name, integrator)
        if not ctx.keep:
            for ext in ('.h5',):
                if os.path.exists(os.path.join(work, name + ext)):
                    os.remove(os.path.join(work, name + ext))
        print('    %-8s %-11s %-22s %-6s wall %7.2f s  max|dE|/N %9.3g  traj err %9.3g  T %s'
              % (scene.key, method, label, 'ok' if row['status'].startswith('ok') else 'FAIL',
                 row.get('wall') or float('nan'), row.get('max_de', float('nan')), row.get('traj_err', float('nan')),
                 '%.4g +- %.2g' % (row['T'], row['T_se']) if 'T' in row else '-'), flush=True)
        if not row['status'].startswith('ok'):
            print('             %s' % row['status'], flush=True)
        return row, times, x

    # reference: Terrace Verlet at dt_ref over t_long
    dt_ref = exact_dt(p['t_long'], p['dt_ref'])
    ref_row, rt, rx = terrace_run('reference', dt_ref, 'dt = %g %s' % (dt_ref, scene.tunit), scene.verlet(dt_ref))
    if not ref_row['status'].startswith('ok') or rx is None:
        raise RuntimeError('%s: the reference run failed: %s' % (scene.key, ref_row['status']))
    ref = dict(times=rt, x=rx)
    rows.append(ref_row)
    dts = [exact_dt(p['t_long'], dt) for dt in p['dts']]     # every run ends exactly at t_long
    for dt in dts:
        rows.append(terrace_run('terrace-vv', dt, 'dt = %g %s' % (dt, scene.tunit), scene.verlet(dt), ref)[0])
    for h in p['hs']:
        rows.append(terrace_run('terrace-es', h, 'h = %s' % scene.h_label(h), scene.stepping(h), ref)[0])
    if ctx.lammps and have_lammps():
        for dt in dts:
            name = 'lmp_%g' % dt
            r = run_lammps(work, name, scene.lammps_input(name, dt, p['t_long'], p['thermo'], p['traj']),
                           timeout=ctx.timeout)
            row = dict(scene=scene.key, method='lammps-vv', param=dt, param_label='dt = %g %s' % (dt, scene.tunit),
                       natoms=N, t_long=p['t_long'])
            times = x = v = None
            th = {}
            if r['error'] or r['loop'] is None:
                row['status'] = 'error: ' + (r['error'] or 'no loop time')
            else:
                row.update(status='ok', loop=r['loop'], output=r['output'], n=r.get('n'), pair=r.get('pair'),
                           comm=r.get('comm'), wall=timed_lammps(name, dt))
                th = r['thermo']
                dump = os.path.join(work, name + '.dump')
                if os.path.exists(dump):
                    times, x, v = read_lammps_dump(dump, dt)
                    x, v = x[:, :, :scene.dim], v[:, :, :scene.dim]
                    if not ctx.keep:
                        os.remove(dump)
            analyse(row, th, times, x, v, None, ref)
            rows.append(row)
            print('    %-8s %-11s %-22s %-6s wall %7.2f s  max|dE|/N %9.3g  traj err %9.3g  T %s'
                  % (scene.key, 'lammps-vv', row['param_label'], 'ok' if row['status'] == 'ok' else 'FAIL',
                     row.get('wall') or float('nan'), row.get('max_de', float('nan')),
                     row.get('traj_err', float('nan')),
                     '%.4g +- %.2g' % (row['T'], row['T_se']) if 'T' in row else '-'), flush=True)
            if row['status'] != 'ok':
                print('             %s' % row['status'], flush=True)
    write_csv(os.path.join(ctx.data, 'sweep_%s.csv' % scene.key), rows)
    write_energy_curves(os.path.join(ctx.data, 'curves_%s.csv' % scene.key), curves)
    return rows, curves


def fmt(v):
    if v is None:
        return ''
    if isinstance(v, float):
        return '' if not np.isfinite(v) and np.isnan(v) else '%.6g' % v
    return str(v)


def write_energy_curves(path, curves):
    """The energy-error curves (E(t) - E0)/N of the runs the energy figure draws (the finest and the
    coarsest parameter of each method), one row per sample: method, param, time, de; --report-only
    draws the figure from them."""
    energy = {k: v for k, v in curves.items() if k[2] == 'energy'}
    keep = set()
    for m in {k[0] for k in energy}:
        params = sorted(k[1] for k in energy if k[0] == m)
        keep.update({(m, params[0], 'energy'), (m, params[-1], 'energy')})
    with open(path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(['method', 'param', 'time', 'de'])
        for (method, param, kind), value in sorted(energy.items(), key=lambda kv: (kv[0][0], kv[0][1])):
            if (method, param, kind) not in keep:
                continue
            for t, de in zip(*value):
                w.writerow([method, repr(float(param)), repr(float(t)), repr(float(de))])


def read_energy_curves(path):
    """The curves write_energy_curves wrote: {(method, param, 'energy'): (time, de)} ({} if none)."""
    if not os.path.exists(path):
        return {}
    runs = {}
    with open(path, newline='') as f:
        for r in csv.DictReader(f):
            runs.setdefault((r['method'], float(r['param']), 'energy'), []).append((float(r['time']), float(r['de'])))
    return {k: (np.array([a for a, _ in v]), np.array([b for _, b in v])) for k, v in runs.items()}


def write_csv(path, rows):
    with open(path, 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(FIELDS)
        for r in rows:
            w.writerow([fmt(r.get(k)) for k in FIELDS])
