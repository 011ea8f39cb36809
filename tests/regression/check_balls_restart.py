#!/usr/bin/env python3
"""Bitwise restart through the contact (issue 13, must-show 6).

The two colliding rubber balls on the coarse mesh (scripts/make_ball_mesh.py --refine 3 --gap 0.031:
208 nodes and 672 tetrahedra per ball; ball 2 at 1 m/s with 10 rad/s; default contact, d0 = 29.6 mm,
and the closest nodes start 35.6 mm apart, so the contact begins at about 6 ms and lasts about
37 ms), both integrators, 1 and 2 ranks:
  - velocity Verlet dt = 2e-5 s, 599 steps with a checkpoint every 500 (one, at step 500,
    t = 10 ms); energy stepping h = 1e-3 J, 12 ms with a checkpoint every 10 ms (one, at 10 ms);
  - the checkpoint is inside the contact: in the straight run's trajectory frame at the checkpoint
    time the closest nodes of the two balls are nearer than the contact distance d0 (the barrier
    acts), and they were farther than d0 in the first frame;
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
import subprocess
import sys

import h5py
import numpy as np

terrace, out = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
shutil.rmtree(out, ignore_errors=True)
os.makedirs(out)
venv = os.path.expanduser("~/.cache/terrace-venv")
vpy = os.path.join(venv, "bin", "python")
if subprocess.run([vpy, "-c", "import gmsh"], capture_output=True).returncode != 0 if os.path.exists(vpy) else True:
    if not os.path.exists(vpy):
        subprocess.run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", venv], capture_output=True)
    r = subprocess.run([vpy, "-m", "pip", "install", "-q", "gmsh"], capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        print("SKIPPED: the gmsh Python package is not installed and cannot be installed (offline?): "
              + r.stderr.strip()[-200:])
        sys.exit(77)
mesh = os.path.join(out, "balls.msh")
subprocess.run([sys.executable, os.path.join(repo, "scripts", "make_ball_mesh.py"), mesh, "--refine", "3",
                "--gap", "0.031"], check=True, stdout=subprocess.DEVNULL)
failed = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failed.append(what)


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
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = [terrace, "run.nml"] if np_ == 1 else ["mpirun", "--oversubscribe", "-np", str(np_), terrace, "run.nml"]
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=300)


def same_h5(a_path, b_path):
    a, b = h5py.File(a_path, "r"), h5py.File(b_path, "r")
    na, nb = [], []
    a.visit(na.append)
    b.visit(nb.append)
    if sorted(na) != sorted(nb):
        return f"layouts differ: {sorted(set(na) ^ set(nb))}"
    n = 0
    for name in ["/"] + na:
        oa, ob = a[name], b[name]
        if sorted(oa.attrs) != sorted(ob.attrs) or any(
                not np.array_equal(np.asarray(oa.attrs[k]), np.asarray(ob.attrs[k])) for k in oa.attrs):
            return f"{name}: attributes differ"
        if isinstance(oa, h5py.Dataset):
            va, vb = oa[()], ob[()]
            if va.dtype != vb.dtype or va.shape != vb.shape or not np.array_equal(va, vb):
                return f"{name}: dataset differs"
            n += 1
    return n


def read(path):
    return open(path, "rb").read()


def closest(x, nb):
    """Smallest distance between a node of ball 1 (the first NB nodes) and a node of ball 2."""
    a, b = x[:nb], x[nb:]
    return min(float(np.min(np.linalg.norm(a - b[j], axis=1))) for j in range(len(b)))


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
            xs = f["particles/all/position/value"]
            k = int(np.argmin(np.abs(times - tc)))
            nb = xs.shape[1] // 2
            d_ck, d_first = closest(xs[k], nb), closest(xs[0], nb)
        check(abs(times[k] - tc) < 1e-9 and d_ck < d0 < d_first,
              f"{name}, {np_} rank(s): the checkpoint ({at}) is inside the contact: closest nodes of the two balls "
              f"{d_ck * 1e3:.2f} mm < d0 = {d0 * 1e3:.2f} mm (at t = 0: {d_first * 1e3:.2f} mm)")
        for f in ("restart.h5", "thermo.csv", "traj.h5"):
            shutil.copy(os.path.join(a, f), b)
        open(os.path.join(b, "run.nml"), "w").write(deck(integ, length, ckpt, "read_checkpoint='restart.h5', "))
        r = run(b, np_)
        check(r.returncode == 0, f"{name}, {np_} rank(s): restart from the checkpoint (exit {r.returncode}) "
              f"{r.stderr.strip()[-300:]}")
        if r.returncode != 0:
            continue
        lines = read(os.path.join(a, "thermo.csv")).count(b"\n") - 1
        check(read(os.path.join(a, "thermo.csv")) == read(os.path.join(b, "thermo.csv")),
              f"{name}, {np_} rank(s): {lines} thermo lines of the restarted run byte-identical to the straight run's")
        check(read(os.path.join(a, "final.txt")) == read(os.path.join(b, "final.txt")),
              f"{name}, {np_} rank(s): final positions and velocities byte-identical")
        n = same_h5(os.path.join(a, "traj.h5"), os.path.join(b, "traj.h5"))
        check(isinstance(n, int), f"{name}, {np_} rank(s): trajectory identical ({n} datasets)")
        xa, xb = read(os.path.join(a, "traj.xdmf")), read(os.path.join(b, "traj.xdmf"))
        check(xa == xb, f"{name}, {np_} rank(s): XDMF sidecar identical ({xa.count(b'<Time ')} frames)")

if failed:
    print(f"{len(failed)} check(s) failed")
    sys.exit(1)
print("PASS")
