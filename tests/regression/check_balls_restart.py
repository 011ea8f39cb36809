#!/usr/bin/env python3
"""Bitwise restart through the contact.

The two colliding rubber balls on the coarse mesh (scripts/make_ball_mesh.py --refine 3 --gap 0.02:
208 nodes and 672 tetrahedra per ball; ball 2 at 1 m/s with 10 rad/s; default contact (node_face,
d0 = 14.8 mm), the closest boundary node starts about 20 mm from a face of the other ball, so the
contact begins at about 5 ms and lasts about 33 ms), both integrators, 1 and 2 ranks:
  - velocity Verlet dt = 2e-5 s, 599 steps with a checkpoint every 500 (one, at step 500,
    t = 10 ms); energy stepping h = 1e-3 J, 12 ms with a checkpoint every 10 ms (one, at 10 ms);
  - the checkpoint is inside the contact: in the straight run's trajectory frame at the checkpoint
    time the closest (boundary node, boundary face) of the two balls are nearer than the contact
    distance d0 (the barrier acts), and they were farther than d0 in the first frame;
  - a second directory gets the checkpoint (and the thermo and trajectory files, which a restart
    cuts back to the checkpoint and continues) and restarts from it: the continued thermo CSV and
    the final-state file are byte-identical to the straight run's, every dataset and attribute of
    the H5MD trajectory is identical, and the XDMF sidecar is the same text.
The mesh needs the gmsh Python package: installed into ~/.cache/terrace-venv when missing; when that
is not possible (offline), the test is SKIPPED (exit 77).
usage: check_balls_restart.py TERRACE OUTDIR
"""
import os
import re
import shutil
import sys

import h5py
import numpy as np

from mesh_checks import REPO, ball_mesh, check, compare_restart, finish, run as run_terrace, start

from point_triangle import boundary_faces, min_node_face_distance  # noqa: E402

terrace, out = start()
mesh = os.path.join(out, "balls.msh")
ball_mesh(mesh, 3, 0.02)


def deck(integrator, length, ckpt, extra=""):
    return f"""&run units='si', dimension=3, {length}, seed=1 /
&system {extra}mesh_file='balls.msh', mass_density=1100.0, periodic=.false.,.false.,.false.,
        velocity(:,2)=-1.0,0.0,0.0, angular_velocity(:,2)=0.0,0.0,10.0 /
&potential style='neohookean', lambda=2.7e6, mu=3.0e5 /
&integrator {integrator} /
&output thermo_interval=0.0005, thermo_file='thermo.csv', trajectory_file='traj.h5', trajectory_interval=0.0005,
        final_atoms_file='final.txt', checkpoint_file='restart.h5', {ckpt} /
"""


def run(cwd, np_):
    return run_terrace(terrace, cwd, np_)


def closest(x, nb):
    """Smallest distance between a boundary node of one ball (ball 1: the first NB nodes) and a
    boundary face of the other."""
    return min(min_node_face_distance(x, np.unique(faces[1 - b]), faces[b]) for b in (0, 1))


def read_tets(path):
    """The tetrahedra of each ball (physical volumes 1 and 2) of an MSH 2.2 file, 0-based node ids
    (make_ball_mesh.py numbers the nodes 1..N)."""
    lines = open(path).read().split("$Elements")[1].split("$EndElements")[0].split("\n")[2:]
    tets = {1: [], 2: []}
    for line in lines:
        v = [int(t) for t in line.split()]
        if len(v) > 1 and v[1] == 4:
            tets[v[3]].append(v[3 + v[2]:7 + v[2]])
    return [np.array(tets[b]) - 1 for b in (1, 2)]


faces = [boundary_faces(t) for t in read_tets(mesh)]


cases = [("velocity Verlet", "style='velocity_verlet', dt=2.0e-5", "n_steps=599", "checkpoint_every=500"),
         ("energy stepping", "style='energy_stepping', terrace_height=1.0e-3", "run_time=0.012",
          "checkpoint_interval=0.01")]
for name, integ, length, ckpt in cases:
    for np_ in (1, 2):
        tag = f"{name.split()[0].lower()}_np{np_}"
        a, b = os.path.join(out, tag, "straight"), os.path.join(out, tag, "restarted")
        os.makedirs(a)
        os.makedirs(b)
        shutil.copy(mesh, a)
        shutil.copy(mesh, b)
        open(os.path.join(a, "run.nml"), "w").write(deck(integ, length, ckpt))
        r = run(a, np_)
        check(r.returncode == 0, f"{name}, {np_} rank(s): straight run (exit {r.returncode}) {r.stderr.strip()[-300:]}")
        if r.returncode != 0:
            continue
        m = re.search(r"d0 =\s*([0-9.Ee+-]+)", r.stdout)
        d0 = float(m.group(1)) if m else float("nan")
        with h5py.File(os.path.join(a, "restart.h5"), "r") as f:
            st = f["state"].attrs
            tc = float(st["time"])
            at = f"step {int(st['step'])}, time {tc * 1e3:.4g} ms"
        with h5py.File(os.path.join(a, "traj.h5"), "r") as f:
            times = f["particles/all/position/time"][:]
            order = np.argsort(f["particles/all/id"][()])
            xs = f["particles/all/position/value"][()][:, order]
            k = int(np.argmin(np.abs(times - tc)))
            nb = xs.shape[1] // 2
            d_ck, d_first = closest(xs[k], nb), closest(xs[0], nb)
        check(abs(times[k] - tc) < 1e-9 and d_ck < d0 < d_first,
              f"{name}, {np_} rank(s): the checkpoint ({at}) is inside the contact: closest (node, face) of the two balls "
              f"{d_ck * 1e3:.2f} mm < d0 = {d0 * 1e3:.2f} mm (at t = 0: {d_first * 1e3:.2f} mm)")
        compare_restart(terrace, a, b, np_, f"{name}, {np_} rank(s)",
                        deck(integ, length, ckpt, "read_checkpoint='restart.h5', "), f"(checkpoint at {at})")

finish()
