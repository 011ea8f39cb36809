#!/usr/bin/env python3
"""The talk's cube mesh: N x N x N cubic cells (N = 8 in the talk), each with its 8 corners, 6 face
centres and 1 body centre; each face is split into 4 triangles (face centre + one cube edge) and
each triangle is joined to the body centre: 24 tetrahedra per cell, conforming across cells.
N = 8 gives (N+1)^3 + N^3 + 3 N^2 (N+1) = 2,969 nodes and 24 N^3 = 12,288 tetrahedra.

Writes Gmsh MSH 4.1 ASCII (default) or 2.2: node tags 1..n, positively oriented 4-node
tetrahedra (element type 4), one physical volume (tag 1, "cube"). numpy only.

usage: /usr/bin/python3 scripts/make_cube_mesh.py OUT.msh [--cells 8] [--size 1.0] [--format 4.1|2.2] [--center]
"""
import argparse
import sys

import numpy as np


def cube_mesh(n, size, center):
    h = size / n
    nodes = {}
    coords = []

    def node(key, x):
        if key not in nodes:
            nodes[key] = len(coords) + 1
            coords.append(x)
        return nodes[key]

    # keys on a doubled grid: corners at even (i, j, k), face centres with two odd, body centre all odd
    def at(i2, j2, k2):
        return node((i2, j2, k2), (0.5 * h * i2, 0.5 * h * j2, 0.5 * h * k2))

    tets = []
    for k in range(n):
        for j in range(n):
            for i in range(n):
                c = at(2 * i + 1, 2 * j + 1, 2 * k + 1)
                for axis in range(3):
                    for side in (0, 2):
                        base = [2 * i + 1, 2 * j + 1, 2 * k + 1]
                        base[axis] = 2 * [i, j, k][axis] + side
                        fc = at(*base)
                        u, w = [a for a in range(3) if a != axis]
                        # the face's four corners in cyclic order
                        ring = []
                        for du, dw in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                            p = list(base)
                            p[u] += du
                            p[w] += dw
                            ring.append(at(*p))
                        for q in range(4):
                            tets.append([c, fc, ring[q], ring[(q + 1) % 4]])
    x = np.array(coords, dtype=float)
    if center:
        x -= 0.5 * size
    t = np.array(tets, dtype=np.int64)
    # orient positively: det[X1-X0, X2-X0, X3-X0] > 0
    d = np.linalg.det(np.stack([x[t[:, 1] - 1] - x[t[:, 0] - 1], x[t[:, 2] - 1] - x[t[:, 0] - 1],
                                x[t[:, 3] - 1] - x[t[:, 0] - 1]], axis=2))
    neg = d < 0
    t[neg, 2], t[neg, 3] = t[neg, 3].copy(), t[neg, 2].copy()
    return x, t


def write_msh41(path, x, t):
    n, m = len(x), len(t)
    with open(path, "w") as f:
        f.write("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n")
        f.write('$PhysicalNames\n1\n3 1 "cube"\n$EndPhysicalNames\n')
        lo, hi = x.min(axis=0), x.max(axis=0)
        f.write("$Entities\n0 0 0 1\n")
        f.write(f"1 {lo[0]:.17g} {lo[1]:.17g} {lo[2]:.17g} {hi[0]:.17g} {hi[1]:.17g} {hi[2]:.17g} 1 1 0\n")
        f.write("$EndEntities\n")
        f.write(f"$Nodes\n1 {n} 1 {n}\n3 1 0 {n}\n")
        f.write("".join(f"{i}\n" for i in range(1, n + 1)))
        f.write("".join(f"{a:.17g} {b:.17g} {c:.17g}\n" for a, b, c in x))
        f.write("$EndNodes\n")
        f.write(f"$Elements\n1 {m} 1 {m}\n3 1 4 {m}\n")
        f.write("".join(f"{e + 1} {r[0]} {r[1]} {r[2]} {r[3]}\n" for e, r in enumerate(t)))
        f.write("$EndElements\n")


def write_msh22(path, x, t):
    with open(path, "w") as f:
        f.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n")
        f.write('$PhysicalNames\n1\n3 1 "cube"\n$EndPhysicalNames\n')
        f.write(f"$Nodes\n{len(x)}\n")
        f.write("".join(f"{i + 1} {a:.17g} {b:.17g} {c:.17g}\n" for i, (a, b, c) in enumerate(x)))
        f.write("$EndNodes\n")
        f.write(f"$Elements\n{len(t)}\n")
        f.write("".join(f"{e + 1} 4 2 1 1 {r[0]} {r[1]} {r[2]} {r[3]}\n" for e, r in enumerate(t)))
        f.write("$EndElements\n")


def check(x, t):
    """Counts, orientation, volume and conformity (every interior face shared by two tetrahedra)."""
    d = np.linalg.det(np.stack([x[t[:, 1] - 1] - x[t[:, 0] - 1], x[t[:, 2] - 1] - x[t[:, 0] - 1],
                                x[t[:, 3] - 1] - x[t[:, 0] - 1]], axis=2))
    faces = np.sort(np.concatenate([t[:, [1, 2, 3]], t[:, [0, 2, 3]], t[:, [0, 1, 3]], t[:, [0, 1, 2]]]), axis=1)
    _, counts = np.unique(faces, axis=0, return_counts=True)
    return d.min() > 0, d.sum() / 6, counts.max(), int((counts == 1).sum())


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--cells", type=int, default=8)
    ap.add_argument("--size", type=float, default=1.0, help="edge length of the cube (m)")
    ap.add_argument("--format", choices=("4.1", "2.2"), default="4.1")
    ap.add_argument("--center", action="store_true", help="centre the cube on the origin")
    a = ap.parse_args()
    x, t = cube_mesh(a.cells, a.size, a.center)
    positive, volume, max_share, boundary = check(x, t)
    if not positive or max_share > 2 or abs(volume - a.size ** 3) > 1e-9 * a.size ** 3:
        sys.exit(f"make_cube_mesh: bad mesh (positive {positive}, volume {volume}, a face in {max_share} tets)")
    (write_msh41 if a.format == "4.1" else write_msh22)(a.out, x, t)
    print(f"{a.out}: {len(x)} nodes, {len(t)} tetrahedra, volume {volume:.6g}, {boundary} boundary faces, "
          f"all positively oriented, conforming (MSH {a.format})")


if __name__ == "__main__":
    main()
