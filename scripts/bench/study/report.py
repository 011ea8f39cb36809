"""Figures (doc/figures/bench_*.png) and doc/benchmarks.md from the study's results. Every number
in the page is computed here from the rows that the sweeps and stress tests wrote to
doc/bench_data/*.csv; the conclusions are derived from the same rows (equal-error comparisons by
log-log interpolation of the Verlet curve), not written by hand."""
import textwrap
import math
import os

nan = float('nan')

import numpy as np

import matplotlib
from terrace_tools.plotting import plt, save  # noqa: E402
import matplotlib.ticker  # noqa: E402

from terrace_tools import plotting  # noqa: E402

from . import scenes as S  # noqa: E402
from . import sweep  # noqa: E402

STYLE, METHODS = plotting.STYLE, plotting.METHODS


def f(v, spec='%.3g'):
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return '–'
    return spec % v


def ok(r):
    return str(r.get('status', '')).startswith('ok')


def trapped(r):
    return 'trapped' in str(r.get('status', ''))


def series(rows, method, key, with_trapped=False):
    pts = [(r[key], r['wall'], r) for r in rows if r['method'] == method and ok(r)
           and (with_trapped or not trapped(r))
           and r.get(key) is not None and r.get('wall') and math.isfinite(r[key]) and r[key] > 0]
    return pts


# ----------------------------------------------------------------------------------- figures
def fig_workprecision(scene, rows, path):
    panels = [('max_de', '(a) max |E(t) − E0| / N  [%s/atom]' % scene.eunit),
              ('drift_abs', '(b1) |energy drift|  [%s/atom/%s]' % (scene.eunit, scene.tunit)),
              ('max_dp', '(b2) max |P(t) − P(0)|  [mass·velocity]'),
              ('traj_err', '(c) RMS position error at t = %g %s  [%s]'
               % (scene.params_used['t_short'], scene.tunit, scene.lunit))]
    for r in rows:
        if r.get('drift') is not None and math.isfinite(r['drift']):
            r['drift_abs'] = abs(r['drift'])
    fig, axs = plt.subplots(2, 2, figsize=(11, 8))
    for ax, (key, label) in zip(axs.ravel(), panels):
        for m in METHODS + ['reference']:
            pts = series(rows, m, key, with_trapped=True)
            if not pts:
                continue
            pts.sort(key=lambda p: p[2]['param'])
            st = STYLE[m]
            ax.loglog([p[0] for p in pts], [p[1] for p in pts], '-' if m != 'reference' else '',
                      color=st['color'], marker=st['marker'], label=st['label'], ms=7)
            tr = [p for p in pts if trapped(p[2])]
            if tr:
                ax.loglog([p[0] for p in tr], [p[1] for p in tr], ls='', marker=st['marker'], ms=11, mfc='white',
                          mec=st['color'], label='energy stepping, trapped (>90 % reflections)'
                          if key == 'max_de' else None)
            for e, w, r in pts:
                if m == 'reference':
                    continue
                lab = ('%g' % (r['param'] * 1000) if scene.units == 'metal' else '%g' % r['param']) \
                    if m != 'terrace-es' else ('%.3g' % (r['param'] / S.KB_METAL) if scene.units == 'metal'
                                              else '%g' % r['param'])
                ax.annotate(lab, (e, w), textcoords='offset points', xytext=(4, 3), fontsize=7, color=st['color'])
        ax.set_xlabel(label)
        ax.set_ylabel('wall time [s] (timing run, no output)')
        ax.grid(True, which='both', alpha=0.3)
        log_tick_labels(ax)
    # one legend for the figure, from every panel (a method may be missing from one), in two rows
    seen = {}
    for ax in axs.ravel():
        for h, lab in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(lab, h)
    fig.legend(list(seen.values()), list(seen.keys()), loc='lower center', ncol=3, fontsize=8)
    lab = 'labels: dt in fs, h in K k_B' if scene.units == 'metal' else 'labels: dt in tau, h in eps'
    atoms = '' if ('%d atoms' % scene.natoms) in scene.title else '%d atoms, ' % scene.natoms
    fig.suptitle('%s: %s%g %s per run (%s)' % (scene.title, atoms, scene.params_used['t_long'],
                                               scene.tunit, lab), fontsize=10)
    fig.tight_layout(rect=(0, 0.07, 1, 0.97))
    save(fig, path, dpi=110, tight=False)


