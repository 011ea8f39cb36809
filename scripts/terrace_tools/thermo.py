"""Terrace's thermo CSV (&output thermo_file; doc/input.md, "Thermo CSV"): a header line of
column names, then one row per sample (comment lines starting with '#' are skipped)."""
import os

import numpy as np


def read(path):
    """The thermo CSV as {column: float array}, in the file's column order ({} for a missing or
    empty file)."""
    if not os.path.exists(path) or os.path.getsize(path) == 0:
        return {}
    with open(path) as f:
        lines = [ln for ln in f if ln.strip() and not ln.startswith("#")]
    if not lines:
        return {}
    head = [h.strip() for h in lines[0].strip().split(",")]
    rows = [[float(w) for w in ln.strip().split(",")] for ln in lines[1:]]
    a = np.array(rows, dtype=float).reshape(len(rows), len(head))
    return {k: a[:, i] for i, k in enumerate(head)}


def energy_drift(t, natoms, column="etotal"):
    """(last - first) / (natoms (t_last - t_first)) of a column: the run log's energy drift per atom
    per time unit (with a thermostat the run log uses econserve)."""
    e, time = t[column], t["time"]
    return (e[-1] - e[0]) / (natoms * (time[-1] - time[0]))


def momentum_change(t):
    """|P_last - P_first| from the px, py, pz columns."""
    p = np.stack([t["px"], t["py"], t["pz"]], axis=1)
    return float(np.linalg.norm(p[-1] - p[0]))
