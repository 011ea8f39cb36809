#!/usr/bin/env python3
"""Write a Mackay icosahedron as a Terrace atoms file (type x y z [vx vy vz]).

Shells n = 1..K around a central atom, 10 n^2 + 2 atoms each (13, 55, 147, 309, ... in all):
the points (n-p-q) V_i + p V_j + q V_k over the 20 faces (i, j, k) of the icosahedron whose
vertices V lie at the circumradius of an edge `a`, so that neighbours in a shell are `a` apart.

usage: make_icosahedron.py SHELLS NEIGHBOUR_DISTANCE > cluster.atoms
"""
import itertools
import math
import sys


def icosahedron_vertices():
    phi = (1 + 5 ** 0.5) / 2
    v = []
    for a, b in itertools.product((-1, 1), (-phi, phi)):
        v += [(0, a, b), (a, b, 0), (b, 0, a)]
    return v  # edge length 2


def faces(v):
    edge = 2.0
    near = lambda p, q: abs(math.dist(p, q) - edge) < 1e-9
    return [f for f in itertools.combinations(range(12), 3)
            if near(v[f[0]], v[f[1]]) and near(v[f[1]], v[f[2]]) and near(v[f[0]], v[f[2]])]


def main():
    shells, a = int(sys.argv[1]), float(sys.argv[2])
    unit = icosahedron_vertices()
    tri = faces(unit)
    v = [tuple(c * a / 2 for c in p) for p in unit]  # edge a
    pts = {(0.0, 0.0, 0.0)}
    for n in range(1, shells + 1):
        for i, j, k in tri:
            for p in range(n + 1):
                for q in range(n + 1 - p):
                    r = n - p - q
                    x = tuple(r * v[i][d] + p * v[j][d] + q * v[k][d] for d in range(3))
                    pts.add(tuple(round(c, 9) for c in x))
    print(f"# Mackay icosahedron, {shells} shells, {len(pts)} atoms, neighbour distance {a}")
    print("# type x y z (Angstrom)")
    for x in sorted(pts, key=lambda p: (p[0] ** 2 + p[1] ** 2 + p[2] ** 2, p)):
        print(f"1 {x[0]:.9f} {x[1]:.9f} {x[2]:.9f}")


if __name__ == "__main__":
    main()
