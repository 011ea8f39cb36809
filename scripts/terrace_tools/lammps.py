"""LAMMPS files the benchmarks and tests use: the log (thermo rows, loop time, timing breakdown),
text dumps, and data files (written for LAMMPS, read by Terrace's &system read_data)."""
import re

import numpy as np

_THERMO_NAMES = {"Step": "step", "Time": "time", "Temp": "temp", "PotEng": "pe", "KinEng": "ke", "TotEng": "etotal",
                 "Press": "press", "v_px": "px", "v_py": "py", "v_pz": "pz", "v_lx": "lx", "v_ly": "ly",
                 "v_lz": "lz"}


def parse_log(text):
    """A LAMMPS log's last run: {'loop', 'n', 'output', 'pair', 'neigh', 'comm', 'other' (and their
    slowest rank's, 'pair_max', ...), 'error',
    'thermo': {column: array}} (thermo columns renamed as Terrace's CSV: pe, ke, etotal, ...)."""
    r = {"loop": None, "output": 0.0, "error": "", "thermo": {}}
    m = re.findall(r"^Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps", text, re.M)
    if m:
        r["loop"] = float(m[-1][0])
        r["nprocs"] = int(m[-1][1])
        r["n"] = int(m[-1][2])
    for key in ("pair", "neigh", "comm", "output", "modify", "other"):
        r[key] = 0.0
    for line in text.splitlines():           # the timing breakdown: 'Pair | min | avg | max | ...'
        cols = [c.strip() for c in line.split("|")]
        if len(cols) >= 3 and cols[0].lower() in ("pair", "neigh", "comm", "output", "modify", "other"):
            try:
                r[cols[0].lower()] = float(cols[2])
                # the slowest rank's ('max'; a one-rank breakdown may leave min and max empty)
                r[cols[0].lower() + "_max"] = float(cols[3]) if len(cols) > 3 and cols[3] else float(cols[2])
            except ValueError:
                pass
    m = re.search(r"^(ERROR.*)$", text, re.M)
    if m:
        r["error"] = m.group(1).strip()
    lines = text.splitlines()
    start = None
    for i, line in enumerate(lines):
        if line.split()[:1] == ["Step"]:
            start = i
    if start is not None:
        head = lines[start].split()
        rows = []
        for line in lines[start + 1:]:
            w = line.split()
            if len(w) != len(head):
                break
            try:
                rows.append([float(x) for x in w])
            except ValueError:
                break
        if rows:
            a = np.array(rows)
            r["thermo"] = {_THERMO_NAMES.get(h, h): a[:, i] for i, h in enumerate(head)}
    return r


def read_log(path):
    with open(path) as f:
        return parse_log(f.read())


def read_dump(path, dt=1.0, columns=None):
    """A text dump (ITEM: TIMESTEP / NUMBER OF ATOMS / BOX BOUNDS / ATOMS ...), rows sorted by id:
    (times (F,) = step * dt, {column: array (F, N)}). columns: the ATOMS columns to keep (all)."""
    times, frames = [], []
    names = None
    with open(path) as f:
        lines = f.read().splitlines()
    i = 0
    while i < len(lines):
        if lines[i].startswith("ITEM: TIMESTEP"):
            step = int(lines[i + 1])
            n = int(lines[i + 3])
            j = i + 4
            while not lines[j].startswith("ITEM: ATOMS"):
                j += 1
            names = lines[j].split()[2:]
            a = np.array([[float(w) for w in lines[k].split()] for k in range(j + 1, j + 1 + n)]).reshape(n, len(names))
            if "id" in names:
                a = a[np.argsort(a[:, names.index("id")])]
            times.append(step * dt)
            frames.append(a)
            i = j + 1 + n
        else:
            i += 1
    if not frames:
        return np.array([]), {}
    stack = np.array(frames)
    keep = names if columns is None else columns
    return np.array(times), {c: stack[:, :, names.index(c)] for c in keep}


def write_data(path, types, x, v, lo, hi, masses, title="terrace start state"):
    """A data file in the atomic style (id type x y z), with masses and velocities."""
    n = len(types)
    with open(path, "w") as f:
        f.write("%s\n\n%d atoms\n%d atom types\n\n" % (title, n, len(masses)))
        for d, ax in enumerate("xyz"):
            f.write("%.17g %.17g %slo %shi\n" % (lo[d], hi[d], ax, ax))
        f.write("\nMasses\n\n")
        for t, m in enumerate(masses, 1):
            f.write("%d %.17g\n" % (t, m))
        f.write("\nAtoms # atomic\n\n")
        for i in range(n):
            f.write("%d %d %.17g %.17g %.17g\n" % (i + 1, types[i], *x[i]))
        f.write("\nVelocities\n\n")
        for i in range(n):
            f.write("%d %.17g %.17g %.17g\n" % (i + 1, *v[i]))
