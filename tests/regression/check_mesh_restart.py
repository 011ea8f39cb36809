#!/usr/bin/env python3
"""Checkpoint and bitwise restart of a mesh scene.

The spinning cube on the small mesh (2 x 2 x 2 cells of the talk's subdivision: 71 nodes, 192
tetrahedra; rubber-like, 100 rad/s), with both integrators, on 1 and 2 ranks:
  - velocity Verlet, 199 steps with a checkpoint every 100 (so one, at step 100); energy
    stepping, 9 ms with a checkpoint every 5 ms (one, at 5 ms);
  - the straight run writes thermo, trajectory (and its XDMF sidecar), final state and the
    checkpoint; a second directory gets the checkpoint (and the thermo and trajectory files,
    which a restart cuts back to the checkpoint and continues) and restarts from it;
  - the continued thermo CSV and final-atoms file are byte-identical to the straight run's,
    every dataset and attribute of the H5MD trajectory (connectivity included) is identical, and
    the XDMF sidecar is the same text;
and a checkpoint restarted with another mesh file under the same name (a finer mesh; the same
mesh scaled by 1.01) stops with one clear error line and no output changed.

usage: check_mesh_restart.py TERRACE OUTDIR
"""
import os
import shutil

import h5py

from mesh_checks import check, compare_restart, cube_mesh as mesh, finish, read, run as run_terrace, start

terrace, out = start()


def deck(integrator, length, extra=""):
    return f"""&run units='si', dimension=3, {length}, seed=1 /
&system {extra}mesh_file='cube2.msh', mass_density=1100.0, periodic=.false.,.false.,.false.,
        angular_velocity(:,1)=0.0,0.0,100.0 /
&potential style='neohookean', lambda=2.7e6, mu=3.0e5 /
&integrator {integrator} /
&output thermo_interval=0.0005, thermo_file='thermo.csv', trajectory_file='traj.h5', trajectory_interval=0.001,
        final_atoms_file='final.txt', checkpoint_file='restart.h5', {{CKPT}} /
"""


def run(cwd, np_):
    return run_terrace(terrace, cwd, np_)


cases = [("velocity Verlet", "style='velocity_verlet', dt=1.0e-4", "n_steps=199", "checkpoint_every=100"),
         ("energy stepping", "style='energy_stepping', terrace_height=1.0e-3", "run_time=0.009",
          "checkpoint_interval=0.005")]
for name, integ, length, ckpt in cases:
    for np_ in (1, 2):
        tag = f"{name.split()[0].lower()}_np{np_}"
        a, b = os.path.join(out, tag, "straight"), os.path.join(out, tag, "restarted")
        os.makedirs(a)
        os.makedirs(b)
        mesh(os.path.join(a, "cube2.msh"))
        shutil.copy(os.path.join(a, "cube2.msh"), b)
        open(os.path.join(a, "run.nml"), "w").write(deck(integ, length).replace("{CKPT}", ckpt))
        r = run(a, np_)
        check(r.returncode == 0, f"{name}, {np_} rank(s): straight run (exit {r.returncode}) {r.stderr.strip()[-300:]}")
        if r.returncode != 0:
            continue
        with h5py.File(os.path.join(a, "restart.h5"), "r") as f:
            st = f["state"].attrs
            at = f"step {int(st['step'])}, time {float(st['time']):g} s"
            check(int(st["mesh_nodes"]) == 71 and int(st["mesh_elements"]) == 192,
                  f"{name}, {np_} rank(s): the checkpoint ({at}) names its mesh (71 nodes, 192 tetrahedra)")
        compare_restart(terrace, a, b, np_, f"{name}, {np_} rank(s)",
                        deck(integ, length, "read_checkpoint='restart.h5', ").replace("{CKPT}", ckpt),
                        f"(checkpoint at {at})")

# a checkpoint of another mesh: a finer mesh, or the same connectivity at other reference positions
base = os.path.join(out, "velocity_np1", "straight")
for what, cells, size, expect in (("a 3 x 3 x 3 mesh", 3, 0.1, "a checkpoint of a different mesh (71 nodes and 192"),
                                  ("the mesh scaled by 1.01", 2, 0.101, "same numbers of nodes and tetrahedra")):
    c = os.path.join(out, "other_mesh_" + str(cells))
    os.makedirs(c)
    mesh(os.path.join(c, "cube2.msh"), cells, size)
    for f in ("restart.h5", "thermo.csv", "traj.h5"):
        shutil.copy(os.path.join(base, f), c)
    open(os.path.join(c, "run.nml"), "w").write(
        deck(cases[0][1], cases[0][2], "read_checkpoint='restart.h5', ").replace("{CKPT}", cases[0][3]))
    before = {f: read(os.path.join(c, f)) for f in ("thermo.csv", "traj.h5")}
    r = run(c, 1)
    err = r.stderr.strip().splitlines()
    check(r.returncode != 0 and len(err) == 1 and err[0].startswith("terrace: error: ") and expect in err[0]
          and "read_checkpoint" in err[0],
          f"restart with {what} under the same name: exit {r.returncode}, one line: {r.stderr.strip()[:230]}")
    check(all(read(os.path.join(c, f)) == v for f, v in before.items())
          and not os.path.exists(os.path.join(c, "traj.xdmf")) and not os.path.exists(os.path.join(c, "final.txt")),
          f"restart with {what}: no output written or changed")

finish()
