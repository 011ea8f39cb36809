#!/usr/bin/env python3
"""Energy stepping keeps its neighbour lists complete: the energy of its last state, from the run,
equals that of its final positions computed afresh.

A 256-atom LJ liquid (fcc start at T* = 1.44, rho* = 0.8442, rc = 2.5 sigma, energy shifted, skin
0.3) runs 1.5 tau of energy stepping, in which the atoms move several skins: the built list and the
pruned list (rc + skin/4) must be renewed many times. A list that outlived its validity would miss
pairs that came inside the cutoff; the run's V would then still be conserved with K (the missing
pairs are simply not part of its potential) but would not be the energy of its positions. So: the
last thermo row's pe (thermo_file, every digit) against a minimum-image all-pairs sum over the
final_atoms_file (numpy, independent of Terrace's lists), to 1e-11 relative, on 1 and 3 ranks; and
at least --min-builds list builds in the run. The same for EAM (108 Cu atoms, Cu_u3.eam, from the
lattice at 5000 K, about 2300 K after 1 ps; a skin of 0.1 A, so that the vibrations alone carry
pairs of the fourth shell, 5.11 A, inside the cutoff, 4.95 A), against Terrace's own energy of the
final positions with a list built for them (a zero-step Verlet run). EAM has no pruned list; its
built list expires hundreds of times here.

usage: es_list_complete.py TERRACE OUTDIR [--ranks 1,3] [--min-builds 5]
"""
import argparse
import csv
import os
import shutil
import subprocess
import sys

import numpy as np

from terrace_tools import summary

CELLS = 4
DENSITY = 0.8442
RC = 2.5
EAM_FILE = '/usr/share/lammps/potentials/Cu_u3.eam'
EAM_A = 3.615
EAM_DECK = f"""&run units='metal', dimension=3, run_time=1.0, seed=77 /
&system lattice='fcc', lattice_constant={EAM_A}, cells=3,3,3, periodic=.true.,.true.,.true., temperature=5000.0 /
&potential style='eam', file='{EAM_FILE}' /
&neighbor skin=0.1 /
&integrator style='energy_stepping', target_mean_dt=5.0e-4 /
&output thermo_interval=0.5, thermo_file='thermo.csv', final_atoms_file='final.atoms' /
"""
# the reference for EAM: Terrace's own energy of the final positions with a list built for them
EAM_ZERO = f"""&run units='metal', dimension=3, n_steps=0 /
&system atoms_file='final.atoms', box_lo=0,0,0, box_hi={3*EAM_A},{3*EAM_A},{3*EAM_A},
        periodic=.true.,.true.,.true. /
&potential style='eam', file='{EAM_FILE}' /
&neighbor skin=1.0 /
&integrator style='velocity_verlet', dt=0.001 /
&output thermo_file='zero.csv' /
"""
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


def last_row(path):
    with open(path) as f:
        return list(csv.DictReader(f))[-1]


def run(terrace, work, deck, np_, env):
    open(os.path.join(work, 'run.nml'), 'w').write(deck)
    cmd = [os.path.abspath(terrace), 'run.nml']
    if np_ > 1:
        cmd = ['mpirun', '--oversubscribe', '-np', str(np_)] + cmd
    p = subprocess.run(cmd, cwd=work, capture_output=True, text=True, env=env, timeout=600)
    open(os.path.join(work, 'run.log'), 'w').write(p.stdout + p.stderr)
    if p.returncode != 0:
        print(p.stdout[-3000:], p.stderr[-3000:])
        sys.exit(f'FAIL: terrace failed in {work}')
    return p.stdout


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
    for scene in ('lj', 'eam'):
        if scene == 'eam' and not os.path.exists(EAM_FILE):
            failures.append(f'{EAM_FILE} is missing (Debian package lammps-data)')
            continue
        for np_ in [int(r) for r in a.ranks.split(',')]:
            work = os.path.join(a.outdir, f'{scene}_np{np_}')
            shutil.rmtree(work, ignore_errors=True)
            os.makedirs(work)
            run(a.terrace, work, DECK if scene == 'lj' else EAM_DECK, np_, env)
            row = last_row(os.path.join(work, 'thermo.csv'))   # every digit (the screen has ten)
            pe_run = float(row['pe'])
            end = 1.5 if scene == 'lj' else 1.0
            if abs(float(row['time']) - end) > 1e-12:
                failures.append(f'{scene}, {np_} rank(s): the last thermo row is at time {row["time"]}, not {end}')
            figures = summary.read(os.path.join(work, 'run.summary.json'))
            builds = summary.get(figures, 'neighbor/builds')
            prunes = summary.get(figures, 'neighbor/prunes', None)
            x = np.loadtxt(os.path.join(work, 'final.atoms'), comments='#')[:, 1:4]
            if scene == 'lj':
                pe_ref = all_pairs_energy(x, length)
                ref = 'all pairs (numpy)'
            else:
                open(os.path.join(work, 'zero.nml'), 'w').write(EAM_ZERO)
                subprocess.run([os.path.abspath(a.terrace), 'zero.nml'], cwd=work, capture_output=True,
                               text=True, env=env, timeout=600, check=True)
                pe_ref = float(last_row(os.path.join(work, 'zero.csv'))['pe'])
                ref = 'a list built for the final positions'
            rel = abs(pe_run - pe_ref)/abs(pe_ref)
            print(f'{scene}, {np_} rank(s): {len(x)} atoms, {builds} list builds'
                  f'{f", {prunes} prunes" if prunes is not None else ""}; pe from the run {pe_run:.12e}, '
                  f'from {ref} {pe_ref:.12e}, relative difference {rel:.2e}')
            if builds < a.min_builds:
                failures.append(f'{scene}, {np_} rank(s): only {builds} list builds (the atoms must move several skins)')
            if not rel <= 1e-11:
                failures.append(f'{scene}, {np_} rank(s): pe {pe_run!r} is not the energy of the final positions '
                                f'{pe_ref!r}')
    if failures:
        sys.exit('FAIL: ' + '; '.join(failures))
    print('OK: the energy of the last state is that of its positions (lists complete)')


if __name__ == '__main__':
    main()
