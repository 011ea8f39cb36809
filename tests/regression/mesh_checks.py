"""What the mesh regression tests (check_mesh_*.py, check_balls*.py) share: the command line
(TERRACE OUTDIR, a fresh OUTDIR), ok/FAIL lines, running a deck on N ranks, byte and HDF5
comparisons, and the gmsh Python package (installed once into ~/.cache/terrace-venv; SKIPPED,
exit 77, where it cannot be installed)."""
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
VENV = os.path.expanduser("~/.cache/terrace-venv")
failed = []


def start():
    """(terrace, outdir) from the command line; outdir emptied."""
    terrace, out = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    return terrace, out


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        failed.append(what)


def finish():
    if failed:
        print(f"{len(failed)} check(s) failed")
        sys.exit(1)
    print("PASS")
    sys.exit(0)


def run(terrace, cwd, np_, deck="run.nml", timeout=300):
    """terrace DECK in cwd on np_ ranks (mpirun from 2 on)."""
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    cmd = [terrace, deck] if np_ == 1 else ["mpirun", "--oversubscribe", "-np", str(np_), terrace, deck]
    return subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)


def read(path):
    return open(path, "rb").read()


def same_h5(a_path, b_path):
    """The number of datasets when every dataset and attribute of both files is equal, else why not."""
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


def need_gmsh():
    """The gmsh package in the venv that scripts/make_ball_mesh.py re-executes itself with."""
    vpy = os.path.join(VENV, "bin", "python")
    if os.path.exists(vpy) and subprocess.run([vpy, "-c", "import gmsh"], capture_output=True).returncode == 0:
        return
    if not os.path.exists(vpy):
        subprocess.run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", VENV], capture_output=True)
    r = subprocess.run([vpy, "-m", "pip", "install", "-q", "gmsh"], capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        print("SKIPPED: the gmsh Python package is not installed and cannot be installed (offline?): "
              + r.stderr.strip()[-200:])
        sys.exit(77)


def ball_mesh(path, refine, gap):
    need_gmsh()
    subprocess.run([sys.executable, os.path.join(REPO, "scripts", "make_ball_mesh.py"), path, "--refine", str(refine),
                    "--gap", str(gap)], check=True, stdout=subprocess.DEVNULL)


def cube_mesh(path, cells=2, size=0.1):
    subprocess.run([sys.executable, os.path.join(REPO, "scripts", "make_cube_mesh.py"), path, "--cells", str(cells),
                    "--size", str(size), "--center"], check=True, stdout=subprocess.DEVNULL)


def compare_restart(terrace, a, b, np_, label, deck_text, note=""):
    """Restart in b from the checkpoint the straight run in a wrote (with a's thermo and trajectory,
    which a restart cuts back and continues; deck_text reads the checkpoint) and check that the
    thermo CSV, the final state, every dataset and attribute of the trajectory and the XDMF sidecar
    (listing every frame) are identical to the straight run's."""
    for f in ("restart.h5", "thermo.csv", "traj.h5"):
        shutil.copy(os.path.join(a, f), b)
    open(os.path.join(b, "run.nml"), "w").write(deck_text)
    r = run(terrace, b, np_)
    check(r.returncode == 0, f"{label}: restart from the checkpoint (exit {r.returncode}) {r.stderr.strip()[-300:]}")
    if r.returncode != 0:
        return
    lines = read(os.path.join(a, "thermo.csv")).count(b"\n") - 1
    check(read(os.path.join(a, "thermo.csv")) == read(os.path.join(b, "thermo.csv")),
          f"{label}: {lines} thermo lines of the restarted run byte-identical to the straight run's {note}")
    check(read(os.path.join(a, "final.txt")) == read(os.path.join(b, "final.txt")),
          f"{label}: final positions and velocities byte-identical")
    n = same_h5(os.path.join(a, "traj.h5"), os.path.join(b, "traj.h5"))
    check(isinstance(n, int), f"{label}: trajectory identical ({n} datasets, connectivity included)")
    xa, xb = read(os.path.join(a, "traj.xdmf")), read(os.path.join(b, "traj.xdmf"))
    frames = xa.count(b"<Time ")
    with h5py.File(os.path.join(a, "traj.h5"), "r") as f:
        nt = len(f["particles/all/position/time"])
    check(xa == xb and frames == nt, f"{label}: XDMF sidecar identical, listing all {frames} frames")
