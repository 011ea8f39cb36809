#!/usr/bin/env python3
"""Write tests/regression/decks/cuni_es.data: a random 50/50 Cu-Ni fcc alloy (a = 3.56 A, 4 x 4 x 4
periodic cells, 256 atoms; type 1 = Cu, 2 = Ni, each site Ni with probability 1/2 from a fixed
seed) with Maxwell-Boltzmann velocities at 600 K (fixed seed, total momentum removed), as a LAMMPS
data file (atomic style, metal units: A, A/ps, amu). The energy-stepping alloy tests read it; this
script is how it was made (python3 tests/regression/make_cuni_es_data.py OUT.data)."""
import math
import random
import sys

A, N, T = 3.56, 4, 600.0
MASS = {1: 63.546, 2: 58.689}
KB = 8.617333262e-5            # eV/K
MVV2E = 1.0364269e-4           # amu A^2/ps^2 in eV


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else 'cuni_es.data'
    rng = random.Random(20261127)
    basis = [(0.0, 0.0, 0.0), (0.5, 0.5, 0.0), (0.5, 0.0, 0.5), (0.0, 0.5, 0.5)]
    atoms = []
    for i in range(N):
        for j in range(N):
            for k in range(N):
                for b in basis:
                    t = 2 if rng.random() < 0.5 else 1
                    atoms.append((t, (i + b[0]) * A, (j + b[1]) * A, (k + b[2]) * A))
    vel = []
    for t, *_ in atoms:
        s = math.sqrt(KB * T / (MASS[t] * MVV2E))
        vel.append([rng.gauss(0.0, s) for _ in range(3)])
    mtot = sum(MASS[t] for t, *_ in atoms)
    for d in range(3):
        p = sum(MASS[t] * v[d] for (t, *_), v in zip(atoms, vel))
        for v in vel:
            v[d] -= p / mtot
    with open(out, 'w') as f:
        f.write('Random 50/50 CuNi, 256 atoms, 600 K (tests/regression/make_cuni_es_data.py)\n\n')
        f.write('%d atoms\n2 atom types\n\n' % len(atoms))
        for lo in ('x', 'y', 'z'):
            f.write('0 %.4f %slo %shi\n' % (N * A, lo, lo))
        f.write('\nMasses\n\n1 %.3f\n2 %.3f\n\nAtoms # atomic\n\n' % (MASS[1], MASS[2]))
        for n, (t, x, y, z) in enumerate(atoms, 1):
            f.write('%d %d %.4f %.4f %.4f\n' % (n, t, x, y, z))
        f.write('\nVelocities\n\n')
        for n, v in enumerate(vel, 1):
            f.write('%d %.10f %.10f %.10f\n' % (n, v[0], v[1], v[2]))


if __name__ == '__main__':
    main()
