#!/usr/bin/env python3
"""The talk's seven-atom frozen argon cluster (2-D, LJ, no cutoff): energy stepping vs h.

One command does all of it:
  (a) runs energy stepping for 100 ns (10 ns with --quick) for a scan of terrace heights h
      (in K k_B), in a temporary work dir, each run writing a thermo CSV every 100 ps;
  (b) prints the table h -> mean event interval, reflections %, ray evaluations per event,
      force passes per event, loop time and wall time;
  (c) interpolates the scan (log-log) for the h giving the talk's mean intervals 57, 87 and
      125 fs, runs those three (re-interpolating with the new points, at most --refine times,
      while one misses its target by more than --tol: mean_dt(h) is a noisy curve), and velocity
      Verlet at dt = 10 fs, for the same time; prints the terraced-energy bounds, momenta and the
      longest chains of reflections (stretches where the kinetic energy stays frozen);
  (d) writes three PNG plots (default doc/figures/, with --quick a kept temporary dir):
        frozen_cluster_interval_vs_h.png   mean interval vs h, log-log, targets marked
        frozen_cluster_energy_error.png    (K + V - E0)/k_B vs time, three h and Verlet
        frozen_cluster_temperature.png     T = sum m v^2 / (2 N k_B) vs time, same runs
  (e) prints every number it plots (the scan table, then the time series).

Temperature convention: the talk's T = sum m v^2 / (2 N k_B), i.e. dof = 2N = 14 for 7 atoms
in 2-D (22.7 K at t = 0). Terrace's `temp` column uses dof = dN - d = 12, so T here is computed
from the `ke` column: T = ke / (N k_B).

Usage:  PYTHONPATH=scripts python3 scripts/bench/frozen_cluster.py [--quick] [--terrace PATH] [--heights 1,2,4,...]
                                   [--run-time NS] [--figdir DIR] [--keep] [--refine N] [--tol X]
Run time on a 2-vCPU AMD EPYC: about 4 minutes (100 ns; the h = 1 K run alone takes ~45 s);
--quick (10 ns runs) about 30 s. The binary is copied into the work dir first.
"""
import argparse
import datetime
import os
import platform
import re
import resource
import shutil
import subprocess
import sys
import tempfile
import time

import numpy as np

from terrace_tools import summary, thermo

REPO = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..'))
KB = 8.617343e-5            # eV/K, Terrace's metal boltz (LAMMPS)
NATOMS = 7
TARGETS_FS = (57.0, 87.0, 125.0)   # the talk's mean event intervals
VERLET_DT_PS = 0.01
SAMPLE_PS = 100.0
DEFAULT_HEIGHTS = (1, 2, 4, 8, 12, 16, 24, 32, 48, 64)

SCENE = """\
&run units='metal', dimension=2, run_time={run_time!r}, seed=1 /
&system atoms_file='{atoms}', periodic=.false.,.false., mass=39.951 /
&potential style='lj', epsilon=0.010323577, sigma=3.41, cutoff=0.0 /
{integrator}
&output thermo_interval={sample!r}, thermo_file='{csv}' /
"""


def machine_line():
    model = 'unknown'
    try:
        out = subprocess.run(['lscpu'], capture_output=True, text=True).stdout
        m = re.search(r'^Model name:\s*(.+)$', out, re.M)
        if m:
            model = m.group(1).strip()
    except OSError:
        pass
    return '%s (%s cores visible), %s' % (model, os.cpu_count(), platform.platform())


def commit_line():
    try:
        c = subprocess.run(['git', '-C', REPO, 'rev-parse', '--short', 'HEAD'],
                           capture_output=True, text=True).stdout.strip()
        dirty = subprocess.run(['git', '-C', REPO, 'status', '--porcelain', '--untracked-files=no'],
                               capture_output=True, text=True).stdout.strip()
        return c + (' (+ uncommitted changes)' if dirty else '')
    except OSError:
        return 'unknown'


