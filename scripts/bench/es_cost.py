#!/usr/bin/env python3
"""Cost of energy stepping against velocity Verlet on the same scene (one rank).

For each scene, velocity Verlet and energy stepping run from the same state, and the run logs give:
events/s, mean event interval, reflections, ray evaluations per event (goal <= 2), force passes per
event, the loop time of one event divided by the loop time of one Verlet step (goal <= 2), the
Verlet steps/s, and the simulated time per wall second of both. The "Pair", "Search" and "Other"
rows of the phase table split an event into its force pass(es), its ray evaluations and the rest.

Scenes:
  cluster7  the talk's seven-atom 2-D argon cluster (input/argon_frozen_2d*.nml): Verlet 10 fs,
            energy stepping h = 16 K k_B, 10 ns each;
  rahman    Rahman's liquid argon, 864 atoms, ~94 K (input/argon_liquid.nml melts the fcc start and
            writes argon_liquid_eq.atoms after 30 ps); from that state Verlet 10 fs for 10 ps and
            energy stepping with the same shifted LJ (cutoff 2.5 sigma) at h = 2e-3 eV (~0.25 k_B T,
            as input/argon_liquid_es.nml) for 2 ps;
  lj32k     32,000 LJ atoms, lj units, the LAMMPS benchmark scene (fcc 20^3, rho* = 0.8442,
            T* = 1.44 start) with the energy shifted at rc = 2.5: 500 Verlet steps (dt 0.005) melt the
            crystal (T* ~ 0.73) and write eq.atoms (the liquid is the case of interest); from it
            200 Verlet steps and 600 energy-stepping events at h = 0.3 eps (~0.4 k_B T; n_steps caps
            the events);
  lattice   the same scene as LAMMPS runs it, from its perfect fcc lattice at T* = 1.44: 200 Verlet
            steps and 600 events at h = 0.3 eps. Not in the default set. (Before commit 06b035c the
            event solver bisected on such nearly harmonic rays: ~5 ray evaluations per event.)
  ka        the Kob-Andersen binary LJ mixture (80:20, eps/sigma AB 1.5/0.8, BB 0.5/0.88, cutoffs
            2.5 sigma_ab, energy shifted), 4,000 atoms at rho* = 1.2: an fcc start with the types at
            random (written here, seed 8675309) melted by 1000 Verlet steps from T* = 2.0 (eq_ka.atoms);
            from it 400 Verlet steps (dt 0.005) and 1000 energy-stepping events at h = 0.1 eps: the
            multi-type path (per-pair coefficients) of the force and ray passes.

Usage:  PYTHONPATH=scripts python3 scripts/bench/es_cost.py [--terrace PATH] [--scenes cluster7,rahman,lj32k] [--repeat N]
Run time on a 2-vCPU AMD EPYC: about 40 s (80 s with --repeat 2). The binary is copied first.
Timings: loop times from the run summaries (timing/loop_time_s); with --repeat N the Verlet and the energy-stepping
run of a scene alternate N times and the fastest loop time of each is kept (the machine may be shared).
A last table divides each run's loop time by its own force-pass time (phase table), which cancels
most of a load that changes between the runs.
"""
import argparse
import datetime
import os
import platform
import random
import re
import shutil
import subprocess
import sys
import tempfile

from terrace_tools import summary

REPO = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..'))
KB_METAL = 8.617343e-5

