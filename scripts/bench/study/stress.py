"""Stability stress tests: how each method fails, and whether the failure is reported.

  escalate-dt  velocity Verlet (Terrace, LAMMPS): dt raised until the run fails;
  escalate-h   energy stepping: h raised until it is refused, trapped or loses its energy bound;
  collision    two argon atoms head-on with the energy to reach 0.8 sigma;
  ranks        the seven-atom cluster on 8 ranks (more ranks than atoms) against 1 rank;
  evaporation  the 147-atom icosahedron heated to 600 K: atoms leave the free cluster.
Every outcome is one of: ok; 'stopped: <kind>' with the code's error line; 'NaN in the output (not
detected)'; 'large energy error (run completes)': max|E - E0| > 10 % of K0 with exit status 0 (below
the engine's blow-up threshold |K0| + |V0|); 'bound violated' (energy stepping outside
|K + V - E0| <= h: a missed level crossing); 'trapped' (more than 90 % of the events were reflections: the run
summary's share; the engine warns above one half).
"""
import csv
import os
import shutil

import numpy as np

from . import scenes as S
from .common import KB_METAL, run_terrace, run_lammps, read_thermo, read_h5md, read_lammps_dump, \
    write_atoms_file, write_lammps_data, read_atoms_file, have_lammps

FIELDS = ['test', 'scene', 'method', 'param', 'outcome', 'detail', 'wall']


def _start(scene, ctx, mode):
    """Work dir of SCENE for the stress tests, with its start state (reused from the sweep if there)."""
    d = os.path.join(ctx.work, 'stress', scene.key)
    os.makedirs(d, exist_ok=True)
    swept = os.path.join(ctx.work, scene.key, 'start.atoms')
    if os.path.exists(swept) and scene.natoms:
        shutil.copy(swept, d)
        shutil.copy(os.path.join(ctx.work, scene.key, 'start.data'), d)
    else:
        scene.prepare(ctx.terrace, d, mode)
    return d


def classify(th, err, natoms, kind, h=None):
    """Outcome of one run from its thermo samples and its error line (or '')."""
    if err:
        e = err.lower()
        if 'energy blow-up' in e:
            return 'stopped: energy blow-up', err
        if 'moved more than one box' in e:
            return 'stopped: atom moved > 1 box', err
        if 'nan' in e or 'non-finite' in e:
            return 'stopped: NaN', err
        if 'lost atoms' in e:
            return 'stopped: lost atoms', err
        if 'terrace_height' in e or 'terrace height' in e:
            return 'refused: h too large', err
        return 'stopped: error', err
    if not th or len(th.get('etotal', [])) < 2:
        return 'no output', ''
    e = th['etotal']
    if not np.all(np.isfinite(e)) or not np.all(np.isfinite(th['temp'])):
        return 'NaN in output (not detected)', ''
    de = np.abs(e - e[0])
    k0 = max(abs(th['ke'][0]), 1e-300)
    if kind == 'es':
        if de.max() > h * (1 + 1e-6) + 1e-12 * abs(e[0]):
            return 'bound violated (missed crossing)', 'max|E-E0| = %.3g h' % (de.max() / h)
        return 'ok', 'max|E-E0| = %.3g h' % (de.max() / h)
    if de.max() > 0.1 * k0:
        return 'large energy error (run completes)', 'max|E-E0| = %.3g K0' % (de.max() / k0)
    return 'ok', 'max|E-E0|/N = %.3g' % (de.max() / natoms)


def _row(rows, test, scene, method, param, outcome, detail, wall):
    rows.append(dict(test=test, scene=scene, method=method, param=param, outcome=outcome, detail=detail,
                     wall=wall))
    print('    %-11s %-9s %-11s %-24s %-34s %s' % (test, scene, method, param, outcome, detail[:110]), flush=True)


def escalate_dt(ctx, rows, key, dts, t_end, thermo):
    scene = S.get(key)
    d = _start(scene, ctx, ctx.mode)
    for code in ('terrace', 'lammps'):
        if code == 'lammps' and not (ctx.lammps and have_lammps()):
            continue
        for dt in dts:
            name = 'esc_%s_%g' % (code, dt)
            if code == 'terrace':
                r = run_terrace(ctx.terrace, d, name, scene.terrace_deck(name, scene.verlet(dt), t_end, thermo, 0),
                                timeout=ctx.timeout)
                th = read_thermo(os.path.join(d, name + '.csv'))
                err = r['error'] if r['rc'] != 0 else ''
            else:
                r = run_lammps(d, name, scene.lammps_input(name, dt, t_end, thermo, 0), timeout=ctx.timeout)
                th, err = r['thermo'], r['error']
            out, det = classify(th, err, scene.natoms, 'vv')
            _row(rows, 'escalate-dt', key, code + '-vv', 'dt = %g %s' % (dt, scene.tunit), out, det, r['wall'])
            if out != 'ok':
                break


