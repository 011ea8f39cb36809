"""The figures' plotting style: matplotlib without a display (Agg), one colour and marker per
method, log axes labelled at 2 and 5 times the powers of ten when they span less than two decades."""
import math

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
