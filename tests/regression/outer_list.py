#!/usr/bin/env python3
"""Velocity Verlet with &neighbor outer_skin: the list is built with outer_skin and the force pass
reads the pairs within rc + skin pruned from it. The force pass must still see every pair within
rc at every step, and the run must follow the one without the outer list.

Scene: a 500-atom LJ liquid (fcc 5x5x5 at rho* = 0.8442 melting from T* = 1.44, rc = 2.5 sigma,
energy shifted, skin 0.3, outer_skin 0.9, dt 0.005), 2000 steps, thermo every 10 steps and a frame
of positions every 100 steps. Runs: without the outer list (1 rank), with it (1 and 4 ranks), and with
it on a fixed schedule (skin 0.1, every = 10, check = .false., prune_every = 2; 1 and 4 ranks): in 10
steps no atom of this liquid moves (outer_skin - skin)/2 = 0.4, in 2 steps none moves skin/2 = 0.05,
so that schedule is exact here too. Without its prunes (a list of rc + 0.1 kept for 10 steps) it is
not: its thermo leaves the exact run's by 0.26 relative within 500 steps (its frames, every 100
steps, fall on builds, where the list is whole).

1. Exact list: at each of the 21 frames, the thermo pe of that step (every digit, from thermo_file)
   equals a minimum-image all-pairs sum over the frame's positions (numpy, no Terrace list) to 1e-11
   relative, on 1 and 4 ranks. A pruned list that outlived its validity would miss pairs that came
   inside rc, and its pe would not be the energy of the positions.
2. The same trajectory: the thermo rows with and without the outer list agree to 1e-10 relative
   (1e-9 absolute) over the first --same-steps steps. Not to the end: both lists hold the same pairs,
   but the bins (at least rc + list skin wide), so the atoms' order after each sort and the order of
   the sums, differ; the round-off differences, 1e-16 at first, grow exponentially in a liquid (its
   largest Lyapunov exponent) and reach 1e-10 after several hundred steps. The 1- and 4-rank runs
   with the outer list are compared in the same way, and so are the two schedules.
3. The schedule: the builds and prunes on 1 and 4 ranks within 2 of each other (the decisions take
   global maxima; decisions taken apart would not even agree on when to sum: a hang. Not exactly the
   same: past the first few hundred steps the two trajectories part by round-off, and a portable
   build's 2000 steps made 130 and 129 prunes), prunes > 0, and fewer builds than without the outer list. The run log states the prunes. The
   fixed schedule builds at step 0 and every 10 steps (201 builds, none late) and prunes at the other
   multiples of 2 (800 prunes).

usage: outer_list.py TERRACE OUTDIR [--same-steps 500]
"""
import argparse
import csv
import os
import shutil
import sys

import h5py
import numpy as np

from terrace_tools import summary

from es_list_complete import RC, all_pairs_energy, run as run_deck   # (beside this script: on sys.path as its folder)

CELLS = 5
DENSITY = 0.8442
DECK = f"""&run units='lj', dimension=3, n_steps=2000, seed=4242 /
&system lattice='fcc', density={DENSITY}, cells={CELLS},{CELLS},{CELLS}, periodic=.true.,.true.,.true., mass=1.0,
        temperature=1.44 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff={RC}, shift=.true. /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3NEIGHBOR /
&output thermo_every=10, thermo_file='thermo.csv', trajectory_file='traj.h5', trajectory_every=100,
        trajectory_fields='position' /
"""


def rows(path):
    with open(path) as f:
        return [r for r in csv.DictReader(f)]


FIXED = ', every=10, check=.false., prune_every=2'     # the fixed schedule's keys (with skin 0.1)


def run(terrace, work, outer, np_, env, fixed=False):
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    deck = DECK.replace('NEIGHBOR', (f', outer_skin={outer}' if outer else '') + (FIXED if fixed else ''))
    return run_deck(terrace, work, deck.replace('skin=0.3,', 'skin=0.1,') if fixed else deck, np_, env)