log_tick_labels = plotting.log_tick_labels


OBS = [('T', 'T_se', 'temperature [%s]', None), ('P', 'P_se', 'pressure [%s]', None),
       ('gr_peak', 'gr_peak_se', 'g(r) first-peak height', None), ('D', 'D_se', 'diffusion coefficient [%s²/%s]', None),
       ('vdos', 'vdos_se', 'VDOS peak frequency [1/%s]', None)]


def obs_label(scene, key, text):
    if key == 'T':
        return text % ('K' if scene.units == 'metal' else 'eps/k_B')
    if key == 'P':
        return text % ('bar' if scene.units == 'metal' else 'eps/sigma³')
    if key == 'D':
        return text % (scene.lunit, scene.tunit)
    if key == 'vdos':
        return text % scene.tunit
    return text


def _se(r, kse):
    """A row's standard error, 0 where it has none (NaN: the VDOS peak from terrace-analyze)."""
    v = r.get(kse)
    return v if v is not None and math.isfinite(v) else 0.0


def fig_observables(scene, rows, path):
    keys = [o for o in OBS if any(r.get(o[0]) is not None and ok(r) for r in rows)]
    if not keys:
        return False
    fig, axs = plt.subplots(1, len(keys), figsize=(4.2 * len(keys), 3.8), squeeze=False)
    ref = [r for r in rows if r['method'] == 'reference' and ok(r)]
    for ax, (k, kse, text, _) in zip(axs[0], keys):
        if ref and ref[0].get(k) is not None:
            m0, s0 = ref[0][k], _se(ref[0], kse)
            ax.axhspan(m0 - 2 * s0, m0 + 2 * s0, color='0.85', label='reference ± 2 SE')
            ax.axhline(m0, color='0.4', lw=1)
        for m in METHODS:
            pts = [r for r in rows if r['method'] == m and ok(r) and r.get(k) is not None and r.get('wall')]
            if not pts:
                continue
            st = STYLE[m]
            for sel, mfc, lab in (([r for r in pts if not trapped(r)], st['color'], st['label']),
                                  ([r for r in pts if trapped(r)], 'white', 'energy stepping, trapped')):
                if sel:
                    ax.errorbar([r['wall'] for r in sel], [r[k] for r in sel],
                                yerr=[2 * _se(r, kse) for r in sel], fmt=st['marker'], color=st['color'],
                                mfc=mfc, label=lab, capsize=3)
        ax.set_xscale('log')
        ax.set_xlabel('wall time [s]')
        ax.set_ylabel(obs_label(scene, k, text))
        ax.grid(True, alpha=0.3)
    # one legend below the panels, from every panel's entries: inside a panel it hid data points
    seen = {}
    for ax in axs[0]:
        for h, lab in zip(*ax.get_legend_handles_labels()):
            seen.setdefault(lab, h)
    ncol = min(len(seen), 2 * len(keys))                   # a narrow figure gets several rows
    nrow = -(-len(seen) // ncol)
    fig.legend(list(seen.values()), list(seen.keys()), loc='lower center', ncol=ncol, fontsize=8)
    title = '%s: long-run observables over %g %s (error bars ± 2 SE)' % (scene.title, scene.params_used['t_long'],
                                                                        scene.tunit)
    fig.suptitle(textwrap.fill(title, 60 * len(keys)), fontsize=10)
    fig.tight_layout(rect=(0, 0.06 * nrow + 0.02, 1, 1))
    save(fig, path, dpi=110, tight=False)
    return True


def fig_curves(scene, curves, path):
    """Energy error against time for the finest and the coarsest run of each method."""
    fig, ax = plt.subplots(figsize=(8, 4))
    for m in METHODS:
        ks = sorted([k for k in curves if k[0] == m and k[2] == 'energy'], key=lambda k: k[1])
        for k in (ks[:1] + ks[-1:]) if len(ks) > 1 else ks:
            t, de = curves[k]
            lab = '%s %s' % (m, ('dt %g' % k[1]) if m != 'terrace-es' else ('h %.3g' % k[1]))
            ax.plot(t, de, color=STYLE[m]['color'], lw=0.8, alpha=0.9 if k == ks[0] else 0.5, label=lab)
    ax.set_xlabel('time [%s]' % scene.tunit)
    ax.set_ylabel('(E − E0)/N [%s/atom]' % scene.eunit)
    ax.set_yscale('symlog', linthresh=1e-8)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, ncol=3, loc='upper center', bbox_to_anchor=(0.5, -0.16))
    ax.set_title(textwrap.fill('%s: energy error, finest and coarsest parameter of each method' % scene.title, 90),
                 fontsize=9)
    save(fig, path, dpi=110)