CLUSTER = """\
&run units='metal', dimension=2, {length}, seed=1 /
&system atoms_file='argon_frozen_2d.atoms', periodic=.false.,.false., mass=39.951 /
&potential style='lj', epsilon=0.010323577, sigma=3.41, cutoff=0.0 /
{integrator}
&output thermo_file='' /
"""
RAHMAN = """\
&run units='metal', dimension=3, {length}, seed=1964 /
&system atoms_file='argon_liquid_eq.atoms', box_lo=0.0,0.0,0.0, box_hi=34.6809019,34.6809019,34.6809019,
        periodic=.true.,.true.,.true., mass=39.948 /
&potential style='lj', epsilon=0.0103408116, sigma=3.4, cutoff=8.5, shift=.true. /
&neighbor skin=1.0 /
{integrator}
&output thermo_file='' /
"""
LJ32K_LATTICE = """\
&run units='lj', dimension=3, {length}, seed=87287 /
&system lattice='fcc', density=0.8442, cells=20,20,20, periodic=.true.,.true.,.true., mass=1.0,
        temperature=1.44 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.true. /
&neighbor skin=0.3 /
{integrator}
&output thermo_file='' /
"""
# the melting run of lj32k: the lattice scene, 500 Verlet steps, writing eq.atoms
LJ32K_EQ = LJ32K_LATTICE.format(length='n_steps=500', integrator="&integrator style='velocity_verlet', dt=0.005 /") \
    .replace("&output thermo_file='' /", "&output thermo_every=100, thermo_file='', final_atoms_file='eq.atoms' /")
assert 'final_atoms_file' in LJ32K_EQ, 'LJ32K_LATTICE no longer ends with the output group LJ32K_EQ replaces'
LJ32K = """\
&run units='lj', dimension=3, {length}, seed=1 /
&system atoms_file='eq.atoms', box_lo=0.0,0.0,0.0, box_hi={L!r},{L!r},{L!r},
        periodic=.true.,.true.,.true., mass=1.0 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.true. /
&neighbor skin=0.3 /
{integrator}
&output thermo_file='' /
"""


KA_POT = ("&potential style='lj', epsilon(1,1)=1.0, sigma(1,1)=1.0, epsilon(2,2)=0.5, sigma(2,2)=0.88,\n"
          "           epsilon(1,2)=1.5, sigma(1,2)=0.8, cutoff=2.5, pair_cutoff(1,2)=2.0, pair_cutoff(2,2)=2.2,\n"
          "           shift=.true. /")
KA_CELLS, KA_RHO = 10, 1.2
KA_L = KA_CELLS * (4.0 / KA_RHO) ** (1.0 / 3.0)
KA_EQ = """\
&run units='lj', dimension=3, n_steps=1000, seed=20260 /
&system atoms_file='ka_start.atoms', box_lo=0.0,0.0,0.0, box_hi={L!r},{L!r},{L!r},
        periodic=.true.,.true.,.true., mass=1.0,1.0, temperature=2.0 /
""" + KA_POT + """
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&output thermo_every=100, thermo_file='', final_atoms_file='eq_ka.atoms' /
"""
KA = """\
&run units='lj', dimension=3, {length}, seed=1 /
&system atoms_file='eq_ka.atoms', box_lo=0.0,0.0,0.0, box_hi={L!r},{L!r},{L!r},
        periodic=.true.,.true.,.true., mass=1.0,1.0 /
""" + KA_POT + """
&neighbor skin=0.3 /
{integrator}
&output thermo_file='' /
"""