def same_rows(a, b, steps):
    """The largest relative difference of the thermo columns up to `steps` (1e-9 absolute floor)."""
    worst = 0.0
    for ra, rb in zip(a, b):
        if int(ra['step']) > steps:
            break
        for k in ('temp', 'pe', 'ke', 'etotal', 'press'):
            va, vb = float(ra[k]), float(rb[k])
            if abs(va - vb) > 1e-9:
                worst = max(worst, abs(va - vb)/max(abs(va), abs(vb)))
    return worst


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('terrace')
    ap.add_argument('outdir')
    ap.add_argument('--same-steps', type=int, default=500)
    a = ap.parse_args()
    length = CELLS*(4.0/DENSITY)**(1.0/3.0)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT='1', OMPI_ALLOW_RUN_AS_ROOT_CONFIRM='1')
    failures = []
    runs = {'off_np1': (0, 1), 'on_np1': (0.9, 1), 'on_np4': (0.9, 4), 'fixed_np1': (0.9, 1), 'fixed_np4': (0.9, 4)}
    thermo, figures = {}, {}
    for name, (outer, np_) in runs.items():
        work = os.path.join(a.outdir, name)
        out = run(a.terrace, work, outer, np_, env, name.startswith('fixed'))
        thermo[name] = rows(os.path.join(work, 'thermo.csv'))
        figures[name] = summary.read(os.path.join(work, 'run.summary.json'))
        if outer and 'prunes between the builds' not in out:
            failures.append(f'{name}: the run log does not state the prunes')
        if not outer:
            continue
        # 1. every frame's pe is the energy of its positions
        pe_at = {int(r['step']): float(r['pe']) for r in thermo[name]}
        with h5py.File(os.path.join(work, 'traj.h5'), 'r') as f:
            steps = f['particles/all/position/step'][()]
            xs = f['particles/all/position/value'][()]
        worst = 0.0
        for step, x in zip(steps, xs):
            ref = all_pairs_energy(x, length)
            rel = abs(pe_at[int(step)] - ref)/abs(ref)
            worst = max(worst, rel)
            if not rel <= 1e-11:
                failures.append(f'{name}: step {step}: pe {pe_at[int(step)]!r} is not the energy of the positions {ref!r}')
        print(f'{name}: {len(steps)} frames (steps {steps[0]}..{steps[-1]}): pe = all-pairs energy of the positions '
              f'to {worst:.1e} relative')
    # 2. the same trajectory as without the outer list, and on 1 and 4 ranks
    for x, y in (('off_np1', 'on_np1'), ('on_np1', 'on_np4'), ('on_np1', 'fixed_np1'), ('fixed_np1', 'fixed_np4')):
        d = same_rows(thermo[x], thermo[y], a.same_steps)
        print(f'{x} against {y}: thermo to {d:.1e} relative over the first {a.same_steps} steps; '
              f'etotal at step 2000 {float(thermo[x][-1]["etotal"]):.10f} and {float(thermo[y][-1]["etotal"]):.10f}')
        if not d <= 1e-10:
            failures.append(f'{x} and {y} differ by {d:.2e} (relative) within {a.same_steps} steps')
    # 3. the schedule
    get = {n: (summary.get(figures[n], 'neighbor/builds'), summary.get(figures[n], 'neighbor/prunes', None))
           for n in runs}
    print('builds, prunes: ' + '; '.join(f'{n} {b}, {p}' for n, (b, p) in get.items()))
    if any(abs(u - v) > 2 for u, v in zip(get['on_np1'], get['on_np4'])):
        failures.append(f'builds and prunes differ by more than 2 on 1 and 4 ranks: {get["on_np1"]} and {get["on_np4"]}')
    if not (get['on_np1'][1] or 0) > 0:
        failures.append('no prune with the outer list')
    if not get['on_np1'][0] < get['off_np1'][0]:
        failures.append(f'the outer list is built {get["on_np1"][0]} times, without it {get["off_np1"][0]}')
    for n in ('fixed_np1', 'fixed_np4'):
        late = summary.get(figures[n], 'neighbor/late_builds', None)
        if get[n] != (201, 800) or late != 0:
            failures.append(f'{n}: {get[n][0]} builds ({late} late) and {get[n][1]} prunes; expected 201 (0 late) '
                            'and 800')
    if failures:
        sys.exit('FAIL: ' + '; '.join(failures))
    print('OK: the outer list keeps the force pass exact and follows the run without it')


if __name__ == '__main__':
    main()
