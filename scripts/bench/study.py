#!/usr/bin/env python3
"""Run time against error: the benchmark and stability study of Terrace.

One command runs the whole study from a built tree and writes doc/benchmarks.md, the PNG figures
doc/figures/bench_*.png and the tables behind them (CSV, doc/bench_data/):

  1. work-precision sweeps on five atomistic scenes (seven-atom 2-D argon cluster, 147-atom argon
     icosahedron, Rahman's liquid argon, the LAMMPS LJ benchmark scene, Cu with EAM): h for energy
     stepping, dt for velocity Verlet in Terrace and in LAMMPS, against a Terrace Verlet reference
     with a much finer step: wall time against (a) max energy error per atom, (b) energy drift and
     momentum change, (c) trajectory error at a short horizon, (d) long-run observables with
     error bars;
     and on two mesh scenes (`cube`, the talk's spinning neo-Hookean cube; `balls`,
     two colliding rubber balls with contact; study/solids.py): both integrators against a fine
     Verlet reference, Verlet's largest stable dt by bisection, energy stepping's event intervals;
     and the many-collision run (`bounce`, study/bounce.py): a rubber ball in a closed box of walls,
     10^2 to 10^3 collisions, energy and restitution against time for both integrators;
  2. stability stress tests (dt and h raised until each method fails, a hot collision to 0.8 sigma,
     more ranks than atoms, an evaporating cluster);
  Parallel scaling is not part of the study: scripts/bench/scaling.sh (doc/performance.md).

Usage:
  PYTHONPATH=scripts /usr/bin/python3 scripts/bench/study.py --quick            # minutes (9 min 50 s with --repeat 3 on the 2-vCPU box, load 3-4)
  PYTHONPATH=scripts /usr/bin/python3 scripts/bench/study.py --full             # hours: 100 ns cluster, 32,000-atom LJ, ...
  PYTHONPATH=scripts /usr/bin/python3 scripts/bench/study.py --quick --scenes cube,balls
                           # the mesh scenes only (4 min on the 2-vCPU box), spliced into the page
  PYTHONPATH=scripts /usr/bin/python3 scripts/bench/study.py --quick --scenes bounce
                           # the many-collision run alone (9 min 50 s on the 2-vCPU box, load 8-15)
  PYTHONPATH=scripts /usr/bin/python3 scripts/bench/study.py --quick --scenes minority
                           # the stiff-minority meshes (study/minority.py; needs the gmsh command)
  options: --build DIR (default build/), --scenes a,b, --skip-sweep, --skip-stress, --no-lammps,
           --work DIR, --keep, --doc DIR, --no-report
Timings: each sweep point is run twice, once with thermo samples and trajectory frames for the error
measures and observables, and once (or --repeat N times, the fastest kept) with output only at the
end for its wall time: the loop time minus the output time (Terrace's and LAMMPS's own timers).
"""
import argparse
import json
import os
import shutil
import sys
import tempfile


from study import common, scenes as S, sweep, stress, report, analysis, solids, stiffness, bounce, minority  # noqa: E402

EXTRA_KEYS = ['stiffness', 'bounce', 'minority']      # mesh studies with a section of their own


