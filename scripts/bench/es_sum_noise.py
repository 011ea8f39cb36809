#!/usr/bin/env python3
"""Round-off noise of the total potential energy V against the energy-stepping root tolerance.

Why energy stepping had "verification misses" on large systems: the event solver places a
crossing where V = level to within tol = max(root_tolerance h, 64 eps |V|), and the force pass at
that point checks V against the level to the same tol. If V itself is computed with a round-off
error that is random at the scale of tol, the check fails at random although the crossing is right.

This script takes the 32,000-atom LJ liquid of es_cost.py (the same deck: 500 Verlet steps from
fcc at T* = 1.44, shifted LJ, rc = 2.5; it runs terrace once to make the state, or reads a given
atoms file) and evaluates V at a few points x + s v along the state's velocities (as a ray pass does),
each in three ways, against math.fsum of all pair energies (exact to one rounding):
  plain      one running sum over all pairs (atom by atom, each atom's neighbours in turn): what
             the LJ kernels did before (commit 486be99);
  per atom   each atom's pairs summed plainly, the per-atom sums added plainly;
  per atom + compensated   the per-atom sums added with a compensated (TwoSum) sum: what the
             kernels do now.
The pair order is this script's own (cells), not Terrace's, which does not matter for the size of the
noise: it is set by the number of additions and the size of the partial sums.

Usage:  python3 scripts/bench/es_sum_noise.py [--terrace build/terrace] [--atoms FILE] [--points 8]
Pure Python (no numpy): about 5 s per point on a 2-vCPU Xeon.
"""
import argparse
import math
import os
import shutil
import subprocess
import sys
import tempfile

REPO = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..'))
import es_cost  # noqa: E402  (the decks)

RC = 2.5
H = 0.3                         # es_cost.py's terrace height for this scene (eps)
ROOT_TOL = 1e-9                 # the default root_tolerance
EPS = 2.0 ** -52


def make_state(terrace, work):
    with open(os.path.join(work, 'eq.nml'), 'w') as f:
        f.write(es_cost.LJ32K_EQ)
    p = subprocess.run([terrace, 'eq.nml'], cwd=work, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit('terrace failed:\n' + p.stdout[-2000:] + p.stderr[-2000:])
    return os.path.join(work, 'eq.atoms')


def read_atoms(path):
    x, v = [], []
    for line in open(path):
        if line.startswith('#') or not line.strip():
            continue
        w = line.split()
        x.append([float(t) for t in w[1:4]])
        v.append([float(t) for t in w[4:7]])
    return x, v


def pair_energies(x, L):
    """Per atom i, the list of shifted LJ energies of its pairs (i, j > i in cell order) within RC."""
    n = len(x)
    nc = int(L // RC)
    cs = L / nc
    cells = {}
    for i, (a, b, c) in enumerate(x):
        key = (int(a % L // cs) % nc, int(b % L // cs) % nc, int(c % L // cs) % nc)
        cells.setdefault(key, []).append(i)
    rc2 = RC * RC
    sr6 = RC ** -6
    offset = 4 * (sr6 * sr6 - sr6)
    out = [[] for _ in range(n)]
    half = L / 2
    for (cx, cy, cz), members in cells.items():
        neigh = []
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    neigh.extend(cells.get(((cx + dx) % nc, (cy + dy) % nc, (cz + dz) % nc), ()))
        for i in members:
            xi, yi, zi = x[i]
            row = out[i]
            for j in neigh:
                if j <= i:
                    continue
                ddx = xi - x[j][0]
                ddy = yi - x[j][1]
                ddz = zi - x[j][2]
                if ddx > half:
                    ddx -= L
                elif ddx < -half:
                    ddx += L
                if ddy > half:
                    ddy -= L
                elif ddy < -half:
                    ddy += L
                if ddz > half:
                    ddz -= L
                elif ddz < -half:
                    ddz += L
                r2 = ddx * ddx + ddy * ddy + ddz * ddz
                if r2 < rc2:
                    r6 = 1.0 / (r2 * r2 * r2)
                    row.append(4 * r6 * (r6 - 1) - offset)
    return out


def two_sum_total(terms):
    s = c = 0.0
    for t in terms:
        u = s + t
        z = u - s
        c += (s - (u - z)) + (t - z)
        s = u
    return s + c


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--terrace', default=os.path.join(REPO, 'build', 'terrace'))
    ap.add_argument('--atoms', help='the 32,000-atom start state (default: made with --terrace)')
    ap.add_argument('--points', type=int, default=8, help='points x + s v along the velocities')
    ap.add_argument('--ds', type=float, default=1.0e-5, help='spacing of the points in tau (an event is ~5e-5)')
    a = ap.parse_args()
    work = tempfile.mkdtemp(prefix='es_sum_noise.')
    path = a.atoms or make_state(os.path.abspath(a.terrace), work)
    x0, v = read_atoms(path)
    L = 20 * (4.0 / 0.8442) ** (1.0 / 3.0)
    print('state: %s (%d atoms), box %.6f, shifted LJ rc = %g' % (path, len(x0), L, RC))
    errs = {'plain': [], 'per atom': [], 'per atom + compensated': []}
    tol = None
    for k in range(a.points):
        s = k * a.ds
        x = [[p[0] + s * w[0], p[1] + s * w[1], p[2] + s * w[2]] for p, w in zip(x0, v)]
        rows = pair_energies(x, L)
        exact = math.fsum(t for row in rows for t in row)
        plain = 0.0
        for row in rows:
            for t in row:
                plain += t
        atom = [sum(row) for row in rows]          # per atom, plain (Python's sum adds in order)
        per_atom = 0.0
        for t in atom:
            per_atom += t
        comp = two_sum_total(atom)
        tol = max(ROOT_TOL * H, 64 * EPS * abs(exact))
        errs['plain'].append(plain - exact)
        errs['per atom'].append(per_atom - exact)
        errs['per atom + compensated'].append(comp - exact)
        print('  s = %.1e: V = %.10f, pairs %d; error plain %+.2e, per atom %+.2e, compensated %+.2e'
              % (s, exact, sum(len(r) for r in rows), plain - exact, per_atom - exact, comp - exact))
        sys.stdout.flush()
    print()
    print('tolerance tol = max(%g h, 64 eps |V|) = %.3e  (h = %g)' % (ROOT_TOL, tol, H))
    for name, e in errs.items():
        rms = math.sqrt(sum(t * t for t in e) / len(e))
        print('%-24s rms error %.2e = %.2f tol, largest %.2e' % (name, rms, rms / tol, max(abs(t) for t in e)))
    shutil.rmtree(work, ignore_errors=True)


if __name__ == '__main__':
    main()