def escalate_h(ctx, rows, key, hs, t_end, thermo):
    scene = S.get(key)
    d = _start(scene, ctx, ctx.mode)
    for h in hs:
        name = 'esc_es_%g' % h
        r = run_terrace(ctx.terrace, d, name, scene.terrace_deck(name, scene.stepping(h), t_end, thermo, 0),
                        timeout=ctx.timeout)
        th = read_thermo(os.path.join(d, name + '.csv'))
        out, det = classify(th, r['error'] if r['rc'] != 0 else '', scene.natoms, 'es', h)
        if out == 'ok' and 'events' in r:
            refl = r['refl'] / max(1, r['events'])
            t0, t1 = th['temp'][0], np.mean(th['temp'][1:]) if len(th['temp']) > 1 else float('nan')
            det += '; %d events, %.0f %% reflections, T %.4g -> mean %.4g' % (r['events'], 100 * refl, t0, t1)
            if r['trapped'] or refl > 0.9:
                out = 'trapped (>90 % reflections, warned)'
        _row(rows, 'escalate-h', key, 'terrace-es', 'h = %s' % scene.h_label(h), out, det, r['wall'])
        if out.startswith('refused') or out.startswith('stopped') or out.startswith('bound'):
            break


def collision(ctx, rows):
    """Two argon atoms head-on; the collision energy puts the turning point at 0.8 sigma."""
    d = os.path.join(ctx.work, 'stress', 'collision')
    os.makedirs(d, exist_ok=True)
    eps, sig, m = 0.0103408116, 3.4, 39.948
    mvv2e = 1.0364269e-4
    V = lambda r: 4 * eps * ((sig / r) ** 12 - (sig / r) ** 6)
    x0 = 6.0
    e_rel = V(0.8 * sig) - V(2 * x0)             # kinetic energy of the relative motion at 2 x0
    v0 = np.sqrt(e_rel / (m * mvv2e))            # each atom: 2 * m v0^2 / 2 = e_rel
    types = np.array([1, 1])
    x = np.array([[-x0, 0, 0], [x0, 0, 0]], float)
    v = np.array([[v0, 0, 0], [-v0, 0, 0]], float)
    write_atoms_file(os.path.join(d, 'start.atoms'), types, x, v, 'head-on argon pair, turning point 0.8 sigma')
    lo, hi = np.array([-30.0, -30, -30]), np.array([30.0, 30, 30])
    write_lammps_data(os.path.join(d, 'start.data'), types, x, v, lo, hi, [m], 3)
    scene = S.Scene('collision', 'argon pair', 'metal', 3, False,
                    dict(style='lj', eps=eps, sig=sig, sigma=sig, cutoff=0.0, shift=False), 1.0, m, {}, {}, [])
    scene.natoms = 2
    t_end, frame = 1.0, 0.002          # frames every 2 fs: the sampled closest approach is within 0.001 sigma
    runs = [('terrace-vv', dt) for dt in (0.001, 0.002, 0.005, 0.01, 0.02)] + \
           [('terrace-es', f * eps) for f in (0.01, 0.1, 1.0, 4.0)]
    if ctx.lammps and have_lammps():
        runs += [('lammps-vv', dt) for dt in (0.001, 0.002, 0.005, 0.01, 0.02)]
    for method, p in runs:
        name = 'col_%s_%g' % (method, p)
        if method == 'lammps-vv':
            r = run_lammps(d, name, scene.lammps_input(name, p, t_end, max(frame, p), max(frame, p)),
                           timeout=ctx.timeout)
            err, th = r['error'], r['thermo']
            if not err and os.path.exists(os.path.join(d, name + '.dump')):
                t, X, Vv = read_lammps_dump(os.path.join(d, name + '.dump'), p)
            else:
                t = X = Vv = None
        else:
            integ = scene.verlet(p) if method == 'terrace-vv' else scene.stepping(p)
            fr = max(frame, p) if method == 'terrace-vv' else frame
            r = run_terrace(ctx.terrace, d, name, scene.terrace_deck(name, integ, t_end, fr, fr), timeout=ctx.timeout)
            err = r['error'] if r['rc'] != 0 else ''
            th = read_thermo(os.path.join(d, name + '.csv'))
            t = X = Vv = None
            if not err:
                t, X, Vv, _ = read_h5md(os.path.join(d, name + '.h5'))
        label = ('dt = %g fs' % (p * 1000)) if method != 'terrace-es' else 'h = %.3g eps' % (p / eps)
        if err or X is None:
            out, det = classify(th, err, 2, 'vv')
        else:
            r12 = np.linalg.norm(X[:, 1] - X[:, 0], axis=1)
            vrel = np.linalg.norm(Vv[-1, 1] - Vv[-1, 0])
            v_exact = 2 * np.sqrt((V(0.8 * sig) - V(r12[-1])) / (m * mvv2e))   # energy conservation at the final separation
            de = np.max(np.abs(th['etotal'] - th['etotal'][0])) / eps
            out = 'ok'
            det = ('closest %.3f sigma (exact 0.800), |dE|max %.3g eps, final |v_rel| error %.2g %%'
                   % (r12.min() / sig, de, 100 * abs(vrel - v_exact) / v_exact))
            if not np.isfinite(de) or de > e_rel / eps * 0.1:
                out = 'large energy error (run completes)'
            elif method == 'terrace-es' and de > p / eps * (1 + 1e-6):
                out = 'bound violated (missed crossing)'
        _row(rows, 'collision', 'Ar pair', method, label, out, det, r['wall'])


