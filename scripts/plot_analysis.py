#!/usr/bin/env python3
"""PNG figures of terrace-analyze's CSV curves.

  python3 scripts/plot_analysis.py PREFIX [PREFIX ...] [--out DIR] [--xmax-vdos NU] [--xmax-vacf T]

For every PREFIX (the &analysis output_prefix), each of PREFIX_{vdos,vacf,rdf,msd,sq}.csv that
exists becomes PREFIX_<curve>.png (or DIR/<basename>_<curve>.png with --out). Several prefixes
are drawn on the same axes, one PNG per curve, named after the first prefix. Axis labels are the
CSV headers (name and unit). The MSD figure shows the block standard error as a band and the fitted
line of PREFIX_diffusion.csv. Uses matplotlib's Agg backend (no display needed).
"""
import argparse
import os

import matplotlib
import numpy as np

from terrace_tools import analysis  # noqa: E402
from terrace_tools.plotting import plt, save  # noqa: E402

CURVES = ["vdos", "vacf", "rdf", "msd", "sq"]


def read(path):
    """(column names, (rows, columns) array) of a terrace-analyze CSV (terrace_tools.analysis)."""
    t = analysis.read(path)
    return list(t), analysis.array(path)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("prefixes", nargs="+")
    ap.add_argument("--out", help="directory for the PNGs (default: next to the first prefix)")
    ap.add_argument("--xmax-vdos", type=float, help="upper frequency of the VDOS plot")
    ap.add_argument("--xmax-vacf", type=float, help="upper time of the VACF plot")
    a = ap.parse_args()
    first = a.prefixes[0]
    written = []
    for curve in CURVES:
        present = [p for p in a.prefixes if os.path.exists(f"{p}_{curve}.csv")]
        if not present:
            continue
        fig, ax = plt.subplots(figsize=(6, 4))
        for p in present:
            header, d = read(f"{p}_{curve}.csv")
            label = os.path.basename(p)
            ax.plot(d[:, 0], d[:, 1], lw=1.2, label=label)
            if curve == "msd" and d.shape[1] > 2:
                ax.fill_between(d[:, 0], d[:, 1] - d[:, 2], d[:, 1] + d[:, 2], alpha=0.3)
                if os.path.exists(f"{p}_diffusion.csv"):
                    _, dd = read(f"{p}_diffusion.csv")
                    D, lo, hi = dd[0, 0], dd[0, 3], dd[0, 4]
                    m = (d[:, 0] >= lo) & (d[:, 0] <= hi)
                    c = np.polyfit(d[m, 0], d[m, 1], 1)
                    ax.plot(d[m, 0], np.polyval(c, d[m, 0]), "k--", lw=0.8,
                            label=f"fit: D = {D:.4g} +- {dd[0, 1]:.2g}")
            ax.set_xlabel(header[0])
            ax.set_ylabel(header[1])
        if curve == "vdos" and a.xmax_vdos:
            ax.set_xlim(0, a.xmax_vdos)
        if curve == "vacf":
            ax.axhline(0, color="grey", lw=0.5)
            if a.xmax_vacf:
                ax.set_xlim(0, a.xmax_vacf)
        if curve == "rdf":
            ax.axhline(1, color="grey", lw=0.5)
        if len(present) > 1 or curve == "msd":
            ax.legend(fontsize=8)
        fig.tight_layout()
        base = os.path.basename(first)
        out = os.path.join(a.out, f"{base}_{curve}.png") if a.out else f"{first}_{curve}.png"
        if a.out:
            os.makedirs(a.out, exist_ok=True)
        save(fig, out, dpi=120, tight=False)
        written.append(out)
    if not written:
        raise SystemExit(f"plot_analysis: no CSV curves found for {a.prefixes}")
    print("wrote " + ", ".join(written))


if __name__ == "__main__":
    main()
