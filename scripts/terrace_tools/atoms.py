"""Terrace's atoms files (&system atoms_file, &output final_atoms_file; doc/input.md): '#'
comment lines, then 'type x y z [vx vy vz]' one line per atom, in id order."""
import numpy as np


def read(path):
    """(types (N,) int, x (N, 3), v (N, 3) or None)."""
    a = np.loadtxt(path, comments="#", ndmin=2)
    types = a[:, 0].astype(int)
    x = a[:, 1:4]
    v = a[:, 4:7] if a.shape[1] >= 7 else None
    return types, x, v


def write(path, types, x, v, comment=""):
    """An atoms file with velocities, every value to 17 significant digits."""
    with open(path, "w") as f:
        f.write("# %s\n# type x y z vx vy vz\n" % comment)
        for t, xi, vi in zip(types, x, v):
            f.write("%d %.17g %.17g %.17g %.17g %.17g %.17g\n" % (t, *xi, *vi))


def read_forces(path):
    """Terrace's forces file (&output forces_file): (ids (N,), forces (N, 3))."""
    a = np.loadtxt(path, comments="#", ndmin=2)
    return a[:, 0].astype(np.int64), a[:, 1:4]
