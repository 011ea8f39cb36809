#!/usr/bin/env python3
"""The XDMF sidecar of a mesh trajectory, read by meshio.

A short run of the talk's spinning cube (input/cube_spin_es.nml: 2,969 nodes, 12,288 tetrahedra,
energy stepping, cut to 4 ms with a frame every millisecond) on 2 ranks writes cube.h5 and its
sidecar cube.xdmf. meshio (PyPI, installed into $TERRACE_VENV or ~/.cache/terrace-venv) reads
the sidecar: its temporal collection holds one grid per H5MD frame at the frame's time, each with
2,969 nodes and the 12,288 tetrahedra of the input mesh (as meshio reads cube.msh itself); the
positions each grid's Geometry selects equal the H5MD frame's exactly, and the cube has turned
and deformed between the first and last frames. meshio 5.3 does not implement XDMF HyperSlab
DataItems (each frame's Geometry is one): the test resolves the slab (start, stride, count from
the XML item) over the array meshio's own DataItem reader returns; Topology, Time and the HDF5
item come from meshio unchanged. SKIPPED (exit 77) when meshio cannot be installed (offline).

usage: check_mesh_xdmf.py TERRACE OUTDIR
"""
import os
import re
import shutil
import subprocess
import sys

here = os.path.dirname(os.path.abspath(__file__))
repo = os.path.dirname(os.path.dirname(here))
venv = os.environ.get("TERRACE_VENV", os.path.expanduser("~/.cache/terrace-venv"))
spec = os.environ.get("TERRACE_MESHIO", "meshio==5.3.5")
vpy = os.path.join(venv, "bin", "python")


def ensure_meshio(out):
    """Re-run this script under the virtual environment's python, with meshio installed there."""
    if os.path.realpath(sys.prefix) == os.path.realpath(venv):
        return
    if subprocess.run([vpy, "-c", "import meshio, h5py, numpy"], capture_output=True).returncode != 0:
        made = False
        if not os.path.exists(vpy):
            made = True
            r = subprocess.run(["/usr/bin/python3", "-m", "venv", "--system-site-packages", venv], capture_output=True,
                               text=True)
            if r.returncode != 0:
                print("SKIPPED: /usr/bin/python3 cannot create a virtual environment (python3-venv): "
                      + r.stderr.strip()[-200:])
                sys.exit(77)
        print(f"installing {spec} into {venv} (once; later runs reuse it)")
        log = os.path.join(out, "pip.log")
        with open(log, "w") as f:
            r = subprocess.run([os.path.join(venv, "bin", "pip"), "install", "--disable-pip-version-check", "--timeout",
                                "20", "--retries", "1", "-q", spec], stdout=f, stderr=subprocess.STDOUT, timeout=900)
        if r.returncode != 0:
            if made:
                shutil.rmtree(venv, ignore_errors=True)
            tail = open(log).read().strip().splitlines()[-3:]
            print(f"SKIPPED: could not install {spec} from PyPI (no network?); {log} ends with:")
            print("\n".join(tail))
            sys.exit(77)
    sys.stdout.flush()
    os.execv(vpy, [vpy] + sys.argv)