def parse_log(path):
    """The closing figures of a run, from its run summary (terrace_tools.summary)."""
    f = summary.run_figures(path)
    r = {'loop_s': f['loop']}
    if summary.get(path, 'timing/steps', None) is not None:
        r['steps'] = f['n']
    if f.get('events') is not None:
        r.update(events=f['events'], up=f['up'], down=f['down'], refl=f['refl'], mean_dt_ps=f['mean_dt'],
                 evals=f['evals'], passes=f['passes'],
                 misses=summary.get(path, 'energy_stepping/verification_misses', 0))
    return r


def run_terrace(terrace, work, tag, integrator, run_time_ps, atoms):
    csv = tag + '.csv'
    deck = os.path.join(work, tag + '.nml')
    with open(deck, 'w') as f:
        f.write(SCENE.format(run_time=float(run_time_ps), atoms=atoms, integrator=integrator,
                             sample=SAMPLE_PS, csv=csv))
    ru0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run([terrace, tag + '.nml'], cwd=work, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    ru1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    with open(os.path.join(work, tag + '.log'), 'w') as f:
        f.write(p.stdout + p.stderr)
    if p.returncode != 0:
        sys.stderr.write(p.stdout[-3000:] + p.stderr[-3000:])
        raise SystemExit('terrace failed on %s (exit %d); deck: %s' % (tag, p.returncode, deck))
    r = parse_log(os.path.join(work, tag + '.summary.json'))
    r['wall_s'] = wall
    r['cpu_s'] = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    r['csv'] = thermo.read(os.path.join(work, csv))
    if not np.all(np.isfinite(r['csv']['etotal'])):
        raise SystemExit('non-finite energy in %s (deck %s)' % (csv, deck))
    return r


def es_integrator(h_eV):
    return "&integrator style='energy_stepping', terrace_height=%.9e /" % h_eV


def run_es(terrace, work, hK, run_time_ps, atoms):
    tag = 'es_h%s' % ('%g' % hK).replace('.', 'p')
    r = run_terrace(terrace, work, tag, es_integrator(hK * KB), run_time_ps, atoms)
    r['hK'] = hK
    r['refl_pct'] = 100.0 * r['refl'] / max(r['events'], 1)
    return r


def interp_h(hs, dts, target):
    """h (K) giving mean interval `target` (fs), log-log linear between the bracketing scan points."""
    lh, ld, lt = np.log(hs), np.log(dts), np.log(target)
    for i in range(len(hs) - 1):
        lo, hi = sorted((ld[i], ld[i + 1]))
        if lo <= lt <= hi and ld[i] != ld[i + 1]:
            return float(np.exp(lh[i] + (lt - ld[i]) * (lh[i + 1] - lh[i]) / (ld[i + 1] - ld[i])))
    # outside the scan: extrapolate with a straight log-log fit of all points
    a, b = np.polyfit(ld, lh, 1)
    print('  note: %.0f fs is outside the scan; extrapolated from a log-log fit' % target)
    return float(np.exp(a * lt + b))


def series(r):
    c = r['csv']
    t_ns = c['time'] * 1e-3
    de_K = (c['etotal'] - c['etotal'][0]) / KB
    T_K = c['ke'] / (NATOMS * KB)
    return t_ns, de_K, T_K


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--quick', action='store_true', help='10 ns runs instead of 100 ns')
    ap.add_argument('--terrace', default=os.path.join(REPO, 'build', 'terrace'), help='terrace binary')
    ap.add_argument('--heights', default=','.join(str(h) for h in DEFAULT_HEIGHTS),
                    help='terrace heights for the scan, in K k_B (comma separated)')
    ap.add_argument('--run-time', type=float, default=None, help='run length in ns (overrides --quick)')
    ap.add_argument('--figdir', default=None,
                    help='where the PNGs go (default doc/figures; with --quick a kept temporary dir)')
    ap.add_argument('--keep', action='store_true', help='keep the work dir (decks, logs, CSVs)')
    ap.add_argument('--refine', type=int, default=2,
                    help='at most this many re-interpolations for a target missed by more than --tol (default 2)')
    ap.add_argument('--tol', type=float, default=0.03, help='relative tolerance on the target intervals (0.03)')
    args = ap.parse_args()

    terrace = os.path.abspath(args.terrace)
    if not os.access(terrace, os.X_OK):
        raise SystemExit('terrace binary not found: %s (build: cd build && make terrace)' % terrace)
    run_ns = args.run_time if args.run_time else (10.0 if args.quick else 100.0)
    run_ps = run_ns * 1e3
    heights = sorted(float(x) for x in args.heights.split(','))
    if len(heights) < 2:
        raise SystemExit('--heights needs at least two values')
    figdir = args.figdir
    if figdir is None:
        figdir = (tempfile.mkdtemp(prefix='frozen_cluster_figs.') if args.quick
                  else os.path.join(REPO, 'doc', 'figures'))
    os.makedirs(figdir, exist_ok=True)

    work = tempfile.mkdtemp(prefix='frozen_cluster.')
    # private copy of the binary: a rebuild of build/terrace during the sweep must not mix versions
    built = datetime.datetime.fromtimestamp(os.path.getmtime(terrace), datetime.timezone.utc)
    shutil.copy2(terrace, os.path.join(work, 'terrace'))
    terrace_src, terrace = terrace, os.path.join(work, 'terrace')
    atoms = os.path.join(work, 'argon_frozen_2d.atoms')
    shutil.copy(os.path.join(REPO, 'input', 'argon_frozen_2d.atoms'), atoms)
    atoms = 'argon_frozen_2d.atoms'

    print('Frozen argon cluster (7 atoms, 2-D, LJ eps/k_B = 119.8 K, sigma = 3.41 A, no cutoff)')
    print('command : %s' % ' '.join([os.path.relpath(sys.argv[0], REPO)] + sys.argv[1:]))
    print('machine : %s' % machine_line())
    print('date    : %s' % datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC'))
    print('commit  : %s' % commit_line())
    print('binary  : %s (built %s; copied into the work dir for the whole sweep)'
          % (terrace_src, built.strftime('%Y-%m-%d %H:%M UTC')))
    print('runs    : %g ns each, thermo every %g ps, 1 rank, sequential' % (run_ns, SAMPLE_PS))
    try:
        print('load    : %.2f %.2f %.2f (1/5/15 min load average at start; timings are wall-clock, '
              'cpu = user + sys of the process)' % os.getloadavg())
    except OSError:
        pass
    print('work dir: %s' % work)
    print()
    sys.stdout.flush()

    # ---- (a), (b): scan ---------------------------------------------------------------------
    scan = []
    for hK in heights:
        r = run_es(terrace, work, hK, run_ps, atoms)
        scan.append(r)
        print('  scan h = %6g K: %8d events, %7.2f fs, wall %6.2f s' % (hK, r['events'], r['mean_dt_ps'] * 1e3,
                                                                   r['wall_s']))
        sys.stdout.flush()
    c0 = scan[0]['csv']
    E0 = c0['etotal'][0]
    print()
    print('E0/k_B = %.2f K;  T(0) = %.3f K (talk convention, dof = 2N = 14);  temp column(0) = %.3f K (dof = 12)'
          % (E0 / KB, c0['ke'][0] / (NATOMS * KB), c0['temp'][0]))
    print()

    def table(rows, title):
        print(title)
        print('   h (K k_B)    h (eV)       events   mean dt (fs)  refl (%)  evals/event  passes/event'
              '  max|E-E0| (K)  max|E-E0|/h  loop (s)  wall (s)   cpu (s)')
        for r in rows:
            de = np.max(np.abs(r['csv']['etotal'] - E0)) / KB
            print('  %9.4g  %11.5e  %10d  %12.3f  %8.2f  %11.3f  %12.3f  %13.3f  %11.3f  %8.3f  %8.3f  %8.3f'
                  % (r['hK'], r['hK'] * KB, r['events'], r['mean_dt_ps'] * 1e3, r['refl_pct'], r['evals'],
                     r['passes'], de, de / r['hK'], r['loop_s'], r['wall_s'], r['cpu_s']))
        print()

    table(scan, 'Scan, %g ns per run (mean dt = run_time / events; max|E-E0| over the 100 ps samples):' % run_ns)

    # ---- (c): the talk's three intervals, and Verlet ----------------------------------------
    hs = np.array([r['hK'] for r in scan])
    dts = np.array([r['mean_dt_ps'] * 1e3 for r in scan])
    mono = np.all(np.diff(dts) > 0)
    if not mono:
        print('  note: the mean interval is not monotone in h over this scan')
    h_targets = [interp_h(hs, dts, t) for t in TARGETS_FS]
    print('Interpolated (log-log) h for the talk\'s mean intervals:')
    for t, h in zip(TARGETS_FS, h_targets):
        print('  %5.0f fs -> h = %.3f K k_B = %.6e eV' % (t, h, h * KB))
    print()
    sys.stdout.flush()

    targ = [run_es(terrace, work, h, run_ps, atoms) for h in h_targets]
    # mean_dt(h) is a noisy curve (each h follows its own chaotic trajectory): refine by adding the
    # runs just made to the curve and interpolating again, while a run misses its target by > tol
    pts = {r['hK']: r['mean_dt_ps'] * 1e3 for r in scan}
    for rnd in range(args.refine):
        miss = [k for k, (t, r) in enumerate(zip(TARGETS_FS, targ)) if abs(r['mean_dt_ps'] * 1e3 / t - 1) > args.tol]
        if not miss:
            break
        for r in targ:
            pts[r['hK']] = r['mean_dt_ps'] * 1e3
        hh = np.array(sorted(pts))
        dd = np.array([pts[h] for h in hh])
        for k in miss:
            t = TARGETS_FS[k]
            hn = interp_h(hh, dd, t)
            rn = run_es(terrace, work, hn, run_ps, atoms)
            pts[hn] = rn['mean_dt_ps'] * 1e3
            print('  refine %d: %g fs target (best so far h = %.3f K: %.2f fs); h = %.3f K gives %.2f fs'
                  % (rnd + 1, t, targ[k]['hK'], targ[k]['mean_dt_ps'] * 1e3, hn, pts[hn]))
            if abs(rn['mean_dt_ps'] * 1e3 / t - 1) < abs(targ[k]['mean_dt_ps'] * 1e3 / t - 1):
                targ[k] = rn
        sys.stdout.flush()
    for r in targ:
        pts[r['hK']] = r['mean_dt_ps'] * 1e3
    h_targets = [r['hK'] for r in targ]
    print()
    table(targ, 'Runs at the interpolated h, %g ns each (targets %s fs):' % (run_ns, ', '.join('%g' % t for t in TARGETS_FS)))

    print('Terraced energy E_h = K + k h (column e_terraced) of those runs:')
    for r in targ:
        c = r['csv']
        eh = c['e_terraced']
        print('  h = %7.3f K: (E_h - E0)/k_B = %8.3f K, K + V - E_h in [%.3f, %.3f] K (bound [0, h]), '
              'max|E_h(t) - E_h(0)| = %.2e eV, max|P| = %.2e, max|L - L0| = %.2e'
              % (r['hK'], (eh[0] - E0) / KB, np.min(c['etotal'] - eh) / KB, np.max(c['etotal'] - eh) / KB,
                 np.max(np.abs(eh - eh[0])), np.max(np.hypot(c['px'], c['py'])), np.max(np.abs(c['lz'] - c['lz'][0]))))
    print('Reflection chains: sample intervals (%g ps) in which every event was a reflection (K frozen);'
          ' longest stretch of consecutive such intervals:' % SAMPLE_PS)
    for r in targ:
        c = r['csv']
        ev, rf = np.diff(c['events']), np.diff(c['reflections'])
        allr = (ev > 0) & (ev == rf)
        best, cur, end = 0, 0, 0
        for i, a in enumerate(allr):
            cur = cur + 1 if a else 0
            if cur > best:
                best, end = cur, i + 1
        if best:
            t0, t1 = c['time'][end - best], c['time'][end]
            print('  h = %7.3f K: %d of %d intervals; longest %.1f-%.1f ns: %d events, all reflections, T = %.2f K'
                  % (r['hK'], allr.sum(), len(allr), t0 * 1e-3, t1 * 1e-3, c['events'][end] - c['events'][end - best],
                     c['ke'][end] / (NATOMS * KB)))
        else:
            print('  h = %7.3f K: none' % r['hK'])
    print()

    ver = run_terrace(terrace, work, 'verlet', "&integrator style='velocity_verlet', dt=%r /" % VERLET_DT_PS,
                      run_ps, atoms)
    vde = (ver['csv']['etotal'] - E0) / KB
    print('Velocity Verlet, dt = %g fs, %g ns: %d steps, loop %.3f s, wall %.3f s, cpu %.3f s, %.3f us/step'
          % (VERLET_DT_PS * 1e3, run_ns, ver.get('steps', 0), ver['loop_s'], ver['wall_s'], ver['cpu_s'],
             1e6 * ver['loop_s'] / max(ver.get('steps', 1), 1)))
    print('  max|E-E0| = %.4f K, rms(E-E0) = %.4f K, E(end)-E0 = %.4f K' % (np.max(np.abs(vde)),
                                                                         np.sqrt(np.mean(vde ** 2)), vde[-1]))
    print('Cost per event (ES loop time/event) vs per Verlet step on this scene:')
    vstep = ver['loop_s'] / max(ver.get('steps', 1), 1)
    for r in targ:
        pe = r['loop_s'] / r['events']
        print('  h = %7.3f K: %.3f us/event = %.2f Verlet steps; wall per simulated ns: ES %.3f s, Verlet %.3f s'
              % (r['hK'], 1e6 * pe, pe / vstep, r['loop_s'] / run_ns, ver['loop_s'] / run_ns))
    print()

    # ---- summary of the plotted series --------------------------------------------------------
    runs = targ + [ver]
    labels = ['ES h = %.2f K (mean dt %.0f fs)' % (r['hK'], r['mean_dt_ps'] * 1e3) for r in targ] + \
             ['Verlet dt = %g fs' % (VERLET_DT_PS * 1e3)]
    print('Statistics of the plotted series (100 ps samples, t = 0 included):')
    print('  %-36s  %10s  %10s  %10s  %10s  %10s  %10s  %10s' % ('run', 'min dE (K)', 'max dE (K)', 'mean dE',
                                                            'rms dE', 'mean T (K)', 'min T', 'max T'))
    ser = [series(r) for r in runs]
    for lab, (t, de, T) in zip(labels, ser):
        print('  %-36s  %10.4f  %10.4f  %10.4f  %10.4f  %10.3f  %10.3f  %10.3f'
              % (lab, de.min(), de.max(), de.mean(), np.sqrt(np.mean(de ** 2)), T.mean(), T.min(), T.max()))
    print()

    # ---- (d): plots ---------------------------------------------------------------------------
    import matplotlib
    from terrace_tools.plotting import plt, save

    stamp = 'Terrace %s, %g ns runs' % (commit_line().split()[0], run_ns)
    f1 = os.path.join(figdir, 'frozen_cluster_interval_vs_h.png')
    fig, ax = plt.subplots(figsize=(6.4, 4.6))
    ax.loglog(hs, dts, 'o-', color='C0', label='scan (%g ns runs)' % run_ns)
    extra = sorted((h, d) for h, d in pts.items() if h not in set(hs) and h not in set(h_targets))
    if extra:
        ax.loglog([e[0] for e in extra], [e[1] for e in extra], 'x', color='gray', label='refinement runs (not kept)')
    for k, (t, h, r) in enumerate(zip(TARGETS_FS, h_targets, targ)):
        ax.loglog([h], [r['mean_dt_ps'] * 1e3], 's', color='C%d' % (k + 1), ms=8,
                  label='h = %.2f K: %.1f fs (talk %g fs)' % (h, r['mean_dt_ps'] * 1e3, t))
        ax.axhline(t, color='C%d' % (k + 1), lw=0.7, ls=':')
    ax.set_xlabel('terrace height h (K k$_B$)')
    ax.set_ylabel('mean event interval (fs)')
    ax.set_title('Frozen argon cluster: mean event interval vs h')
    ax.grid(True, which='both', alpha=0.3)
    ax.legend(fontsize=8)
    fig.text(0.99, 0.005, stamp, ha='right', va='bottom', fontsize=6, color='gray')
    save(fig, f1, dpi=120)

    f2 = os.path.join(figdir, 'frozen_cluster_energy_error.png')
    fig, axs = plt.subplots(len(runs), 1, figsize=(7.5, 8.5), sharex=True)
    for k, (ax, lab, (t, de, T), r) in enumerate(zip(axs, labels, ser, runs)):
        ax.plot(t, de, lw=0.6, color='C%d' % (k + 1 if k < 3 else 0))
        if 'hK' in r:
            ax.axhline(r['hK'], color='gray', ls='--', lw=0.7)
            ax.axhline(-r['hK'], color='gray', ls='--', lw=0.7)
            eh = (r['csv']['e_terraced'][0] - E0) / KB       # E_h - E0: K + V lies in [E_h, E_h + h]
            ax.axhline(eh, color='k', ls=':', lw=0.8)
            ax.axhline(eh + r['hK'], color='k', ls=':', lw=0.8)
            ax.set_ylim(-1.15 * r['hK'], 1.15 * r['hK'])
        ax.set_ylabel('(E - E$_0$)/k$_B$ (K)')
        ax.set_title(lab + ('   (dashed: $\\pm h$; dotted: [E$_h$, E$_h$ + h] - E$_0$)' if 'hK' in r else ''),
                     fontsize=9)
        ax.grid(True, alpha=0.3)
    axs[-1].set_xlabel('time (ns)')
    fig.suptitle('Frozen argon cluster: energy error K + V - E$_0$, E$_0$/k$_B$ = %.1f K' % (E0 / KB), fontsize=10)
    fig.text(0.99, 0.005, stamp, ha='right', va='bottom', fontsize=6, color='gray')
    save(fig, f2, dpi=120)

    f3 = os.path.join(figdir, 'frozen_cluster_temperature.png')
    fig, axs = plt.subplots(len(runs), 1, figsize=(7.5, 8.5), sharex=True, sharey=True)
    for k, (ax, lab, (t, de, T)) in enumerate(zip(axs, labels, ser)):
        ax.plot(t, T, lw=0.6, color='C%d' % (k + 1 if k < 3 else 0))
        ax.axhline(T.mean(), color='k', lw=0.8, ls='--')
        ax.set_ylabel('T (K)')
        ax.set_title('%s   (dashed: mean %.2f K)' % (lab, T.mean()), fontsize=9)
        ax.grid(True, alpha=0.3)
    axs[-1].set_xlabel('time (ns)')
    fig.suptitle('Frozen argon cluster: T = $\\sum m v^2 / (2 N k_B)$, sampled every %g ps' % SAMPLE_PS,
                 fontsize=10)
    fig.text(0.99, 0.005, stamp, ha='right', va='bottom', fontsize=6, color='gray')
    save(fig, f3, dpi=120)
    print('figures : %s' % ', '.join((f1, f2, f3)))
    print()

    # ---- (e): every plotted number ----------------------------------------------------------
    print('Plotted data, figure 1 (mean interval vs h): h (K k_B), mean dt (fs)')
    for h, d in zip(hs, dts):
        print('  %g, %.4f' % (h, d))
    for h, d in extra:
        print('  %.4f, %.4f  (refinement run, not kept)' % (h, d))
    for h, r in zip(h_targets, targ):
        print('  %.4f, %.4f  (interpolated h, kept)' % (h, r['mean_dt_ps'] * 1e3))
    print()
    print('Plotted data, figures 2 and 3 (every 100 ps): time (ns), then (E - E0)/k_B (K) and T (K) for '
          + '; '.join(labels))
    cols = ['t_ns'] + ['dE_%d' % i for i in range(len(runs))] + ['T_%d' % i for i in range(len(runs))]
    print('  ' + ','.join(cols))
    n = min(len(s[0]) for s in ser)
    for i in range(n):
        print('  %.3f,' % ser[0][0][i] + ','.join('%.5f' % s[1][i] for s in ser) + ','
              + ','.join('%.4f' % s[2][i] for s in ser))

    if args.keep:
        print('\nwork dir kept: %s' % work)
    else:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == '__main__':
    main()