# ----------------------------------------------------------------------------------- analysis
def interp_wall(vv, e):
    """Wall time of Verlet at error e by log-log interpolation of its (error, wall) points.
    Returns (wall, how): how is 'interp', 'below' (e smaller than every Verlet error: the value is
    the wall of the most accurate Verlet run, a lower bound) or 'above' (e larger than every
    Verlet error: the wall of the cheapest Verlet run, an upper bound)."""
    pts = sorted((p[0], p[1]) for p in vv)
    if len(pts) < 1:
        return None, None
    es = np.array([p[0] for p in pts])
    ws = np.array([p[1] for p in pts])
    if e < es[0]:
        return float(ws[0]), 'below'
    if e > es[-1]:
        return float(np.min(ws)), 'above'
    w = float(np.exp(np.interp(np.log(e), np.log(es), np.log(ws))))
    return w, 'interp'


def equal_error(rows, key):
    """Per energy-stepping run: its error, wall, the Verlet wall at equal error, and the factor
    (Verlet wall / ES wall: > 1 means energy stepping is ahead)."""
    vv = series(rows, 'terrace-vv', key)
    out = []
    for e, w, r in series(rows, 'terrace-es', key):
        wv, how = interp_wall(vv, e)
        if wv is None:
            continue
        out.append(dict(h=r['param'], err=e, wall=w, vv_wall=wv, how=how, factor=wv / w, refl=r.get('refl_frac')))
    return out


def rng(xs):
    lo, hi = min(xs), max(xs)
    return ('%.2g' % lo) if '%.2g' % lo == '%.2g' % hi else '%.2g–%.2g' % (lo, hi)


def verdict(eq):
    """One sentence from the equal-error comparison of one metric."""
    if not eq:
        return 'no comparison (no energy-stepping run that finished untrapped)'
    ahead = [q for q in eq if q['how'] == 'interp' and q['factor'] > 1]
    behind = [q for q in eq if q['how'] == 'interp' and q['factor'] <= 1]
    above = [q for q in eq if q['how'] == 'above']
    below = [q for q in eq if q['how'] == 'below']
    s = []
    if ahead:
        s.append('**energy stepping ahead** at equal error for %d of %d h (Verlet %s× slower)'
                 % (len(ahead), len(eq), rng([q['factor'] for q in ahead])))
    if behind:
        s.append('**Verlet ahead** at equal error for %d of %d h (energy stepping %s× slower)'
                 % (len(behind), len(eq), rng([1 / q['factor'] for q in behind])))
    if above:
        dom = [q for q in above if q['factor'] <= 1]
        txt = '%d of %d h less accurate than every Verlet run' % (len(above), len(eq))
        if dom:
            txt += ('; for %d of them the cheapest Verlet run is also faster (**Verlet ahead** by at least %s×)'
                    % (len(dom), rng([1 / q['factor'] for q in dom])))
        s.append(txt)
    if below:
        s.append('%d of %d h more accurate than every Verlet run swept (energy stepping %s× the wall time of '
                 'the most accurate Verlet run)' % (len(below), len(eq), rng([1 / q['factor'] for q in below])))
    return '; '.join(s)


