"""Shared helpers of the terrace-analyze regression tests: run the program (1 or more ranks),
read its CSV curves, and write small H5MD files with h5py in the layouts other writers use."""
import os
import subprocess
import sys

import h5py
import numpy as np

MPI_ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")


def run(binary, args, nprocs=1, cwd=None, check=True):
    """Run terrace-analyze with args; returns (exit status, stdout, stderr)."""
    cmd = [binary] + list(args)
    if nprocs > 1:
        cmd = ["mpirun", "--oversubscribe", "-np", str(nprocs)] + cmd
    p = subprocess.run(cmd, cwd=cwd, env=MPI_ENV, capture_output=True, text=True, timeout=300)
    if check and p.returncode != 0:
        sys.stdout.write(p.stdout)
        sys.stderr.write(p.stderr)
        raise SystemExit(f"FAIL: {' '.join(cmd)} exited {p.returncode}")
    return p.returncode, p.stdout, p.stderr


def read_csv(path):
    """(header names, columns as a 2-D array)."""
    with open(path) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return header, data


def write_h5md(path, dimension, positions=None, velocities=None, images=None, times=None, edges=None,
               boundary=None, edges_series=False, scalar_time=None, species=None, mass=None, vl_strings=True):
    """An H5MD file as another writer (h5py) lays it out: positions/velocities (frames, N, D);
    times a dataset, or scalar_time = (dt, offset) as a scalar time with an offset attribute;
    edges fixed or, with edges_series, a time-dependent element box/edges/value."""
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


class Checks:
    """Collects pass/fail lines; exit status 1 if any failed."""

    def __init__(self):
        self.failed = 0

    def check(self, ok, what):
        print(("ok    " if ok else "FAIL  ") + what)
        if not ok:
            self.failed += 1

    def finish(self):
        print(f"{'FAILED' if self.failed else 'PASSED'} ({self.failed} failed)")
        sys.exit(1 if self.failed else 0)
