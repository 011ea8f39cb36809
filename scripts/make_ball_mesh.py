#!/usr/bin/env python3
"""Two identical tetrahedral balls for the contact scene, written as Gmsh MSH 2.2.

One ball is meshed by Gmsh (its Python package, from PyPI) with target element size R / refine;
the second is the same mesh translated, so both balls have exactly the same nodes and elements.
Ball 1 (physical volume 1) is centred at (-(R + gap/2), 0, 0), ball 2 (physical volume 2) at
(+(R + gap/2), 0, 0); node tags 1..N (ball 1 first), elements positively oriented.

usage: make_ball_mesh.py OUT.msh [--radius 0.1] [--refine 4] [--gap G] [--seed-free]
  --refine n   target element size R / n (3: coarse, for tests; 4, 6, 8: the study's levels)
  --gap G      initial surface gap in m (default: 2 R / n, more than the default contact distance)
Prints: nodes, tetrahedra, boundary faces per ball, the mean boundary edge, the gap.
Gmsh: pip install gmsh into ~/.cache/terrace-venv (this script re-executes itself with that
venv's python when gmsh is not importable).
"""
import argparse
import os
import sys

VENV_PY = os.path.expanduser("~/.cache/terrace-venv/bin/python")
try:
    import gmsh
except ImportError:
    if os.path.exists(VENV_PY) and not os.environ.get("TERRACE_BALL_MESH_REEXEC"):
        os.environ["TERRACE_BALL_MESH_REEXEC"] = "1"
        os.execv(VENV_PY, [VENV_PY] + sys.argv)
    sys.exit("make_ball_mesh.py: needs the gmsh Python package "
             "(~/.cache/terrace-venv/bin/pip install gmsh)")
import numpy as np


def one_ball(radius, size):
    gmsh.initialize(["-noenv"])
    gmsh.option.setNumber("General.Terminal", 0)
    gmsh.option.setNumber("General.NumThreads", 1)
    gmsh.option.setNumber("Mesh.RandomSeed", 1)
    gmsh.model.add("ball")
    gmsh.model.occ.addSphere(0, 0, 0, radius)
    gmsh.model.occ.synchronize()
    gmsh.option.setNumber("Mesh.MeshSizeMin", size)
    gmsh.option.setNumber("Mesh.MeshSizeMax", size)
    gmsh.option.setNumber("Mesh.Algorithm3D", 1)
    gmsh.option.setNumber("Mesh.Optimize", 1)
    gmsh.model.mesh.generate(3)
    tags, coords, _ = gmsh.model.mesh.getNodes()
    etypes, _, enodes = gmsh.model.mesh.getElements(3)
    gmsh.finalize()
    x = coords.reshape(-1, 3)
    tets = np.asarray(enodes[list(etypes).index(4)], dtype=np.int64).reshape(-1, 4)
    # keep the nodes of tetrahedra only, renumbered 0..n-1 in gmsh's order
    used = np.unique(tets)
    index = {int(t): i for i, t in enumerate(tags)}
    keep = np.array([index[int(t)] for t in used])
    remap = np.full(int(tags.max()) + 1, -1, dtype=np.int64)
    remap[used] = np.arange(len(used))
    x = x[keep]
    tets = remap[tets]
    # positive orientation
    d = x[tets[:, 1:]] - x[tets[:, :1]]
    det = np.einsum("ij,ij->i", d[:, 0], np.cross(d[:, 1], d[:, 2]))
    flip = det < 0
    tets[flip, 2], tets[flip, 3] = tets[flip, 3].copy(), tets[flip, 2].copy()
    return x, tets


def boundary_faces(tets):
    f = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 2, 3]], tets[:, [0, 1, 3]], tets[:, [0, 1, 2]]])
    fs = np.sort(f, axis=1)
    _, inv, cnt = np.unique(fs, axis=0, return_inverse=True, return_counts=True)
    return fs[cnt[inv.ravel()] == 1]


def write_msh(path, x, tets, body):
    with open(path, "w") as out:
        out.write("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n")
        out.write("$PhysicalNames\n2\n3 1 \"ball1\"\n3 2 \"ball2\"\n$EndPhysicalNames\n")
        out.write(f"$Nodes\n{len(x)}\n")
        for i, p in enumerate(x):
            out.write(f"{i + 1} {p[0]:.17g} {p[1]:.17g} {p[2]:.17g}\n")
        out.write(f"$EndNodes\n$Elements\n{len(tets)}\n")
        for e, (t, b) in enumerate(zip(tets, body)):
            out.write(f"{e + 1} 4 2 {b} {b} {t[0] + 1} {t[1] + 1} {t[2] + 1} {t[3] + 1}\n")
        out.write("$EndElements\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("out")
    ap.add_argument("--radius", type=float, default=0.1)
    ap.add_argument("--refine", type=float, default=4)
    ap.add_argument("--gap", type=float, default=None)
    a = ap.parse_args()
    r = a.radius
    size = r / a.refine
    gap = 2 * size if a.gap is None else a.gap
    x, tets = one_ball(r, size)
    n = len(x)
    c = r + 0.5 * gap
    xs = np.concatenate([x + [-c, 0, 0], x + [c, 0, 0]])
    ts = np.concatenate([tets, tets + n])
    body = np.concatenate([np.ones(len(tets), int), 2 * np.ones(len(tets), int)])
    write_msh(a.out, xs, ts, body)
    bf = boundary_faces(tets)
    edges = np.concatenate([np.linalg.norm(x[bf[:, i]] - x[bf[:, (i + 1) % 3]], axis=1) for i in range(3)])
    vol = np.sum(np.abs(np.einsum("ij,ij->i", x[tets[:, 1]] - x[tets[:, 0]],
                                  np.cross(x[tets[:, 2]] - x[tets[:, 0]], x[tets[:, 3]] - x[tets[:, 0]])))) / 6
    print(f"{a.out}: 2 balls of radius {r:g} m, refine {a.refine:g} (size {size:.4g} m): {n} nodes, {len(tets)} "
          f"tetrahedra, {len(bf)} boundary faces per ball; mean boundary edge {edges.mean():.4g} m; "
          f"volume {vol:.5g} m^3 ({vol / (4 / 3 * np.pi * r ** 3):.4f} of the sphere); gap {gap:.4g} m")


if __name__ == "__main__":
    main()