def observables_verdict(rows):
    """Which long-run observables of which runs lie outside 2 combined standard errors of the reference."""
    ref = [r for r in rows if r['method'] == 'reference' and ok(r)]
    if not ref:
        return 'no reference'
    ref = ref[0]
    names = {'T': 'T', 'P': 'P', 'gr_peak': 'g(r) peak', 'D': 'D', 'vdos': 'VDOS peak'}
    checked, off = set(), []
    n = 0
    for r in rows:
        if r['method'] not in METHODS or not ok(r):
            continue
        n += 1
        for k, lab in names.items():
            if r.get(k) is None or ref.get(k) is None:
                continue
            se = math.hypot(*[nan if x is None else x for x in (r.get(k + '_se'), ref.get(k + '_se'))])
            if not math.isfinite(se):
                continue
            checked.add(lab)
            if abs(r[k] - ref[k]) > 2 * se:
                off.append('%s %s %s' % (r['method'], r['param_label'].split('(')[0].strip(), lab))
    if not checked:
        return 'observables: none'
    txt = 'observables (%s): %d runs compared with the reference' % (', '.join(sorted(checked)), n)
    if off:
        return txt + '; outside 2 combined SE (about 1 in 20 expected by chance): ' + ', '.join(off)
    return txt + ', all within 2 combined SE'


def table(header, rows):
    esc = lambda x: str(x).replace('|', '\\|')
    out = ['| ' + ' | '.join(esc(h) for h in header) + ' |', '|' + '---|' * len(header)]
    for r in rows:
        out.append('| ' + ' | '.join(esc(x) for x in r) + ' |')
    return '\n'.join(out)


# ----------------------------------------------------------------------------------- reload
def _num(v):
    if v == '':
        return None
    try:
        x = float(v)
    except ValueError:
        return v
    return x


def load(ctx, keys):
    """The results of the last run, read back from DOC/bench_data (for --report-only)."""
    import csv
    import json
    res = {'sweeps': {}, 'curves': {}, 'stress': None}
    tj = os.path.join(ctx.data, 'timing_%s.json' % ctx.mode)
    if os.path.exists(tj):
        j = json.load(open(tj))
        res['env'], res['timing'] = j['env'], [tuple(p) for p in j['parts']]
    else:
        res['env'], res['timing'] = ctx.env, []
    for k in keys:
        p = os.path.join(ctx.data, 'sweep_%s.csv' % k)
        if not os.path.exists(p):
            continue
        rows = []
        for r in csv.DictReader(open(p)):
            rows.append({kk: (_num(v) if kk not in ('scene', 'method', 'param_label', 'status', 'gr_method') else v)
                         for kk, v in r.items()})
        res['sweeps'][k] = rows
        res['curves'][k] = sweep.read_energy_curves(os.path.join(ctx.data, 'curves_%s.csv' % k))
        sc = S.get(k)
        sc.natoms = int(rows[0]['natoms']) if rows and rows[0].get('natoms') else 0
    p = os.path.join(ctx.data, 'stress.csv')
    if os.path.exists(p):
        res['stress'] = [dict(r, wall=_num(r['wall'])) for r in csv.DictReader(open(p))]
    return res