def ranks(ctx, rows, np_=8):
    scene = S.get('cluster7')
    d = _start(scene, ctx, ctx.mode)
    t_end = 20.0
    for method, integ in (('terrace-vv', scene.verlet(0.005)), ('terrace-es', scene.stepping(16 * KB_METAL))):
        res = {}
        for n in (1, np_):
            name = 'ranks_%s_np%d' % (method, n)
            r = run_terrace(ctx.terrace, d, name, scene.terrace_deck(name, integ, t_end, 0.1, 0), np_=n,
                            timeout=ctx.timeout)
            res[n] = (r, read_thermo(os.path.join(d, name + '.csv')))
        r1, t1 = res[1]
        rn, tn = res[np_]
        if rn['rc'] != 0:
            _row(rows, 'ranks', 'cluster7', method, '%d ranks, 7 atoms' % np_, 'stopped: error', rn['error'], rn['wall'])
            continue
        rel = np.max([np.abs(tn[k] - t1[k]) / (np.abs(t1[k]) + 1e-300) for k in ('pe', 'ke', 'etotal')], axis=0)
        bad = np.nonzero(rel > 1e-8)[0]
        t_first = t1['time'][bad[0]] if len(bad) else None
        early = rel[t1['time'] <= 2.0].max()
        out = 'ok' if t_first is None else 'ok to %g ps, then diverges' % t1['time'][bad[0] - 1]
        det = ('relative difference of pe, ke, etotal from 1 rank: max %.2g over the first 2 ps, max %.2g over %g ps'
               % (early, rel.max(), t_end))
        if t_first is not None:
            det += ' (first sample beyond 1e-8 at t = %g ps: chaotic growth of round-off differences)' % t_first
        _row(rows, 'ranks', 'cluster7', method, '%d ranks, 7 atoms' % np_, out,
             det + '; wall %.2f s vs %.2f s on 1 rank' % (rn['wall'], r1['wall']), rn['wall'])
    if ctx.lammps and have_lammps():
        res = {}
        for n in (1, np_):
            name = 'ranks_lmp_np%d' % n
            res[n] = run_lammps(d, name, scene.lammps_input(name, 0.005, t_end, 0.1, 0), np_=n, timeout=ctx.timeout)
        if res[np_]['error']:
            _row(rows, 'ranks', 'cluster7', 'lammps-vv', '%d ranks, 7 atoms' % np_, 'stopped: error',
                 res[np_]['error'], res[np_]['wall'])
        else:
            a, b = res[1]['thermo'], res[np_]['thermo']
            diff = float(np.max(np.abs(a['etotal'] - b['etotal']) / np.abs(a['etotal'])))
            _row(rows, 'ranks', 'cluster7', 'lammps-vv', '%d ranks, 7 atoms' % np_,
                 'ok' if diff < 1e-8 else 'differs from 1 rank',
                 'max relative difference of etotal from 1 rank: %.2g' % diff, res[np_]['wall'])


