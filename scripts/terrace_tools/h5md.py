"""H5MD trajectories (Terrace's &output trajectory_file and other writers'), with h5py, and a
one-call MDAnalysis Universe.

    frames = h5md.read("traj.h5")            # time, unwrapped positions, velocities, box edges
    u = h5md.universe("traj.h5")             # MDAnalysis Universe: types, masses, every frame

Terrace writes beside a 3-D trajectory its topology for MDAnalysis, traj.topology.data (a LAMMPS
data file); universe() uses it when it is there, else it builds the topology from the file's own
particles/<group>/species and mass. Units: MDAnalysis converts a file's units when every quantity
in it has a unit attribute MDAnalysis knows (metal runs without forces); otherwise (reduced LJ
units, metal forces in eV/Angstrom) the values are kept as written (convert_units=False), which for
metal positions, velocities and times are MDAnalysis's own units (Angstrom, ps) anyway.
"""
import os

import numpy as np

TOPOLOGY_SUFFIX = ".topology.data"


def topology_path(trajectory):
    """The topology Terrace writes beside a trajectory: traj.h5 -> traj.topology.data."""
    for ext in (".h5", ".h5md", ".hdf5"):
        if trajectory.endswith(ext) and len(os.path.basename(trajectory)) > len(ext):
            return trajectory[: -len(ext)] + TOPOLOGY_SUFFIX
    return trajectory + TOPOLOGY_SUFFIX


def particles_group(f):
    """The first group under /particles (Terrace's is 'all')."""
    return f["particles"][list(f["particles"])[0]]


def _text(a):
    return a.decode() if isinstance(a, bytes) else str(a)


def read(path, unwrap=True):
    """Frames of a trajectory: dict with time (F,), step (F,), x (F, N, D) (unwrapped with the
    images when the file has them and unwrap is true, each frame with its own box), v (F, N, D) or
    None, f (F, N, D) or None, edges (D,) of the first frame, frame_edges (F, D) (each frame's box:
    a barostat's run changes it), boundary (list), species (N,), mass (N,), id (N,)."""
    import h5py
    with h5py.File(path, "r") as h:
        p = particles_group(h)
        out = {"time": np.asarray(p["position/time"][()], float), "step": np.asarray(p["position/step"][()])}
        x = np.asarray(p["position/value"][()], float)
        frame_edges = box_series(p, out["step"], x.shape[2])
        edges = frame_edges[0]
        bnd = [_text(b) for b in p["box"].attrs.get("boundary", [])]
        if unwrap and "image" in p:
            per = np.array([b.startswith("periodic") for b in bnd] + [False] * 3)[: x.shape[2]]
            x = x + p["image/value"][()] * (frame_edges * per)[:, None, :]
        out.update(x=x, edges=edges, frame_edges=frame_edges, boundary=bnd)
        for key, name in (("v", "velocity"), ("f", "force")):
            out[key] = np.asarray(p[f"{name}/value"][()], float) if name in p else None
        for name in ("species", "mass", "id"):
            out[name] = p[name][()] if name in p else None
    return out


def connectivity(path, name="tetrahedra"):
    """A mesh trajectory's /connectivity/<name> (the tetrahedra of a mesh scene) as particle ids,
    (M, T) int; None when the file has none."""
    import h5py
    with h5py.File(path, "r") as h:
        key = "connectivity/" + name
        return np.asarray(h[key][()]) if key in h else None


def box_series(p, steps, dimension):
    """Each frame's box edges (F, D) from particles/<group>/box/edges: a fixed dataset ([D] or a
    diagonal [D][D]) repeated, a series of one row per frame, or a series of another length with its
    own step matched to each frame by step (the last box not after it), as Terrace's reader does."""
    import h5py
    e = p["box/edges"]
    nf = len(steps)
    if not isinstance(e, h5py.Group):
        v = np.asarray(e[()], float)
        v = np.diag(v) if v.ndim == 2 else v.reshape(-1)
        return np.tile(v[:dimension], (nf, 1))
    v = np.asarray(e["value"][()], float).reshape(-1, dimension)
    if len(v) == 1:
        return np.tile(v[0], (nf, 1))
    if len(v) == nf:
        return v
    bsteps = np.asarray(e["step"][()])
    rows = np.maximum(np.searchsorted(bsteps, np.asarray(steps), side="right") - 1, 0)
    return v[rows]


def units(path):
    """{quantity: unit attribute} of a trajectory ({} for reduced units)."""
    import h5py
    u = {}
    with h5py.File(path, "r") as h:
        p = particles_group(h)
        for name in ("position", "velocity", "force"):
            if name in p and "unit" in p[name]["value"].attrs:
                u[name] = _text(p[name]["value"].attrs["unit"])
        if "position" in p and "unit" in p["position/time"].attrs:
            u["time"] = _text(p["position/time"].attrs["unit"])
        if "mass" in p and "unit" in p["mass"].attrs:
            u["mass"] = _text(p["mass"].attrs["unit"])
    return u