# ----------------------------------------------------------------------------------- page
def write(ctx, results):
    env = results['env']
    L = []
    w = L.append
    mode = env['mode']
    w('# Benchmarks: run time against error (velocity Verlet, energy stepping, LAMMPS)\n')
    w('Generated by `scripts/bench/study.py`; do not edit by hand — rerun the command below. '
      'The tables behind every figure are in [bench_data/](bench_data/).\n')
    w('## How this page was made\n')
    w('    %s\n' % env['command'])
    w('| | |\n|---|---|')
    w('| mode | %s (%s) |' % (mode, 'minutes: short runs, reduced LJ scene' if mode == 'quick'
                                else 'hours: 100 ns cluster, 32,000-atom LJ scene'))
    w('| machine | %s, %s CPUs visible (`nproc`), %s; load average at start %s |'
      % (env['cpu'], env['nproc'], env['os'], env['load']))
    w('| compiler | %s, CMAKE_BUILD_TYPE=%s |' % (env['compiler'], env['build_type']))
    w('| flags | `%s` |' % env['flags_used'])
    w('| LAMMPS | %s (Debian package), `lmp`, one rank |' % env['lammps'])
    w('| MPI | %s |' % env['mpi'])
    w('| date | %s |' % env['date'])
    w('| commit | %s%s |' % (env['commit'], ' (+ uncommitted changes)' if env['dirty'] else ''))
    analyze = str(env['analyze'])
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))))
    if os.path.isabs(analyze) and analyze.startswith(repo + os.sep):
        analyze = os.path.relpath(analyze, repo)  # the page names the program, not this checkout's path
    w('| g(r), MSD, VDOS | %s |' % analyze)
    tot = sum(t for _, t in results.get('timing', []))
    w('\nWall time of each part of this run (total %.0f s):\n' % tot)
    w(table(['part', 'wall time (s)'], [(n, '%.1f' % t) for n, t in results.get('timing', [])]))
    w('\n**Timing.** The wall time of a sweep point comes from a separate run of the same deck with no '
      'trajectory and one thermo sample at the end (best of %d): its loop time minus its output time '
      '(Terrace\'s and LAMMPS\'s own timers); the errors and observables come from the run with output. '
      'On a shared machine the times carry the noise of the other jobs (±20 %% and worse for runs under '
      '0.1 s); rerun on a quiet machine (with `--repeat 3`) before quoting a factor.\n' % env.get('repeat', 1))

    # conclusions
    w('## Conclusions\n')
    w('Derived from the figures below: for each energy-stepping run, the wall time Terrace\'s '
      'velocity Verlet needs for the *same* error (log-log interpolation between the Verlet runs of '
      'the sweep), per error measure. A factor > 1 means energy stepping is ahead.\n')
    concl = []
    for key in results['sweeps']:
        rows = results['sweeps'][key]
        if not rows:
            continue
        sc = S.get(key)
        es_rows = [r for r in rows if r['method'] == 'terrace-es']
        if es_rows and not any(ok(r) for r in es_rows):
            concl.append('- **%s:** energy stepping is not available in this build (%s). Verlet only.'
                         % (sc.title, es_rows[0]['status'].replace('error: ', '')))
            continue
        a = verdict(equal_error(rows, 'max_de'))
        c = verdict(equal_error(rows, 'traj_err'))
        tr = [r for r in es_rows if trapped(r)]
        note = ''
        if tr:
            note = (' Trapped (>90 %% reflections, kinetic energy frozen; excluded from the comparison): h = %s.'
                    % ', '.join(sc.h_label(r['param']) for r in tr))
        concl.append('- **%s** — (a) energy error: %s. (c) trajectory error: %s. (d) %s.%s'
                     % (sc.title, a, c, observables_verdict(rows), note))
    for key in results['sweeps']:
        rows = results['sweeps'][key]
        tv = {r['param']: r['wall'] for r in rows if r['method'] == 'terrace-vv' and ok(r) and r.get('wall')}
        lv = {r['param']: r['wall'] for r in rows if r['method'] == 'lammps-vv' and ok(r) and r.get('wall')}
        common = sorted(set(tv) & set(lv))
        if common:
            ratios = [lv[d] / tv[d] for d in common]
            concl.append('- **Terrace vs LAMMPS Verlet (%s):** same dt, same errors to the plotted precision; '
                         'LAMMPS wall / Terrace wall = %s (for dt = %s).'
                         % (key, ', '.join('%.2g' % x for x in ratios), ', '.join('%g' % d for d in common)))
    L.extend(concl)
    w('')
    w('Context: [energy_stepping.md](energy_stepping.md) measured one event at 2.5–5.7 Verlet steps and '
      '1–2.5 ray evaluations, and found energy stepping about as fast as Verlet at 10 fs per simulated ns '
      'on the seven-atom cluster at h = 14 K k_B (1.5–2× faster at h = 22–37 K), with an energy error 80–200 '
      'times larger than Verlet\'s. The comparison above is made at *equal* error instead. The event '
      'interval shrinks like 1/√N at fixed h, so the larger the system, the further energy stepping falls '
      'behind; and h cannot be raised to compensate: the LJ scene (4,000 atoms) and Rahman argon trapped '
      'at h of about 0.4 k_B T and above (the trapped rows above; why N does not help: '
      '[energy_stepping.md](energy_stepping.md#transversality-when-to-worry)). The equal-error tables per '
      'scene below give the numbers behind each line. Runs under '
      '~0.1 s (the coarsest dt) are dominated by timing noise, and so are the LAMMPS/Terrace ratios there.\n')

    # method
    w('## What is measured\n')
    w('Every run of a scene starts from the same state (positions and velocities, `start.atoms` for '
      'Terrace, the same numbers in a LAMMPS data file) with the same potential, and runs the same '
      'simulated time t_long. Periodic LJ scenes use the energy-shifted LJ for every method (energy '
      'stepping needs a continuous potential; LAMMPS `pair_modify shift yes`); LAMMPS runs with '
      '`neigh_modify every 1 delay 0 check yes` and the same skin.\n')
    w('- **(a)** max over thermo samples of |E(t) − E0| / N (E = K + V, the true energy also for energy stepping).')
    w('- **(b1)** energy drift: least-squares slope of (E − E0)/N against time; **(b2)** momentum: max |P(t) − P(0)|.')
    w('- **(c)** trajectory error: RMS over atoms of |x(t_s) − x_ref(t_s)| at a short horizon t_s, '
      'unwrapped positions in id order (Terrace H5MD frames, LAMMPS `dump ... xu yu zu` sorted by id), '
      'against the reference: Terrace Verlet with dt_ref (4 to 8 times finer than the finest swept dt, '
      'so 16 to 64 times more accurate).')
    w('- **(d)** long-run observables: temperature and pressure (block averages of the thermo samples, '
      '10 blocks, ± 2 standard errors). From `terrace-analyze` ([analysis.md](analysis.md)), on the '
      'run\'s H5MD file (LAMMPS dumps are first written to H5MD): g(r) first-peak height (`--compute=rdf` '
      'on 4 contiguous blocks of frames; mean and standard error over the blocks); diffusion coefficient '
      '(`--compute=msd --msd_blocks=4`, 3 for runs under 28 frames: MSD over all time origins, longest lag '
      'half a block, linear fit over its second half and at least 3 lags; the tool\'s block standard error); VDOS peak (`--compute=vdos`, Hann window, '
      'correlation time half the run: frequency of the maximum above zero; no error bar, so it is not '
      'part of the 2-SE check). The reference is the same Terrace Verlet run with dt_ref.')
    w('- The wall time is that of the same run without trajectory output (see Timing above).\n')
    rowsS = []
    for key in results['sweeps']:
        sc = S.get(key)
        p = sc.params[mode]
        rowsS.append((key, sc.title, sc.natoms, '%g %s' % (p['t_long'], sc.tunit), '%g' % p['t_short'],
                      ', '.join('%g' % d for d in p['dts']),
                      ', '.join(('%.3g' % (h / S.KB_METAL)) if sc.units == 'metal' else '%g' % h for h in p['hs']),
                      '%g' % p['dt_ref']))
    w(table(['scene', 'description', 'atoms', 't_long', 't_s', 'dt (Verlet, both codes)',
             'h (%s)' % 'K k_B, or eps for lj', 'dt_ref'], rowsS))
    w('\nTimes in ps (metal scenes) or tau (lj scene).\n')

    # per scene
    for key in results['sweeps']:
        rows = results['sweeps'][key]
        sc = S.get(key)
        sc.params_used = sc.params[mode]
        w('## %s\n' % sc.title)
        if not rows:
            w('The sweep of this scene failed; see the study output.\n')
            continue
        wp = 'bench_%s_wp.png' % key
        fig_workprecision(sc, rows, os.path.join(ctx.figs, wp))
        w('![work-precision %s](figures/%s)\n' % (key, wp))
        ob = 'bench_%s_obs.png' % key
        if fig_observables(sc, rows, os.path.join(ctx.figs, ob)):
            w('![observables %s](figures/%s)\n' % (key, ob))
        en = 'bench_%s_energy.png' % key
        if results['curves'].get(key):
            fig_curves(sc, results['curves'][key], os.path.join(ctx.figs, en))
            w('![energy error %s](figures/%s)\n' % (key, en))
        hdr = ['method', 'parameter', 'status', 'wall (s)', 'max|dE|/N', 'drift', 'max|dP|', 'traj err',
               'T ± SE', 'P ± SE', 'g(r) peak ± SE', 'D ± SE', 'VDOS peak ± SE', 'reflections', 'evals/event']
        tr = []
        for r in rows:
            tr.append((r['method'], r['param_label'], r['status'][:90], f(r.get('wall')), f(r.get('max_de')),
                       f(r.get('drift')), f(r.get('max_dp')), f(r.get('traj_err')),
                       ('%s ± %s' % (f(r.get('T'), '%.4g'), f(r.get('T_se'), '%.2g'))) if r.get('T') is not None else '–',
                       ('%s ± %s' % (f(r.get('P'), '%.4g'), f(r.get('P_se'), '%.2g'))) if r.get('P') is not None else '–',
                       ('%s ± %s' % (f(r.get('gr_peak'), '%.4g'), f(r.get('gr_peak_se'), '%.2g')))
                       if r.get('gr_peak') is not None else '–',
                       ('%s ± %s' % (f(r.get('D'), '%.3g'), f(r.get('D_se'), '%.2g'))) if r.get('D') is not None else '–',
                       ('%s ± %s' % (f(r.get('vdos'), '%.3g'), f(r.get('vdos_se'), '%.2g')))
                       if r.get('vdos') is not None else '–',
                       ('%.0f %%' % (100 * r['refl_frac'])) if r.get('refl_frac') is not None else '–',
                       f(r.get('evals'), '%.2f')))
        w(table(hdr, tr))
        w('\nUnits: energies %s/atom, drift %s/atom/%s, positions %s, time %s. Data: [bench_data/sweep_%s.csv](bench_data/sweep_%s.csv).\n'
          % (sc.eunit, sc.eunit, sc.tunit, sc.lunit, sc.tunit, key, key))
        for metric, name in (('max_de', '(a) max energy error'), ('traj_err', '(c) trajectory error')):
            eq = equal_error(rows, metric)
            if not eq:
                continue
            w('Equal-error comparison, %s:\n' % name)
            w(table(['h', 'ES reflections', 'ES error', 'ES wall (s)', 'Verlet wall at that error (s)',
                     'Verlet wall / ES wall'],
                    [(sc.h_label(q['h']), '%.0f %%' % (100 * q['refl']) if q.get('refl') is not None else '–',
                      '%.3g' % q['err'], '%.3g' % q['wall'],
                      ('%.3g' % q['vv_wall']) + {'interp': '', 'below': ' (ES below every Verlet error: ≥)',
                                                  'above': ' (ES above every Verlet error: ≤)'}[q['how']],
                      '%.2g' % q['factor']) for q in eq]))
            w('')

    # stress
    w('## Stability stress tests\n')
    st = results.get('stress')
    if st:
        w('Each method is pushed until it fails; the outcome says how it failed and whether the engine '
          'reported it. "stopped" = the run ended with the one-line error shown; "large energy error (run '
          'completes)" = max|E − E0| above 10 % of the initial kinetic energy K0 with exit status 0 (for '
          'Terrace below its blow-up threshold |K0| + |V0|; LAMMPS has no such check); "(not detected)" = '
          'NaN in the output with exit status 0. Energy stepping outcomes: "bound violated" = '
          '|K + V − E0| > h at a sample (a missed level crossing), "trapped" = more than 90 % of '
          'the events were reflections (the run summary\'s share; the engine warns above one half). Data: [bench_data/stress.csv](bench_data/stress.csv).\n')
        w(table(['test', 'scene', 'method', 'parameter', 'outcome', 'detail', 'wall (s)'],
                [(r['test'], r['scene'], r['method'], r['param'], r['outcome'], r['detail'],
                  f(r['wall'], '%.2f')) for r in st]))
        w('')
    else:
        w('Not run (--skip-stress).\n')
    c7 = results['sweeps'].get('cluster7') or []
    if c7:
        sc = S.get('cluster7')
        w('**Long runs for drift** (the seven-atom cluster over %g ns, %s mode; energy stepping must stay '
          'within |E − E0| ≤ h however long it runs, Verlet\'s error must not grow):\n'
          % (sc.params[mode]['t_long'] / 1000.0, mode))
        w(table(['method', 'parameter', 'energy drift (eV/atom/ns)', 'max|E−E0|/N (eV)', 'max|E−E0| / h', 'max|ΔP|'],
                [(r['method'], r['param_label'], f(1000 * r['drift']) if r.get('drift') is not None else '–',
                  f(r.get('max_de')), f(r.get('de_over_h'), '%.2f'), f(r.get('max_dp')))
                 for r in c7 if ok(r)]))
        w('')
    w('What the engine detects (each with a regression test, `ctest -R "fail_|bad_inputs|es_"`):\n')
    w('- **Energy blow-up** (new, `src/engine/run_checks.f90`): at every thermo sample, a '
      'non-finite energy, or |E − E0| > |K0| + |V0|, stops every rank with `terrace: error: energy '
      'blow-up: ...` or `... became NaN or infinite ...` (exit 1). Tests `fail_energy_blowup`, '
      '`fail_energy_blowup_np4`. Before this check such a run finished with exit status 0 and garbage '
      'energies (LAMMPS, which has no such check, still does: "large energy error (run completes)" above).')
    w('- **Atom flung across the periodic box** (new, `domain_migrate` in `src/parallel/domain.f90`): '
      'at every neighbour-list build, a non-finite coordinate or an atom more than one box length '
      'outside a periodic box stops the run naming the atom (before, the wrap silently clamped it '
      'into the box). Tests `fail_moved_box`, `fail_moved_box_np4`.')
    w('- **Energy stepping:** h larger than |V0| + K0 is refused at input; more than half of the events '
      'reflections warns (with the share; above 90 % the state is trapped); a runaway event search stops with a message; |K + V − E0| ≤ h is checked '
      'by the tests `es_conservation_frozen7` and by this study at every sample.')
    w('- **More ranks than atoms** is supported (replicated all-pairs path for small free scenes); '
      'results agree with one rank (`ranks_frozen7` on 8 ranks, and the table above).')
    w('- **Evaporation from a free cluster:** free dimensions have no box to leave; the cell grid '
      'follows the atoms, so evaporated atoms are kept and the energy stays conserved (table above).\n')

    # scaling: not part of the study
    w('## Parallel scaling\n')
    w('Not part of this study: `scripts/bench/scaling.sh` measures strong and weak scaling of both '
      'integrators next to LAMMPS (LJ and EAM); the figures are in doc/performance.md, "Parallel runs".\n')

    # pending / full mode
    w('## Full mode and what is pending\n')
    w('- `--full` runs the cluster for 100 ns (h from 1 to 64 K k_B), the icosahedron for 1 ns, '
      'Rahman argon for 100 ps, the 32,000-atom LJ scene for 2 tau and Cu (500 atoms, Verlet and '
      'energy stepping at h = 1.5e-3, 3e-3, 6e-3 eV) for 20 ps, with longer stress runs: several hours '
      'on one core.')
    w('- **Cu EAM with energy stepping** runs on 108 atoms in quick mode (3 x 3 x 3 cells): its cost '
      'per simulated ps grows like N^1.5 (events ~ √N, work per event ~ N), so 500 atoms would not fit '
      'the quick budget. The sweep keeps h at or below 6e-3 eV (about k_B T / 4 at 300 K), where the EAM '
      'measurements of [energy_stepping.md](energy_stepping.md#eam-metals) found no trap. Larger h is '
      'not safe in general: 0.012 eV trapped from another equilibrated 108-atom state (same page), '
      'although from this run\'s start state the 0.2 ps escalate-h runs up to 0.024 eV did not trap '
      '(stress table); trapping depends on h / k_B T and on the state, and a large N does not protect against it '
      '([energy_stepping.md](energy_stepping.md#transversality-when-to-worry), "Why N does not help").')
    w('- **g(r), D and the VDOS peak** come from `terrace-analyze` (%s; the adapter is `Analyzer` in '
      'scripts/bench/study/analysis.py; the numpy code there is used only when the build has no '
      'terrace-analyze; the method of each row is in the `gr_method` column of the CSVs).'
      % ('used in this run' if any(r.get('gr_method') == 'terrace-analyze'
                                   for rows in results['sweeps'].values() for r in rows)
         else 'NOT used in this run: numpy fallback'))
    w('- In quick mode the long runs are short (2 ps of liquid, 0.25 tau of LJ): D and the VDOS peak '
      'carry large error bars and the VDOS resolution is about 2/t_long (correlation time t_long/2).\n')
    with open(os.path.join(ctx.doc, 'benchmarks.md'), 'w') as fh:
        fh.write('\n'.join(L) + '\n')
    print('    wrote %s and %d figures' % (os.path.join(ctx.doc, 'benchmarks.md'),
                                          len([x for x in os.listdir(ctx.figs) if x.startswith('bench_')])))
