#!/usr/bin/env python3
"""Render frames of a mesh trajectory (Terrace H5MD with /connectivity/tetrahedra) as a PNG strip.

Each panel draws the boundary triangles of the tetrahedral mesh (faces that belong to one
tetrahedron only) at one frame, coloured by the elastic displacement: the distance of each node
from where the best rigid motion of the reference (first) frame puts it (Kabsch fit of the
node positions, mass-unweighted), so the body's spin and drift show as the panels' orientation
and the colour shows only how the solid deforms. With --exaggerate F the drawn geometry is the
rigid motion plus F times the elastic displacement (the colours stay the true displacements);
the title says so.

usage: render_mesh.py TRAJECTORY.h5 [-o doc/figures/cube_spin.png] [--frames N | --times t1,t2,...]
                      [--exaggerate F] [--title TEXT]
Reads with terrace_tools.h5md; writes one PNG through terrace_tools.plotting.
"""
import argparse

import matplotlib
import numpy as np

from terrace_tools import h5md  # noqa: E402
from terrace_tools.plotting import plt, save  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402


def boundary_faces(tets):
    """Triangles (node rows) of the faces that belong to exactly one tetrahedron, oriented outwards
    when the tetrahedra are positively oriented."""
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 1]]])
    key = np.sort(faces, axis=1)
    _, first, count = np.unique(key, axis=0, return_index=True, return_counts=True)
    return faces[first[count == 1]]


def rigid_fit(x0, x):
    """Rotation R and shift so that R (x0 - c0) + c is the least-squares rigid image of x0 on x."""
    c0, c = x0.mean(axis=0), x.mean(axis=0)
    h = (x0 - c0).T @ (x - c)
    u, _, vt = np.linalg.svd(h)
    d = np.sign(np.linalg.det(vt.T @ u.T))
    r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    return r, c0, c


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("trajectory")
    ap.add_argument("-o", "--output", default="doc/figures/cube_spin.png")
    ap.add_argument("--frames", type=int, default=6, help="panels, evenly spaced over the trajectory")
    ap.add_argument("--times", help="comma-separated times (the nearest frames are drawn)")
    ap.add_argument("--exaggerate", type=float, default=1.0)
    ap.add_argument("--title", default="")
    a = ap.parse_args()

    tets = h5md.connectivity(a.trajectory, "tetrahedra")
    if tets is None:
        raise SystemExit(f"{a.trajectory}: no /connectivity/tetrahedra (not a mesh trajectory)")
    fr = h5md.read(a.trajectory, unwrap=False)
    ids, times, pos = fr["id"], fr["time"], fr["x"]
    tets = tets - 1                                          # node ids -> rows (rows are in id order)
    if not np.array_equal(ids, np.arange(1, len(ids) + 1)):
        raise SystemExit(f"{a.trajectory}: particles/all/id is not 1..N")
    unit = h5md.units(a.trajectory).get("position", "")
    if a.times:
        want = [float(t) for t in a.times.split(",")]
        pick = sorted({int(np.argmin(np.abs(times - t))) for t in want})
    else:
        pick = sorted(set(np.linspace(0, len(times) - 1, min(a.frames, len(times))).round().astype(int)))
    x0 = pos[0]
    frames = [pos[k] for k in pick]

    tri = boundary_faces(tets)
    scale = 1e3 if unit in ("m", "") else 1.0                  # SI lengths drawn in mm
    lunit = "mm" if scale == 1e3 else unit
    drawn, colour = [], []
    for x in frames:
        r, c0, c = rigid_fit(x0, x)
        rigid = (x0 - c0) @ r.T + c
        u = x - rigid
        drawn.append((rigid + a.exaggerate * u) * scale)
        colour.append(np.linalg.norm(u, axis=1)[tri].mean(axis=1) * scale)
    vmax = max(float(np.max(cv)) for cv in colour) or 1.0
    norm = matplotlib.colors.Normalize(0.0, vmax)
    cmap = plt.get_cmap("viridis")
    allx = np.concatenate(drawn)
    lo, hi = allx.min(axis=0), allx.max(axis=0)
    mid, half = (lo + hi) / 2, (hi - lo).max() / 2

    n = len(frames)
    fig = plt.figure(figsize=(2.6 * n + 0.8, 3.2))
    light = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])
    for i, (x, cv, k) in enumerate(zip(drawn, colour, pick)):
        ax = fig.add_subplot(1, n, i + 1, projection="3d")
        p = x[tri]
        nrm = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
        nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
        shade = 0.55 + 0.45 * np.clip(nrm @ light, 0, 1)
        rgba = cmap(norm(cv))
        rgba[:, :3] *= shade[:, None]
        ax.add_collection3d(Poly3DCollection(p, facecolors=rgba, edgecolors=(0, 0, 0, 0.15), linewidths=0.2))
        ax.set_xlim(mid[0] - half, mid[0] + half)
        ax.set_ylim(mid[1] - half, mid[1] + half)
        ax.set_zlim(mid[2] - half, mid[2] + half)
        ax.set_box_aspect((1, 1, 1))
        ax.view_init(elev=28, azim=-60)
        ax.set_axis_off()
        ax.set_title(f"t = {times[k] * 1e3:.3g} ms" if unit in ("m", "") else f"t = {times[k]:.4g}", fontsize=10)
    fig.subplots_adjust(left=0.0, right=0.92, bottom=0.02, top=0.84, wspace=0.0)
    cax = fig.add_axes([0.935, 0.15, 0.012, 0.6])
    cax.grid(False)                                        # (a colour bar has no grid)
    cb = fig.colorbar(matplotlib.cm.ScalarMappable(norm=norm, cmap=cmap), cax=cax)
    cb.set_label(f"elastic displacement ({lunit})", fontsize=9)
    title = a.title or f"{a.trajectory}: {len(x0)} nodes, {len(tets)} tetrahedra, {len(tri)} boundary triangles"
    if a.exaggerate != 1.0:
        title += f"  (deformation drawn x{a.exaggerate:g})"
    fig.suptitle(title, fontsize=10)
    save(fig, a.output, dpi=110, tight=False)
    print(f"{a.output}: frames {pick} of {len(times)}, max elastic displacement {vmax:.4g} {lunit}")


if __name__ == "__main__":
    main()
