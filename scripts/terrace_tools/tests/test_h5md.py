"""The H5MD reader and the topology beside a trajectory against h5py and the engine's text outputs."""
import os

import numpy as np
import pytest

from terrace_tools import atoms, h5md, summary

h5py = pytest.importorskip("h5py")

LIQUID = """&run units='lj', dimension=3, n_steps=40, seed=4242 /
&system lattice='fcc', density=0.8442, cells=4,4,4, periodic=.true.,.true.,.true., mass=1.0, temperature=1.44 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&output thermo_every=10, thermo_file='liquid.csv', trajectory_file='liquid.h5', trajectory_every=10,
        trajectory_fields='position velocity force image', final_atoms_file='liquid_final.atoms',
        forces_file='liquid_forces.txt' /
"""

FLAT = """&run units='metal', dimension=2, n_steps=20, seed=1 /
&system atoms_file='{repo}/input/argon_frozen_2d.atoms', periodic=.false.,.false., mass=39.951 /
&potential style='lj', epsilon=0.010323577, sigma=3.41, cutoff=0.0 /
&integrator style='velocity_verlet', dt=0.01 /
&output thermo_every=10, thermo_file='flat.csv', trajectory_file='flat.h5', trajectory_every=10 /
"""


def read_topology(path):
    """Masses by type and the Atoms rows (id, mol, type, x, y, z) of a LAMMPS data file."""
    lines = open(path).read().splitlines()
    i = lines.index("Masses")
    masses = {}
    k = i + 2
    while lines[k].strip():
        t, m = lines[k].split()
        masses[int(t)] = float(m)
        k += 1
    j = next(n for n, ln in enumerate(lines) if ln.startswith("Atoms"))
    rows = np.array([[float(w) for w in ln.split()] for ln in lines[j + 2:] if ln.strip()])
    return masses, rows


@pytest.mark.parametrize("np_", [1, 2])
def test_read_equals_h5py_and_text_outputs(run, np_):
    run("liquid", LIQUID, np_=np_)
    fr = h5md.read(run.path("liquid.h5"), unwrap=False)
    with h5py.File(run.path("liquid.h5"), "r") as f:
        p = f["particles/all"]
        assert np.array_equal(fr["x"], p["position/value"][()])
        assert np.array_equal(fr["v"], p["velocity/value"][()])
        assert np.array_equal(fr["f"], p["force/value"][()])
        assert np.array_equal(fr["time"], p["position/time"][()])
        assert np.array_equal(fr["species"], p["species"][()])
    assert fr["boundary"] == ["periodic"] * 3
    ids, forces = atoms.read_forces(run.path("liquid_forces.txt"))
    assert np.array_equal(ids, fr["id"]) and np.array_equal(forces, fr["f"][0])
    types, x, v = atoms.read(run.path("liquid_final.atoms"))
    assert np.array_equal(v, fr["v"][-1])
    d = x - fr["x"][-1]
    d -= fr["edges"] * np.round(d / fr["edges"])
    assert np.abs(d).max() < 1e-12 * fr["edges"].max()
    # unwrapped positions differ from the wrapped ones by whole box lengths
    un = h5md.read(run.path("liquid.h5"))["x"]
    k = (un - fr["x"]) / fr["edges"]
    assert np.allclose(k, np.round(k), atol=1e-9)


def test_topology_beside_trajectory(run):
    run("liquid", LIQUID, np_=2)
    top = run.path("liquid.topology.data")
    assert h5md.topology_path(run.path("liquid.h5")) == top
    assert summary.get(run.path("liquid.summary.json"), "outputs/topology_file") == "liquid.topology.data"
    masses, rows = read_topology(top)
    with h5py.File(run.path("liquid.h5"), "r") as f:
        p = f["particles/all"]
        assert np.array_equal(rows[:, 0].astype(np.int64), p["id"][()])
        assert np.array_equal(rows[:, 2].astype(int), p["species"][()])
        assert np.array_equal(np.array([masses[int(t)] for t in rows[:, 2]]), p["mass"][()])
        # positions of the first frame (the data file wraps nothing: the frame's positions as stored)
        assert np.allclose(rows[:, 3:6], p["position/value"][0], rtol=1e-15, atol=1e-15)
        edges = p["box/edges/value"][0]
    lo_hi = [ln.split()[:2] for ln in open(top) if ln.rstrip().endswith(("xhi", "yhi", "zhi"))]
    assert np.allclose([float(b) - float(a) for a, b in lo_hi], edges, rtol=1e-15)


def test_no_topology_for_2d(run):
    from .conftest import REPO
    run("flat", FLAT.format(repo=REPO))
    assert os.path.exists(run.path("flat.h5"))
    assert not os.path.exists(run.path("flat.topology.data"))
    assert "topology_file" not in summary.read(run.path("flat.summary.json"))["outputs"]


def test_units_and_conversion_verdict(run):
    run("liquid", LIQUID)
    assert h5md.units(run.path("liquid.h5")) == {}
    assert not h5md.mdanalysis_converts(run.path("liquid.h5"))


def test_write_synthetic_roundtrip(tmp_path):
    x = np.random.default_rng(1).random((3, 5, 3))
    path = str(tmp_path / "s.h5")
    h5md.write_synthetic(path, 3, positions=x, velocities=x, times=[0.0, 1.0, 2.0], edges=[2.0, 2.0, 2.0],
                         species=[1, 1, 2, 2, 1], mass=[1.0, 1.0, 2.0, 2.0, 1.0])
    fr = h5md.read(path)
    assert np.array_equal(fr["x"], x) and np.array_equal(fr["time"], [0.0, 1.0, 2.0])
    assert list(fr["species"]) == [1, 1, 2, 2, 1]
