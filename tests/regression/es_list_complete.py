#!/usr/bin/env python3
"""Energy stepping keeps its neighbour lists complete: the energy of its last state, from the run,
equals an all-pairs sum over the final positions.

A 256-atom LJ liquid (fcc start at T* = 1.44, rho* = 0.8442, rc = 2.5 sigma, energy shifted, skin
0.3) runs 1.5 tau of energy stepping, in which the atoms move several skins: the built list and the
pruned list (rc + skin/4) must be renewed many times. A list that outlived its validity would miss
pairs that came inside the cutoff; the run's V would then still be conserved with K (the missing
pairs are simply not part of its potential) but would not be the energy of its positions. So: the
last thermo row's pe (thermo_file, every digit) against a minimum-image all-pairs sum over the
final_atoms_file (numpy, independent of Terrace's lists), to 1e-11 relative, on 1 and 3 ranks; and at least --min-builds list
builds in the run.

usage: es_list_complete.py TERRACE OUTDIR [--ranks 1,3] [--min-builds 5]
"""
import argparse
import csv
import os
import re
import shutil
import subprocess
import sys

import numpy as np

CELLS = 4
DENSITY = 0.8442
RC = 2.5
DECK = f"""&run units='lj', dimension=3, run_time=1.5, seed=4242 /
&system lattice='fcc', density={DENSITY}, cells={CELLS},{CELLS},{CELLS}, periodic=.true.,.true.,.true., mass=1.0,
        temperature=1.44 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff={RC}, shift=.true. /
&neighbor skin=0.3 /
&integrator style='energy_stepping', terrace_height=0.03 /
&output thermo_interval=0.5, thermo_file='thermo.csv', final_atoms_file='final.atoms' /
"""


def all_pairs_energy(x, length):
    """Shifted LJ (eps = sigma = 1) over all minimum-image pairs within RC."""
    e_cut = 4.0*(RC**-12 - RC**-6)
    total = 0.0
    for i in range(len(x) - 1):
        d = x[i + 1:] - x[i]
        d -= length*np.round(d/length)
        r2 = np.einsum('ij,ij->i', d, d)
        r2 = r2[r2 < RC*RC]
        inv6 = r2**-3
        total += float(np.sum(4.0*(inv6*inv6 - inv6) - e_cut))
    return total


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument('terrace')
    ap.add_argument('outdir')
    ap.add_argument('--ranks', default='1,3')
    ap.add_argument('--min-builds', type=int, default=5)
    a = ap.parse_args()
    length = CELLS*(4.0/DENSITY)**(1.0/3.0)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT='1', OMPI_ALLOW_RUN_AS_ROOT_CONFIRM='1')
    failures = []
    for np_ in [int(r) for r in a.ranks.split(',')]:
        work = os.path.join(a.outdir, f'np{np_}')
        shutil.rmtree(work, ignore_errors=True)
        os.makedirs(work)
        open(os.path.join(work, 'run.nml'), 'w').write(DECK)
        cmd = [os.path.abspath(a.terrace), 'run.nml']
        if np_ > 1:
            cmd = ['mpirun', '--oversubscribe', '-np', str(np_)] + cmd
        p = subprocess.run(cmd, cwd=work, capture_output=True, text=True, env=env, timeout=600)
        open(os.path.join(work, 'run.log'), 'w').write(p.stdout + p.stderr)
        if p.returncode != 0:
            print(p.stdout[-3000:], p.stderr[-3000:])
            sys.exit(f'FAIL: terrace failed on {np_} rank(s)')
        # the last thermo row (the CSV has every digit; the screen ten)
        with open(os.path.join(work, 'thermo.csv')) as f:
            rows = list(csv.DictReader(f))
        pe_run = float(rows[-1]['pe'])
        if abs(float(rows[-1]['time']) - 1.5) > 1e-12:
            failures.append(f'{np_} rank(s): the last thermo row is at time {rows[-1]["time"]}, not the end 1.5')
        builds = int(re.search(r'Neighbour list builds: (\d+)', p.stdout).group(1))
        prunes = re.search(r': (\d+) prunes', p.stdout)
        x = np.loadtxt(os.path.join(work, 'final.atoms'), comments='#')[:, 1:4]
        pe_ref = all_pairs_energy(x, length)
        rel = abs(pe_run - pe_ref)/abs(pe_ref)
        print(f'{np_} rank(s): {len(x)} atoms, {builds} list builds, {prunes.group(1) if prunes else "?"} prunes; '
              f'pe from the run {pe_run:.10e}, all pairs {pe_ref:.10e}, relative difference {rel:.2e}')
        if builds < a.min_builds:
            failures.append(f'{np_} rank(s): only {builds} list builds (the run must move the atoms several skins)')
        if not rel <= 1e-11:
            failures.append(f'{np_} rank(s): pe {pe_run!r} is not the energy of the final positions {pe_ref!r}')
    if failures:
        sys.exit('FAIL: ' + '; '.join(failures))
    print('OK: the energy of the last state is that of its positions (lists complete)')


if __name__ == '__main__':
    main()