def write_ka_start(path):
    """fcc lattice of KA_CELLS^3 cells at KA_RHO, 20 % of the sites type 2 (fixed random choice)."""
    a = (4.0 / KA_RHO) ** (1.0 / 3.0)
    basis = [(0, 0, 0), (0.5, 0.5, 0), (0.5, 0, 0.5), (0, 0.5, 0.5)]
    sites = [((i + bx) * a, (j + by) * a, (k + bz) * a) for k in range(KA_CELLS) for j in range(KA_CELLS)
             for i in range(KA_CELLS) for (bx, by, bz) in basis]
    order = list(range(len(sites)))
    random.Random(8675309).shuffle(order)
    btype = set(order[:len(sites) // 5])
    with open(path, 'w') as f:
        f.write('# type x y z (Kob-Andersen start: fcc, 20 %% type 2 at random)\n')
        for n, (x, y, z) in enumerate(sites):
            f.write('%d %.12f %.12f %.12f\n' % (2 if n in btype else 1, x, y, z))


# name: description, template, Verlet length, Verlet dt, ES length, ES h, time unit, atoms
SCENES = {
    'cluster7': ('7-atom 2-D argon cluster', CLUSTER, 'run_time=10000.0', 0.01, 'run_time=10000.0',
                 16 * KB_METAL, 'ps', 7),
    'rahman': ('Rahman liquid argon, 864 atoms', RAHMAN, 'run_time=10.0', 0.01, 'run_time=2.0',
               2.0e-3, 'ps', 864),
    'lj32k': ('LJ liquid, 32,000 atoms', LJ32K, 'n_steps=200', 0.005, 'n_steps=600', 0.3, 'tau', 32000),
    'lattice': ('LJ benchmark scene from its fcc lattice, 32,000 atoms', LJ32K_LATTICE, 'n_steps=200', 0.005,
                'n_steps=600', 0.3, 'tau', 32000),
    'ka': ('Kob-Andersen mixture, 4,000 atoms', KA, 'n_steps=400', 0.005, 'n_steps=1000', 0.1, 'tau', 4000),
}


def sh(cmd):
    try:
        return subprocess.run(cmd, capture_output=True, text=True).stdout.strip()
    except OSError:
        return ''


def parse_log(out, summary_path):
    """The run's figures from its summary (terrace_tools.summary.run_figures, and the temperature of
    the last thermo sample; None and nan where a run wrote none)."""
    r = {'loop': None, 'n': None, 'builds': 0, 'temp_end': float('nan')}
    if os.path.exists(summary_path):
        r = summary.run_figures(summary_path)
        r['misses'] = summary.get(summary_path, 'energy_stepping/verification_misses', 0)
        r['temp_end'] = summary.get(summary_path, 'thermo_last/temp', float('nan'))
    return r


def run(terrace, work, name, text, repeat=1, best=None):
    """Run the deck `repeat` times; return the run with the shortest loop time (or `best`, if shorter)."""
    path = os.path.join(work, name + '.nml')
    with open(path, 'w') as f:
        f.write(text)
    for _ in range(max(1, repeat)):
        if os.path.exists(os.path.join(work, name + '.summary.json')):
            os.remove(os.path.join(work, name + '.summary.json'))
        p = subprocess.run([terrace, name + '.nml'], cwd=work, capture_output=True, text=True, timeout=1800)
        with open(os.path.join(work, name + '.log'), 'w') as f:
            f.write(p.stdout + p.stderr)
        if p.returncode != 0:
            sys.exit('terrace failed on %s (exit %d), deck %s:\n%s\n%s'
                     % (name, p.returncode, path, p.stdout[-2000:], p.stderr[-2000:]))
        r = parse_log(p.stdout, os.path.join(work, name + '.summary.json'))
        if r['loop'] is None or r['n'] is None:
            sys.exit('no run summary (loop time) for %s (%s)' % (name, path))
        if best is None or r['loop'] < best['loop']:
            best = r
    return best


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--terrace', default=os.path.join(REPO, 'build', 'terrace'), help='terrace binary')
    ap.add_argument('--scenes', default='cluster7,rahman,lj32k', help='comma-separated subset of %s'
                    % ','.join(SCENES))
    ap.add_argument('--repeat', type=int, default=1, help='repeat each timed run, keep the fastest')
    ap.add_argument('--keep', action='store_true', help='keep the work dir')
    a = ap.parse_args()
    scenes = [s.strip() for s in a.scenes.split(',') if s.strip()]
    for s in scenes:
        if s not in SCENES:
            sys.exit('unknown scene %r (have %s)' % (s, ', '.join(SCENES)))
    src = os.path.abspath(a.terrace)
    if not os.access(src, os.X_OK):
        sys.exit('terrace binary not found: %s' % src)
    work = tempfile.mkdtemp(prefix='es_cost.')
    terrace = os.path.join(work, 'terrace')      # private copy: a rebuild meanwhile must not mix versions
    shutil.copy2(src, terrace)
    built = datetime.datetime.fromtimestamp(os.path.getmtime(src), datetime.timezone.utc)

    model = re.search(r'^Model name:\s*(.+)$', sh(['lscpu']), re.M)
    dirty = sh(['git', '-C', REPO, 'status', '--porcelain', '--untracked-files=no'])
    print('Energy stepping vs velocity Verlet: cost on the same scene, 1 rank')
    print('command : %s' % ' '.join([os.path.relpath(os.path.abspath(sys.argv[0]), REPO)] + sys.argv[1:]))
    print('machine : %s (%s cores visible), %s' % (model.group(1).strip() if model else '?', os.cpu_count(),
                                                  platform.platform()))
    print('date    : %s' % datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC'))
    print('commit  : %s%s' % (sh(['git', '-C', REPO, 'rev-parse', '--short', 'HEAD']),
                              ' (+ uncommitted changes)' if dirty else ''))
    print('binary  : %s (built %s)' % (src, built.strftime('%Y-%m-%d %H:%M UTC')))
    try:
        print('load    : %.2f %.2f %.2f (load average at start)' % os.getloadavg())
    except OSError:
        pass
    print('work dir: %s' % work)
    print()
    sys.stdout.flush()

    rows = []
    for key in scenes:
        desc, tmpl, vlen, vdt, elen, h, unit, natoms = SCENES[key]
        fmt = dict()
        if key == 'cluster7':
            shutil.copy(os.path.join(REPO, 'input', 'argon_frozen_2d.atoms'), work)
        elif key == 'rahman':
            deck = open(os.path.join(REPO, 'input', 'argon_liquid.nml')).read()
            deck = deck.replace("thermo_file='argon_liquid.csv'", "thermo_file='rahman_eq.csv'")
            if "final_atoms_file='argon_liquid_eq.atoms'" not in deck:
                sys.exit('input/argon_liquid.nml no longer writes argon_liquid_eq.atoms')
            e = run(terrace, work, 'rahman_eq', deck)
            print('  rahman  : equilibration (input/argon_liquid.nml, Verlet 30 ps from fcc at 184 K): '
                  'loop %.2f s, T at the end %.1f K' % (e['loop'], e['temp_end']))
        elif key == 'lj32k':
            e = run(terrace, work, 'lj32k_eq', LJ32K_EQ)
            print('  lj32k   : equilibration (500 Verlet steps from fcc, T* = 1.44): loop %.2f s, T* at the end %.3f'
                  % (e['loop'], e['temp_end']))
            fmt['L'] = 20 * (4.0 / 0.8442) ** (1.0 / 3.0)
        elif key == 'ka':
            write_ka_start(os.path.join(work, 'ka_start.atoms'))
            e = run(terrace, work, 'ka_eq', KA_EQ.format(L=KA_L))
            print('  ka      : equilibration (1000 Verlet steps from fcc, T* = 2.0): loop %.2f s, T* at the end %.3f'
                  % (e['loop'], e['temp_end']))
            fmt['L'] = KA_L
        # Verlet and energy stepping alternate (VV ES VV ES ...), so that a change of the machine's load
        # hits both; the fastest run of each is kept
        vv = es = None
        for _ in range(max(1, a.repeat)):
            vv = run(terrace, work, key + '_vv', tmpl.format(
                length=vlen, integrator="&integrator style='velocity_verlet', dt=%r /" % vdt, **fmt), 1, vv)
            es = run(terrace, work, key + '_es', tmpl.format(
                length=elen, integrator="&integrator style='energy_stepping', terrace_height=%.9e /" % h, **fmt),
                1, es)
        t_step = vv['loop'] / vv['n']
        t_event = es['loop'] / es['events']
        sim = es['mean_dt'] * es['events']
        rows.append(dict(key=key, desc=desc, unit=unit, natoms=natoms, h=h, vdt=vdt, vv=vv, es=es,
                         ev_per_s=es['events'] / es['loop'], ratio=t_event / t_step, vv_per_s=vv['n'] / vv['loop'],
                         es_sim_per_s=sim / es['loop'], vv_sim_per_s=vdt * vv['n'] / vv['loop']))
        print('  %-8s: Verlet %d steps in %.3f s; energy stepping %d events in %.3f s (%.1f%% reflections, '
              '%d verification misses, %d list builds)'
              % (key, vv['n'], vv['loop'], es['events'], es['loop'], 100.0 * es['refl'] / es['events'],
                 es['misses'], es['builds']))
        sys.stdout.flush()

    print()
    print('%-10s %10s %15s %6s %8s %9s %10s %12s %15s %15s' % (
        'scene', 'events/s', 'mean dt', 'refl', 'evals/ev', 'passes/ev', 'event/step',
        'VV steps/s', 'ES sim/wall s', 'VV sim/wall s'))
    for r in rows:
        es = r['es']
        print('%-10s %10.4g %11.4g %-3s %5.1f%% %8.3f %9.3f %10.2f %12.4g %11.4g %-3s %11.4g %-3s' % (
            r['key'], r['ev_per_s'], es['mean_dt'], r['unit'], 100.0 * es['refl'] / es['events'], es['evals'],
            es['passes'], r['ratio'], r['vv_per_s'], r['es_sim_per_s'], r['unit'], r['vv_sim_per_s'], r['unit']))
    print()
    for r in rows:
        es = r['es']
        hs = ('h = %.3g eV = %.3g K k_B' % (r['h'], r['h'] / KB_METAL)) if r['unit'] == 'ps' else 'h = %.3g eps' % r['h']
        print('%-10s %s; %s; Verlet dt = %g %s; mean dt / Verlet dt = %.3g; T at the end: ES %.4g, Verlet %.4g '
              '(temp column, dof = dN - d)' % (r['key'], r['desc'], hs, r['vdt'], r['unit'], es['mean_dt'] / r['vdt'],
                                               es['temp_end'], r['vv']['temp_end']))
    print()
    print('Where an event goes (phase table): Pair = force pass(es), Search = ray evaluations, Other = the rest')
    print('(Comm, Neigh and Output are in the loop time but in none of the last three columns)')
    print('%-10s %16s %16s %16s %16s %16s %14s' % ('scene', 'ES loop/event', 'VV loop/step', 'ES pair/event',
                                                   'VV pair/step', 'ES search/event', 'ES other/ev'))
    for r in rows:
        es, vv = r['es'], r['vv']
        ne = es['events']
        print('%-10s %13.4g us %13.4g us %13.4g us %13.4g us %13.4g us %11.4g us' % (
            r['key'], 1e6 * es['loop'] / ne, 1e6 * vv['loop'] / vv['n'], 1e6 * es['pair'] / ne,
            1e6 * vv['pair'] / vv['n'], 1e6 * (es['search'] or 0.0) / ne, 1e6 * (es['other'] or 0.0) / ne))
    print()
    print('Load-cancelled: each run\'s loop time in its own force passes (phase table "Pair" per force pass),')
    print('so that a change of the load between the runs cancels; the last column is their ratio, an estimate of')
    print('event/step that the load does not move (the ES force pass also sums V and the virial, the Verlet one not)')
    print('%-10s %18s %18s %16s %16s %14s' % ('scene', 'ES force pass', 'VV force pass', 'ES event in', 'VV step in',
                                              'event/step'))
    print('%-10s %18s %18s %16s %16s %14s' % ('', '', '', 'force passes', 'force passes', 'load-cancelled'))
    for r in rows:
        es, vv = r['es'], r['vv']
        ne = es['events']
        fp_es = es['pair'] / (es['passes'] * ne)          # seconds per ES force pass
        fp_vv = vv['pair'] / vv['n']                       # seconds per Verlet force pass
        ev_fp = es['loop'] / ne / fp_es
        st_fp = vv['loop'] / vv['n'] / fp_vv
        print('%-10s %15.4g us %15.4g us %16.3f %16.3f %14.2f' % (r['key'], 1e6 * fp_es, 1e6 * fp_vv, ev_fp, st_fp,
                                                                 ev_fp / st_fp))
    print()
    print("event/step = loop time per event / loop time per Verlet step (goal <= 1.5); evals/ev goal <= 2;")
    print("'sim/wall s' = simulated time per second of loop time. Mean dt in the scene's time unit.")
    if a.keep:
        print('work dir kept: %s' % work)
    else:
        shutil.rmtree(work, ignore_errors=True)


if __name__ == '__main__':
    main()
