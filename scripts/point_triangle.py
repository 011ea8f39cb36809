"""Closest points of triangles to points, vectorised with NumPy (the Voronoi regions of
src/potentials/point_triangle.f90), for the ball scripts and tests: closest_on_triangles, and
boundary_faces / min_node_face_distance for two-body meshes."""
import numpy as np


def closest_on_triangles(p, a, b, c):
    """Closest points of triangles (a, b, c) to points p (arrays (n, 3)), by the Voronoi regions
    (as src/potentials/point_triangle.f90): the barycentric weights (n, 3)."""
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(1), (ac * ap).sum(1)
    bp = p - b
    d3, d4 = (ab * bp).sum(1), (ac * bp).sum(1)
    cp = p - c
    d5, d6 = (ab * cp).sum(1), (ac * cp).sum(1)
    va, vb, vc = d3 * d6 - d5 * d4, d5 * d2 - d1 * d6, d1 * d4 - d3 * d2
    den = va + vb + vc
    den = np.where(den == 0, 1, den)
    w = np.stack([1 - (vb + vc) / den, vb / den, vc / den], axis=1)      # the face
    done = np.zeros(len(p), bool)

    def put(mask, ww):
        nonlocal done
        m = mask & ~done
        w[m] = ww[m] if ww.ndim == 2 else ww
        done |= m
    one = np.ones(len(p))
    zero = np.zeros(len(p))
    with np.errstate(divide="ignore", invalid="ignore"):
        put((d1 <= 0) & (d2 <= 0), np.array([1.0, 0, 0]))
        put((d3 >= 0) & (d4 <= d3), np.array([0, 1.0, 0]))
        t = d1 / (d1 - d3)
        put((vc <= 0) & (d1 >= 0) & (d3 <= 0), np.stack([one - t, t, zero], 1))
        put((d6 >= 0) & (d5 <= d6), np.array([0, 0, 1.0]))
        t = d2 / (d2 - d6)
        put((vb <= 0) & (d2 >= 0) & (d6 <= 0), np.stack([one - t, zero, t], 1))
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        put((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), np.stack([zero, one - t, t], 1))
    return w


def boundary_faces(tets):
    """Faces (sorted node triples) that belong to exactly one tetrahedron of tets (m, 4)."""
    f = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 2, 3]], tets[:, [0, 1, 3]], tets[:, [0, 1, 2]]])
    fs = np.sort(f, axis=1)
    _, inv, cnt = np.unique(fs, axis=0, return_inverse=True, return_counts=True)
    return fs[cnt[inv.ravel()] == 1]


def min_node_face_distance(x, nodes, faces):
    """Smallest distance from the points x[nodes] to the triangles x[faces] (all pairs)."""
    i, q = np.meshgrid(np.arange(len(nodes)), np.arange(len(faces)), indexing="ij")
    i, q = i.ravel(), q.ravel()
    p = x[nodes[i]]
    fa, fb, fc = x[faces[q, 0]], x[faces[q, 1]], x[faces[q, 2]]
    w = closest_on_triangles(p, fa, fb, fc)
    d = p - (w[:, 0:1] * fa + w[:, 1:2] * fb + w[:, 2:3] * fc)
    return float(np.sqrt((d * d).sum(1)).min())