# what MDAnalysis's H5MD reader converts (its unit names for these quantities)
_MDA_KNOWS = {"position": {"Angstrom", "nm", "pm", "fm", "A", "angstrom"},
              "velocity": {"Angstrom ps-1", "A ps-1", "nm ps-1", "Angstrom fs-1", "nm ns-1", "pm ps-1", "m s-1"},
              "force": {"kJ mol-1 Angstrom-1", "kJ mol-1 nm-1", "Newton", "N", "J m-1", "kcal mol-1 Angstrom-1"},
              "time": {"ps", "fs", "ns", "s", "second", "sec"}}


def mdanalysis_converts(path):
    """Does MDAnalysis accept convert_units=True for this file (every quantity has a unit it knows)?"""
    import h5py
    u = units(path)
    with h5py.File(path, "r") as h:
        p = particles_group(h)
        present = [n for n in ("position", "velocity", "force") if n in p]
    needed = present + ["time"]
    return all(u.get(n) in _MDA_KNOWS[n] for n in needed)


def universe(path, topology=None, convert_units=None):
    """An MDAnalysis Universe of a trajectory in one call: the topology Terrace wrote beside it
    (or the one given), else one built from the file's species (as types) and masses; every frame;
    units converted when MDAnalysis knows them all (convert_units=None), else kept as written."""
    import warnings

    import MDAnalysis as mda
    if convert_units is None:
        convert_units = mdanalysis_converts(path)
    if topology is None and os.path.exists(topology_path(path)):
        topology = topology_path(path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if topology is not None:
            return mda.Universe(topology, path, format="H5MD", convert_units=convert_units)
        import h5py
        with h5py.File(path, "r") as h:
            p = particles_group(h)
            n = p["position/value"].shape[1] if "position" in p else p["velocity/value"].shape[1]
            species = p["species"][()] if "species" in p else None
            mass = p["mass"][()] if "mass" in p else None
        u = mda.Universe.empty(n, trajectory=False)
        if species is not None:
            u.add_TopologyAttr("types", [str(int(s)) for s in species])
        if mass is not None:
            u.add_TopologyAttr("masses", np.asarray(mass, float))
        u.load_new(path, format="H5MD", convert_units=convert_units)
        return u


def write_synthetic(path, dimension, positions=None, velocities=None, images=None, times=None, edges=None,
               boundary=None, edges_series=False, scalar_time=None, species=None, mass=None, vl_strings=True):
    """An H5MD file as another writer (h5py) lays it out: positions/velocities (frames, N, D);
    times a dataset, or scalar_time = (dt, offset) as a scalar time with an offset attribute;
    edges fixed or, with edges_series, a time-dependent element box/edges/value."""
    import h5py
    with h5py.File(path, "w") as f:
        h = f.create_group("h5md")
        h.attrs["version"] = np.array([1, 1], dtype=np.int32)
        f.create_group("h5md/creator").attrs["name"] = "terrace-analyze test"
        p = f.create_group("particles/all")
        nframes = None
        for name, data in (("position", positions), ("velocity", velocities), ("image", images)):
            if data is None:
                continue
            g = p.create_group(name)
            g.create_dataset("value", data=data)
            nframes = data.shape[0]
            if scalar_time is not None:
                dset = g.create_dataset("time", data=float(scalar_time[0]))
                dset.attrs["offset"] = float(scalar_time[1])
                g.create_dataset("step", data=1)
            elif times is not None:
                g.create_dataset("time", data=np.asarray(times, dtype=float))
                g.create_dataset("step", data=np.arange(len(times), dtype=np.int64))
            if name in ("position", "velocity"):
                g["value"].attrs["unit"] = "Ang" if name == "position" else "Ang ps-1"
                if "time" in g:
                    g["time"].attrs["unit"] = "ps"
        b = p.create_group("box")
        b.attrs["dimension"] = np.int32(dimension)
        if boundary is None:
            boundary = ["periodic"] * dimension
        if vl_strings:
            b.attrs["boundary"] = np.array(boundary, dtype=h5py.string_dtype())
        else:
            b.attrs["boundary"] = np.array([s.encode() for s in boundary], dtype="S8")
        if edges is not None:
            if edges_series:
                e = b.create_group("edges")
                e.create_dataset("value", data=np.tile(np.asarray(edges, float), (nframes, 1)))
                e.create_dataset("step", data=np.arange(nframes, dtype=np.int64))
                if times is not None:
                    e.create_dataset("time", data=np.asarray(times, float))
            else:
                b.create_dataset("edges", data=np.asarray(edges, float))
        if species is not None:
            p.create_dataset("species", data=np.asarray(species, np.int32))
        if mass is not None:
            p.create_dataset("mass", data=np.asarray(mass, float))
