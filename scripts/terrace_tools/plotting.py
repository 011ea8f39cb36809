"""The figures' plotting style: matplotlib without a display (Agg), the same fonts, grid and
resolution in every figure of doc/figures (RC, applied on import), one colour and marker per method,
log axes labelled at 2 and 5 times the powers of ten when they span less than two decades, and
save(fig, path) to write a figure the same way everywhere.

    from terrace_tools.plotting import plt, save
    fig, ax = plt.subplots()
    ...
    save(fig, "doc/figures/name.png")
"""
import math
import os

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402,F401  (re-exported: from terrace_tools.plotting import plt)
import matplotlib.ticker  # noqa: E402

STYLE = {"terrace-vv": dict(color="tab:blue", marker="o", label="Terrace velocity Verlet (dt)"),
         "terrace-es": dict(color="tab:red", marker="s", label="Terrace energy stepping (h)"),
         "lammps-vv": dict(color="tab:green", marker="^", label="LAMMPS velocity Verlet (dt)"),
         "reference": dict(color="0.4", marker="*", label="reference (Terrace Verlet, fine dt)")}
METHODS = ["terrace-vv", "terrace-es", "lammps-vv"]
DPI = 110
# every figure: light grid, legends and titles a little smaller than the axis labels
RC = {"axes.grid": True, "axes.axisbelow": True, "grid.alpha": 0.3, "grid.linewidth": 0.6, "axes.titlesize": 10, "axes.labelsize": 10,
      "legend.fontsize": 8, "legend.framealpha": 0.85, "xtick.labelsize": 9, "ytick.labelsize": 9,
      "savefig.dpi": DPI, "figure.dpi": DPI}
plt.rcParams.update(RC)


def save(fig, path, dpi=DPI, tight=True, **kwargs):
    """Lay the figure out (tight_layout unless tight=False), write it to path (PNG at DPI unless
    told), close it; returns path. kwargs go to savefig (bbox_inches='tight', ...)."""
    if tight:
        fig.tight_layout()
    d = os.path.dirname(path)
    if d:
        os.makedirs(d, exist_ok=True)
    fig.savefig(path, dpi=dpi, **kwargs)
    plt.close(fig)
    return path


def log_tick_labels(ax):
    """Log axes spanning less than about two decades get labels at 2 and 5 times the powers of
    ten too (else such an axis may show a single label); wider ones keep only the powers."""
    for axis, lim in ((ax.xaxis, ax.get_xlim()), (ax.yaxis, ax.get_ylim())):
        if axis.get_scale() != "log":
            continue
        lo, hi = min(lim), max(lim)
        if lo > 0 and math.log10(hi / lo) < 2.0:
            axis.set_minor_locator(matplotlib.ticker.LogLocator(base=10, subs=(2.0, 5.0)))
            axis.set_minor_formatter(matplotlib.ticker.LogFormatterSciNotation(labelOnlyBase=False,
                                                                               minor_thresholds=(3, 3)))
        else:
            axis.set_minor_formatter(matplotlib.ticker.NullFormatter())
