#!/usr/bin/python3
"""Temperature ramp on Rahman's argon crystal (input/argon_ramp.nml): does T follow the target, and
where does the crystal melt?

usage: scripts/thermostat_ramp.py [--terrace BIN] [--out DIR] [--png FILE] [--csv EXISTING_THERMO]

Runs the deck (unless --csv names its thermo file), then reports
  - T - T_target(t) in 10 windows along the ramp: the mean (the lag of a thermostat of damping
    tau behind a target rising at rate r is about r tau) and the standard deviation, against the
    canonical fluctuation of the instantaneous temperature, T_target sqrt(2 / Nf);
  - the melting point: the window of the steepest rise of the potential energy;
and draws T and T_target against time, and V against T_target (doc/figures/thermostat_ramp.png).
"""
import argparse
import math
import os
import re
import subprocess
import sys

import numpy as np

from terrace_tools import thermo

here = os.path.dirname(os.path.abspath(__file__))
repo = os.path.dirname(here)
KB = 8.617343e-5


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--terrace", default=os.path.join(repo, "build", "terrace"))
    p.add_argument("--out", default="thermostat_ramp")
    p.add_argument("--png", default=os.path.join(repo, "doc", "figures", "thermostat_ramp.png"))
    p.add_argument("--csv", default=None)
    args = p.parse_args()
    deck = os.path.join(repo, "input", "argon_ramp.nml")
    text = open(deck).read()
    t0 = float(re.search(r"temperature=([0-9.]+), temperature_end", text).group(1))
    t1 = float(re.search(r"temperature_end=([0-9.]+)", text).group(1))
    run_time = float(re.search(r"run_time=([0-9.]+)", text).group(1))
    tau = float(re.search(r"&thermostat.*damping=([0-9.]+)", text).group(1))
    if args.csv is None:
        os.makedirs(args.out, exist_ok=True)
        with open(os.path.join(args.out, "terrace.log"), "w") as log:
            r = subprocess.run([os.path.abspath(args.terrace), deck], cwd=args.out, stdout=log, stderr=subprocess.STDOUT)
        if r.returncode != 0:
            sys.exit("FAIL: the ramp run failed (see " + os.path.join(args.out, "terrace.log") + ")")
        args.csv = os.path.join(args.out, "argon_ramp.csv")
    d = thermo.read(args.csv)
    t = d["time"]; temp = d["temp"]; pe = d["pe"]
    nf = float(np.median(2 * d["ke"][1:] / (KB * temp[1:])))
    target = t0 + (t1 - t0) * np.clip(t / run_time, 0, 1)
    rate = (t1 - t0) / run_time
    print(f"ramp {t0:g} -> {t1:g} K over {run_time:g} ps (rate {rate:.3f} K/ps), damping {tau:g} ps, Nf = {nf:.0f}")
    print(f"expected lag ~ rate x damping = {rate * tau:.3f} K; canonical sd of T = T sqrt(2/Nf) "
          f"= {math.sqrt(2 / nf):.4f} T")
    print("| window (ps) | T_target (K) | mean T - T_target (K) | sd of T (K) | canonical sd (K) | ⟨V⟩ (eV) |")
    print("|---|---|---|---|---|---|")
    nw = 10
    edges = np.linspace(0, run_time, nw + 1)
    mean_pe = []
    worst = 0.0
    for a, b in zip(edges[:-1], edges[1:]):
        k = (t > max(a, 5.0)) & (t <= b)      # the first 5 ps: equipartition of the lattice start
        dev = temp[k] - target[k]
        sd_can = np.mean(target[k]) * math.sqrt(2 / nf)
        # the mean deviation against its standard error (samples 0.1 ps apart, correlated over ~tau/2)
        neff = max(1.0, k.sum() * 0.1 / max(tau, 0.1))
        z = abs(dev.mean() - (-rate * tau)) / (sd_can / math.sqrt(neff))
        worst = max(worst, z)
        mean_pe.append(pe[k].mean())
        print(f"| {a:.0f}-{b:.0f} | {np.mean(target[k]):.1f} | {dev.mean():+.3f} | {dev.std():.3f} | {sd_can:.3f} | "
              f"{pe[k].mean():.3f} |")
    # melting: steepest rise of V over 5 ps windows
    w = int(round(5.0 / (t[1] - t[0])))
    vs = np.convolve(pe, np.ones(w) / w, mode="valid")
    ts = np.convolve(target, np.ones(w) / w, mode="valid")
    jump = np.diff(vs[::w])
    i = int(np.argmax(jump))
    print(f"steepest rise of V: {jump[i]:.3f} eV between T_target = {ts[::w][i]:.1f} and {ts[::w][i + 1]:.1f} K "
          f"(melting of the expanded crystal)")
    print(f"largest |mean deviation - expected lag| in standard errors: {worst:.2f}")
    try:
        from terrace_tools.plotting import plt, save
    except ImportError:
        print("matplotlib missing: no figure")
        return
    fig, ax = plt.subplots(1, 2, figsize=(11, 4))
    ax[0].plot(t, temp, lw=0.5, label="T (instantaneous)")
    ax[0].plot(t, target, "k--", lw=1, label="target")
    ax[0].fill_between(t, target * (1 - math.sqrt(2 / nf)), target * (1 + math.sqrt(2 / nf)), color="0.8",
                       label="target ± canonical sd")
    ax[0].set_xlabel("time (ps)"); ax[0].set_ylabel("T (K)"); ax[0].legend(); ax[0].set_title("CSVR ramp, 864 argon atoms")
    ax[1].plot(target, pe / 864.0, lw=0.5)
    ax[1].set_xlabel("target T (K)"); ax[1].set_ylabel("V per atom (eV)"); ax[1].set_title("potential energy: melting")
    save(fig, args.png)
    print("figure: " + args.png)


if __name__ == "__main__":
    main()