def main():
    terrace, out = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
    if os.path.realpath(sys.prefix) != os.path.realpath(venv):
        shutil.rmtree(out, ignore_errors=True)
        os.makedirs(out)
    ensure_meshio(out)
    import h5py
    import meshio
    import numpy as np
    from meshio.xdmf.time_series import TimeSeriesReader

    failed = []

    def check(ok, what):
        print(("ok   " if ok else "FAIL ") + what)
        if not ok:
            failed.append(what)

    print(f"meshio {meshio.__version__}, h5py {h5py.__version__}")
    subprocess.run(["/usr/bin/python3", os.path.join(repo, "scripts", "make_cube_mesh.py"), os.path.join(out, "cube.msh"),
                    "--size", "0.1", "--center"], check=True, stdout=subprocess.DEVNULL)
    deck = open(os.path.join(repo, "input", "cube_spin_es.nml")).read()
    deck, n1 = re.subn(r"run_time=[0-9.eE+-]+", "run_time=0.004", deck)
    deck, n2 = re.subn(r"thermo_file='[^']*'", "thermo_file='cube.csv', trajectory_file='cube.h5', "
                       "trajectory_interval=0.001", deck)
    assert n1 == 1 and n2 == 1, "input/cube_spin_es.nml changed: run_time or thermo_file not found"
    open(os.path.join(out, "cube.nml"), "w").write(deck)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    r = subprocess.run(["mpirun", "--oversubscribe", "-np", "2", terrace, "cube.nml"], cwd=out, env=env,
                       capture_output=True, text=True, timeout=300)
    check(r.returncode == 0, f"cube_spin_es, 4 ms, 2 ranks, trajectory (exit {r.returncode}) {r.stderr.strip()[-300:]}")
    if failed:
        sys.exit(1)

    class SlabReader(TimeSeriesReader):
        """meshio's reader plus XDMF HyperSlab items (start, stride, count over meshio's own array)."""

        def _read_data_item(self, item):
            if item.get("ItemType") != "HyperSlab":
                return super()._read_data_item(item)
            sel, src = list(item)
            start, stride, count = super()._read_data_item(sel).astype(int).reshape(3, -1)
            a = super()._read_data_item(src)
            idx = tuple(slice(b, b + s * c, s) for b, s, c in zip(start, stride, count))
            dims = [int(d) for d in item.get("Dimensions").split()]
            return a[idx].reshape(dims)

    h5 = h5py.File(os.path.join(out, "cube.h5"), "r")
    pos = h5["particles/all/position/value"]
    times = h5["particles/all/position/time"][:]
    ids = h5["particles/all/id"][:]
    conn = h5["connectivity/tetrahedra"]
    check(conn.attrs["particles_group"] in (b"all", "all"), "H5MD /connectivity/tetrahedra: particles_group = 'all'")
    check(np.array_equal(ids, np.arange(1, len(ids) + 1)), "particles/all/id = 1..N: row = id - 1")

    ref = meshio.read(os.path.join(out, "cube.msh"))
    tets_msh = ref.cells_dict["tetra"]                  # 0-based indices into meshio's point order
    tags = np.arange(1, len(ref.points) + 1)            # make_cube_mesh.py writes tags 1..N in order

    with SlabReader(os.path.join(out, "cube.xdmf")) as rd:
        pts, blocks = rd.read_points_cells()                           # the first grid's (frame 0)
        topo = [c for c in rd.mesh_grid if c.tag == "Topology"][0]
        t_xdmf = [rd.read_data(k)[0] for k in range(rd.num_steps)]
        nsteps = rd.num_steps
        worst = 0.0
        for k, grid in enumerate(rd.collection):
            geo = [c for c in grid if c.tag == "Geometry"][0]
            p = rd._read_data_item(list(geo)[0])
            worst = max(worst, float(np.max(np.abs(p - pos[k]))))
            if k == 0:
                p0 = p
    cells = blocks[0].data
    check(len(blocks) == 1 and blocks[0].type == "tetra" and cells.shape == (12288, 4) and
          topo.get("TopologyType") == "Tetrahedron",
          f"meshio: {len(blocks)} cell block '{blocks[0].type}' of {cells.shape[0]} cells (12288 tetrahedra)")
    check(pts.shape == (2969, 3), f"meshio: {pts.shape[0]} nodes (2969)")
    check(np.array_equal(pts, pos[0]), "meshio: the nodes of the first grid are H5MD frame 0's positions")
    check(np.array_equal(cells, conn[:] - 1), "meshio: the tetrahedra are /connectivity/tetrahedra's node ids - 1")
    check(np.array_equal(cells, tags[tets_msh] - 1),
          "meshio: the tetrahedra are those of cube.msh (as meshio reads the mesh file), in its order")
    check(nsteps == len(times) == 5, f"meshio: {nsteps} grids in the temporal collection, {len(times)} H5MD frames")
    check(np.array_equal(np.array(t_xdmf), times), f"meshio: grid times equal the H5MD frame times {list(times)}")
    check(worst == 0.0, f"every frame's positions (XDMF HyperSlab) equal the H5MD frame's: max |diff| = {worst:g} m")
    moved = float(np.max(np.linalg.norm(p - p0, axis=1)))
    check(moved > 1e-3, f"the cube turns between the first and last frames: max node displacement {moved * 1e3:.1f} mm")
    r0 = np.linalg.norm(p0[:, :2], axis=1)
    r1 = np.linalg.norm(p[:, :2], axis=1)
    check(np.max(r1 - r0) > 0, f"and stretches: the largest radial growth is {np.max(r1 - r0) * 1e6:.1f} um")
    if failed:
        print(f"{len(failed)} check(s) failed")
        sys.exit(1)
    print("PASS")


if __name__ == "__main__":
    main()
