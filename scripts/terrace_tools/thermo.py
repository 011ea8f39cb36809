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


def plot(path, columns, out, units=None):
    """One panel per column of a thermo CSV against time, saved as a PNG (`out`). `units`: a label
    per column, e.g. {'temp': 'K'}. Returns the figure's path."""
    from terrace_tools.plotting import plt, DPI
    t = read(path)
    if not t:
        raise SystemExit(f"{path}: no thermo rows")
    missing = [c for c in columns if c not in t]
    if missing:
        raise SystemExit(f"{path}: no column {', '.join(missing)} (columns: {', '.join(t)})")
    fig, axes = plt.subplots(len(columns), 1, sharex=True, figsize=(6.4, 1.9 * len(columns) + 0.6), squeeze=False)
    for ax, c in zip(axes[:, 0], columns):
        ax.plot(t["time"], t[c], color="tab:blue")
        ax.set_ylabel(c + (f" ({units[c]})" if units and c in units else ""))
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel("time" + (f" ({units['time']})" if units and "time" in units else ""))
    fig.suptitle(os.path.basename(path))
    fig.tight_layout()
    fig.savefig(out, dpi=DPI)
    plt.close(fig)
    return out


def main(argv=None):
    """python3 -m terrace_tools.thermo plot THERMO.csv COL[,COL...] OUT.png"""
    import sys
    argv = sys.argv[1:] if argv is None else argv
    if len(argv) != 4 or argv[0] != "plot":
        raise SystemExit("usage: python3 -m terrace_tools.thermo plot THERMO.csv COL[,COL...] OUT.png")
    print(plot(argv[1], [c for c in argv[2].split(",") if c], argv[3]))


if __name__ == "__main__":
    main()