class Ctx:
    pass


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    g = ap.add_mutually_exclusive_group()
    g.add_argument('--quick', action='store_true', help='minutes (default)')
    g.add_argument('--full', action='store_true', help='hours')
    ap.add_argument('--build', default=os.path.join(common.REPO, 'build'), help='build directory (terrace binary)')
    ap.add_argument('--scenes', default=','.join(S.SCENE_KEYS + solids.SOLID_KEYS + EXTRA_KEYS),
                    help='default: all; the mesh scenes alone: --scenes cube,balls (their section is '
                         'spliced into the existing page); the stiffness sweeps of the mesh scenes: '
                         '--scenes stiffness; the many-collision run: --scenes bounce; the stiff-minority '
                         'meshes: --scenes minority')
    ap.add_argument('--skip-sweep', action='store_true')
    ap.add_argument('--skip-stress', action='store_true')
    ap.add_argument('--no-lammps', action='store_true')
    ap.add_argument('--work', default='', help='work dir (default: a new temporary dir)')
    ap.add_argument('--keep', action='store_true', help='keep trajectories and dumps')
    ap.add_argument('--doc', default=os.path.join(common.REPO, 'doc'), help='where benchmarks.md goes')
    ap.add_argument('--no-report', action='store_true')
    ap.add_argument('--reuse-extras', action='store_true',
                    help="mesh scenes: keep the saved runs on the talk's 8x8x8 cube and the balls deck's mesh "
                         "(bench_data/solids_*.json) instead of running them again")
    ap.add_argument('--report-only', action='store_true',
                    help='rebuild benchmarks.md and the figures from DOC/bench_data (no runs; the energy-curve figures are kept)')
    ap.add_argument('--repeat', type=int, default=1,
                    help='timing runs per sweep point, the fastest kept (default 1; use 3 on a quiet machine)')
    ap.add_argument('--timeout', type=int, default=0, help='per-run limit in s (default 600 quick, 36000 full)')
    a = ap.parse_args()

    ctx = Ctx()
    ctx.mode = 'full' if a.full else 'quick'
    ctx.keep = a.keep
    ctx.reuse_extras = a.reuse_extras
    ctx.repeat = max(1, a.repeat)
    ctx.lammps = not a.no_lammps
    ctx.timeout = a.timeout or (600 if ctx.mode == 'quick' else 36000)
    build = os.path.abspath(a.build)
    src = os.path.join(build, 'terrace')
    if not os.access(src, os.X_OK):
        sys.exit('terrace binary not found: %s (build first: bash scripts/build.sh)' % src)
    ctx.work = os.path.abspath(a.work) if a.work else tempfile.mkdtemp(prefix='terrace_study.')
    os.makedirs(ctx.work, exist_ok=True)
    ctx.terrace = os.path.join(ctx.work, 'terrace')      # a private copy: a rebuild meanwhile cannot mix versions
    shutil.copy2(src, ctx.terrace)
    ctx.build = build
    ctx.analyzer = analysis.Analyzer(build)
    ctx.doc = os.path.abspath(a.doc)
    ctx.figs = os.path.join(ctx.doc, 'figures')
    ctx.data = os.path.join(ctx.doc, 'bench_data')
    os.makedirs(ctx.figs, exist_ok=True)
    os.makedirs(ctx.data, exist_ok=True)
    ctx.env = common.environment(build)
    ctx.env['mode'] = ctx.mode
    ctx.env['repeat'] = ctx.repeat
    ctx.env['command'] = ' '.join(['PYTHONPATH=scripts', '/usr/bin/python3',
                                   os.path.relpath(os.path.abspath(sys.argv[0]), common.REPO)]
                                  + sys.argv[1:])
    ctx.env['analyze'] = ctx.analyzer.exe or 'not in this build (numpy fallback)'
    keys = [k.strip() for k in a.scenes.split(',') if k.strip()]
    for k in keys:
        if k not in S.SCENE_KEYS + solids.SOLID_KEYS + EXTRA_KEYS:
            sys.exit('unknown scene %r (have %s)' % (k, ', '.join(S.SCENE_KEYS + solids.SOLID_KEYS + EXTRA_KEYS)))
    stiff = 'stiffness' in keys
    bouncing = 'bounce' in keys
    mino = 'minority' in keys
    solid_keys = [k for k in keys if k in solids.SOLID_KEYS]
    keys = [k for k in keys if k not in solids.SOLID_KEYS + EXTRA_KEYS]

    e = ctx.env
    print('Terrace benchmark study, %s mode' % ctx.mode)
    print('machine : %s, %s CPUs visible, %s; load %s' % (e['cpu'], e['nproc'], e['os'], e['load']))
    print('compiler: %s, %s, flags %s' % (e['compiler'], e['build_type'], e['flags_used']))
    print('LAMMPS  : %s;  MPI: %s' % (e['lammps'], e['mpi']))
    print('commit  : %s%s;  date %s' % (e['commit'], ' (+ uncommitted changes)' if e['dirty'] else '', e['date']))
    print('work dir: %s' % ctx.work, flush=True)

    page = os.path.join(ctx.doc, 'benchmarks.md')
    if a.report_only:
        if keys:
            results = report.load(ctx, keys)
            report.write(ctx, results)
        solids.splice(page, solids.write_report(ctx, {}, e))      # the mesh scenes' saved results
        stiffness.splice(page, stiffness.write_report(ctx))
        bounce.splice(page, bounce.write_report(ctx))
        minority.splice(page, minority.write_report(ctx))
        return
    sw = common.Stopwatch()
    results = {'env': e, 'sweeps': {}, 'curves': {}, 'stress': None}
    if not a.skip_sweep:
        for k in keys:
            with sw.part('sweep %s' % k):
                try:
                    rows, curves = sweep.run_scene(S.get(k), ctx)
                except RuntimeError as err:
                    print('    %s: FAILED: %s' % (k, err), flush=True)
                    rows, curves = [], {}
            results['sweeps'][k] = rows
            results['curves'][k] = curves
    results['solids'] = {}
    if not a.skip_sweep:
        for k in solid_keys:
            with sw.part('mesh scene %s' % k):
                try:
                    results['solids'][k] = solids.run_scene(k, ctx)
                except RuntimeError as err:
                    print('    %s: FAILED: %s' % (k, err), flush=True)
    results['stiffness'] = None
    if not a.skip_sweep and stiff:
        with sw.part('stiffness sweeps'):
            try:
                results['stiffness'] = stiffness.run(ctx)
            except RuntimeError as err:
                print('    stiffness: FAILED: %s' % err, flush=True)
    results['bounce'] = None
    if not a.skip_sweep and bouncing:
        with sw.part('many-collision run'):
            try:
                results['bounce'] = bounce.run(ctx)
            except RuntimeError as err:
                print('    bounce: FAILED: %s' % err, flush=True)
    results['minority'] = None
    if not a.skip_sweep and mino:
        with sw.part('stiff-minority meshes'):
            try:
                results['minority'] = minority.run(ctx)
            except RuntimeError as err:
                print('    minority: FAILED: %s' % err, flush=True)
    if not a.skip_stress and keys:
        with sw.part('stress tests'):
            results['stress'] = stress.run_all(ctx)
    results['timing'] = sw.parts
    if not a.no_report:
        with sw.part('figures and doc/benchmarks.md'):
            if keys:
                report.write(ctx, results)
            solids.splice(page, solids.write_report(ctx, results['solids'], e))   # this run's or saved
            stiffness.splice(page, stiffness.write_report(ctx, results['stiffness']))   # likewise
            bounce.splice(page, bounce.write_report(ctx, results['bounce']))   # likewise
            minority.splice(page, minority.write_report(ctx, results['minority']))       # likewise
    results['timing'] = sw.parts
    print()
    print('Time per part:')
    for name, dt in sw.parts:
        print('  %-32s %7.1f s' % (name, dt))
    print('  %-32s %7.1f s' % ('total', sw.total()))
    tfile = ('timing_%s.json' % ctx.mode if keys else 'timing_solids_%s.json' % ctx.mode if solid_keys
             else 'timing_stiffness_%s.json' % ctx.mode if stiff else 'timing_bounce_%s.json' % ctx.mode
             if bouncing else 'timing_minority_%s.json' % ctx.mode)
    with open(os.path.join(ctx.data, tfile), 'w') as f:
        json.dump({'parts': sw.parts, 'total': sw.total(), 'env': e}, f, indent=1)


if __name__ == '__main__':
    main()