def evaporation(ctx, rows, t_end):
    """The icosahedron heated to 600 K: atoms evaporate from the free cluster."""
    scene = S.get('ico147')
    d = os.path.join(ctx.work, 'stress', 'evaporation')
    os.makedirs(d, exist_ok=True)
    shutil.copy(os.path.join(S.REPO, 'input', 'argon_ico147.atoms'), d)
    deck = ("&run units='metal', dimension=3, n_steps=1, seed=600 /\n"
            "&system atoms_file='argon_ico147.atoms', periodic=.false.,.false.,.false., mass=39.951, "
            "temperature=600.0 /\n%s\n&integrator style='velocity_verlet', dt=0.0001 /\n&neighbor skin=1.0 /\n"
            "&output thermo_file='', final_atoms_file='start.atoms' /\n" % scene.terrace_potential())
    run_terrace(ctx.terrace, d, 'hot', deck)
    types, x, v = read_atoms_file(os.path.join(d, 'start.atoms'))
    scene.natoms = len(types)
    lo, hi = x.min(0) - 5, x.max(0) + 5
    write_lammps_data(os.path.join(d, 'start.data'), types, x, v, lo, hi, [scene.mass], 3)
    frame = t_end / 4
    runs = [('terrace-vv', 0.005), ('terrace-es', 2e-3)]
    if ctx.lammps and have_lammps():
        runs.append(('lammps-vv', 0.005))
    sig = scene.pot['sigma']
    for method, p in runs:
        name = 'evap_%s' % method
        if method == 'lammps-vv':
            r = run_lammps(d, name, scene.lammps_input(name, p, t_end, 0.1, frame), timeout=ctx.timeout)
            err, th = r['error'], r['thermo']
            X = read_lammps_dump(os.path.join(d, name + '.dump'), p)[1] if not err else None
        else:
            integ = scene.verlet(p) if method == 'terrace-vv' else scene.stepping(p)
            r = run_terrace(ctx.terrace, d, name, scene.terrace_deck(name, integ, t_end, 0.1, frame), timeout=ctx.timeout)
            err = r['error'] if r['rc'] != 0 else ''
            th = read_thermo(os.path.join(d, name + '.csv'))
            X = read_h5md(os.path.join(d, name + '.h5'))[1] if not err else None
        out, det = classify(th, err, scene.natoms, 'es' if method == 'terrace-es' else 'vv', p)
        if X is not None:
            xf = X[-1]
            dd = np.linalg.norm(xf[:, None, :] - xf[None, :, :], axis=2)
            np.fill_diagonal(dd, np.inf)
            free = int(np.sum(dd.min(1) > 2.5 * sig))
            det += '; %d of %d atoms left at the end (%d farther than 2.5 sigma from any other), max distance ' \
                   'from the centre %.0f A' % (len(xf), scene.natoms, free, np.max(np.linalg.norm(xf - xf.mean(0), axis=1)))
        label = 'dt = 5 fs' if method != 'terrace-es' else 'h = 2e-3 eV'
        _row(rows, 'evaporation', 'ico147', method, label + ', 600 K, %g ps' % t_end, out, det, r['wall'])


def run_all(ctx):
    rows = []
    quick = ctx.mode == 'quick'
    escalate_dt(ctx, rows, 'cluster7', [0.01, 0.02, 0.04, 0.08, 0.16], 200.0 if quick else 10000.0, 2.0)
    escalate_dt(ctx, rows, 'rahman', [0.01, 0.02, 0.03, 0.04, 0.06, 0.08, 0.16], 1.0 if quick else 20.0, 0.02)
    escalate_dt(ctx, rows, 'cu_eam', [0.002, 0.005, 0.01, 0.02, 0.04], 0.5 if quick else 10.0, 0.01)
    escalate_h(ctx, rows, 'cluster7', [x * KB_METAL for x in (16, 64, 256, 1024, 4096)],
               200.0 if quick else 10000.0, 2.0)
    escalate_h(ctx, rows, 'rahman', [2e-3, 8e-3, 0.032, 0.128, 0.512, 2.048, 64.0], 0.5 if quick else 10.0, 0.02)
    escalate_h(ctx, rows, 'cu_eam', [3e-3, 6e-3, 0.012, 0.024], 0.2, 0.01)
    collision(ctx, rows)
    ranks(ctx, rows)
    evaporation(ctx, rows, 20.0 if quick else 500.0)
    with open(os.path.join(ctx.data, 'stress.csv'), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(FIELDS)
        for r in rows:
            w.writerow([('%.3g' % r[k]) if isinstance(r[k], float) else r[k] for k in FIELDS])
    return rows
