#!/usr/bin/env python3
"""Frequency shift of the vibrational density of states with the integrator's step.

For every value of the integrator's step parameter the deck is run with Terrace (its &integrator
and &output groups are replaced: velocities written every --interval), then terrace-analyze computes
the VDOS with the same settings for every run, and this script measures, from the VDOS CSV:
  peak      the highest maximum in the band --band LO,HI (parabola through the top three points)
  centroid  int nu g / int g over the band (much less noisy than the peak)
  nu_rms    sqrt(int nu^2 g / int g) over the whole spectrum
The same analysis serves velocity Verlet (--style velocity_verlet, --values are dt) and energy
stepping (--style energy_stepping, --values are terrace_height, or target_mean_dt with
--key target_mean_dt); for energy stepping the mean event interval printed by the run is recorded
as the 'mean step', so both integrators can share one axis.

  python3 scripts/bench/vdos_shift.py run --deck input/cu_eam.nml --style velocity_verlet \
      --values 0.001,0.002,0.005,0.01,0.02 --interval 0.02 --run-time 20 --band 6,8.5 \
      --correlation-time 2 --skip 2 --out /tmp/vdos_shift/cu --label cu_verlet
  python3 scripts/bench/vdos_shift.py plot --tables A.csv B.csv --out doc/figures/x.png \
      [--reference-frequency 7.0]

Every run starts from the deck's initial state; --skip leaves its equilibration out of the analysis
(frames before that time); the deck's &run run_time is replaced by --run-time. Trajectories are
deleted after the analysis unless --keep.
"""
import argparse
import csv
import os
import re
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def replace_group(text, group, body):
    """Replace namelist group &group ... / (values hold no '/') by body, or append it."""
    pat = re.compile(r"&" + group + r"\b[^/]*/", re.IGNORECASE | re.DOTALL)
    if pat.search(text):
        return pat.sub(lambda m: body, text, count=1)
    return text + "\n" + body + "\n"


def set_run_time(text, run_time):
    m = re.search(r"&run\b[^/]*/", text, re.IGNORECASE | re.DOTALL)
    grp = m.group(0)
    grp2 = re.sub(r"(run_time|n_steps)\s*=\s*[^,/\s]+", f"run_time={run_time}", grp, flags=re.IGNORECASE)
    return text.replace(grp, grp2)


def vdos_metrics(path, band):
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    nu, g = data[:, 0], data[:, 1]
    m = (nu >= band[0]) & (nu <= band[1])
    i = np.flatnonzero(m)[np.argmax(g[m])]
    y0, y1, y2 = g[i - 1], g[i], g[i + 1]
    denom = y0 - 2 * y1 + y2
    shift = 0.5 * (y0 - y2) / denom if denom != 0 else 0.0
    peak = nu[i] + shift * (nu[1] - nu[0])
    centroid = (nu[m] * g[m]).sum() / g[m].sum()
    nu_rms = np.sqrt((nu ** 2 * g).sum() / g.sum())
    return peak, centroid, nu_rms


def cmd_run(a):
    terrace = os.path.abspath(a.terrace)
    analyze = os.path.abspath(a.analyze)
    deck_dir = os.path.dirname(os.path.abspath(a.deck))
    os.makedirs(a.out, exist_ok=True)
    text = "".join(ln for ln in open(a.deck) if not ln.lstrip().startswith("!"))   # comments may hold '&'
    text = set_run_time(text, a.run_time)
    key = a.key or ("dt" if a.style == "velocity_verlet" else "terrace_height")
    band = [float(v) for v in a.band.split(",")]
    rows = []
    for value in a.values.split(","):
        tag = f"{a.label}_{key}_{value}"
        traj = os.path.join(os.path.abspath(a.out), tag + ".h5")
        deck = replace_group(text, "integrator", f"&integrator style='{a.style}', {key}={value} /")
        deck = replace_group(deck, "output", f"&output thermo_interval={a.interval * 50}, "
                             f"thermo_file='{tag}.csv', trajectory_file='{traj}', "
                             f"trajectory_interval={a.interval}, trajectory_fields='velocity', overwrite=.true. /")
        nml = os.path.join(deck_dir, f".vdos_shift_{tag}.nml")   # atoms files are relative to the deck
        with open(nml, "w") as f:
            f.write(deck)
        t0 = time.time()
        launcher = ["mpirun", "--oversubscribe", "-np", str(a.np)] if a.np > 1 else []
        p = subprocess.run(launcher + [terrace, nml], cwd=deck_dir, capture_output=True, text=True)
        wall = time.time() - t0
        os.remove(nml)
        for f in (os.path.join(deck_dir, tag + ".csv"),):
            if os.path.exists(f):
                os.replace(f, os.path.join(a.out, tag + ".csv"))
        with open(os.path.join(a.out, tag + ".log"), "w") as f:
            f.write(p.stdout + p.stderr)
        if p.returncode != 0:
            sys.exit(f"vdos_shift: the run {tag} failed (log: {a.out}/{tag}.log)")
        mean_step = float(value)
        m = re.search(r"Mean event interval:\s*([0-9.Ee+-]+)", p.stdout)
        if m:
            mean_step = float(m.group(1))
        loop = re.search(r"Loop time:\s*([0-9.]+)", p.stdout)
        prefix = os.path.join(a.out, tag)
        q = subprocess.run(launcher + [analyze, f"--trajectory_file={traj}", "--compute=vdos",
                                       f"--correlation_time={a.correlation_time}", f"--output_prefix={prefix}",
                                       f"--first_frame={int(round(a.skip / a.interval)) + 1}"],
                           capture_output=True, text=True)
        if q.returncode != 0:
            sys.exit(f"vdos_shift: terrace-analyze failed on {traj}: {q.stderr.strip()}")
        if not a.keep:
            os.remove(traj)
        peak, centroid, nu_rms = vdos_metrics(prefix + "_vdos.csv", band)
        thermo = np.loadtxt(os.path.join(a.out, tag + ".csv"), delimiter=",", skiprows=1, usecols=(1, 2), ndmin=2)
        temp = thermo[thermo[:, 0] >= a.skip, 1].mean()          # over the analysed part
        rows.append(dict(style=a.style, key=key, value=float(value), mean_step=mean_step, peak=peak,
                         centroid=centroid, nu_rms=nu_rms, temperature=temp,
                         loop_time=float(loop.group(1)) if loop else wall))
        print(f"{a.style:16s} {key}={value:10s} mean step {mean_step:.5g}  T {temp:7.2f}  peak {peak:.4f}  "
              f"centroid {centroid:.4f}  nu_rms {nu_rms:.4f}  loop {rows[-1]['loop_time']:.1f} s", flush=True)
    table = os.path.join(a.out, f"vdos_shift_{a.label}.csv")
    with open(table, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {table}")


def cmd_plot(a):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for path in a.tables:
        rows = list(csv.DictReader(open(path)))
        step = np.array([float(r["mean_step"]) for r in rows]) * 1000    # fs
        cen = np.array([float(r["centroid"]) for r in rows])
        pk = np.array([float(r["peak"]) for r in rows])
        label = os.path.basename(path).replace("vdos_shift_", "").replace(".csv", "")
        order = np.argsort(step)
        ref = cen[order][0]
        axes[0].plot(step[order], 100 * (cen[order] / ref - 1), "o-", label=label + " (band centroid)")
        axes[0].plot(step[order], 100 * (pk[order] / pk[order][0] - 1), "x:", label=label + " (peak)")
        axes[1].plot(step[order], cen[order], "o-", label=label)
    if a.reference_frequency:
        dt = np.linspace(1e-3, axes[0].get_xlim()[1], 200)
        w = 2 * np.pi * a.reference_frequency
        with np.errstate(invalid="ignore"):
            shift = (2 / (dt * 1e-3)) * np.arcsin(w * dt * 1e-3 / 2) / w - 1
        axes[0].plot(dt, 100 * shift, "k--", lw=0.8,
                     label=f"Verlet, harmonic {a.reference_frequency} THz: (2/dt) asin(w dt/2)")
    axes[0].set_xlabel("time step / mean event interval (fs)")
    axes[0].set_ylabel("frequency shift against the smallest step (%)")
    axes[0].legend(fontsize=7)
    axes[1].set_xlabel("time step / mean event interval (fs)")
    axes[1].set_ylabel("band centroid (THz)")
    axes[1].legend(fontsize=7)
    if a.title:
        fig.suptitle(a.title)
    fig.tight_layout()
    fig.savefig(a.out, dpi=120)
    print(f"wrote {a.out}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--deck", required=True)
    r.add_argument("--style", required=True, choices=["velocity_verlet", "energy_stepping"])
    r.add_argument("--key", help="dt (Verlet), terrace_height or target_mean_dt (energy stepping)")
    r.add_argument("--values", required=True, help="comma-separated values of the key")
    r.add_argument("--interval", type=float, required=True, help="time between velocity frames")
    r.add_argument("--run-time", type=float, required=True)
    r.add_argument("--band", required=True, help="LO,HI frequency band of the peak")
    r.add_argument("--correlation-time", type=float, required=True)
    r.add_argument("--skip", type=float, default=0.0, help="equilibration time left out of the analysis")
    r.add_argument("--out", required=True)
    r.add_argument("--label", required=True)
    r.add_argument("--np", type=int, default=1)
    r.add_argument("--keep", action="store_true", help="keep the trajectories")
    r.add_argument("--terrace", default=os.path.join(ROOT, "build", "terrace"))
    r.add_argument("--analyze", default=os.path.join(ROOT, "build", "terrace-analyze"))
    p = sub.add_parser("plot")
    p.add_argument("--tables", nargs="+", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--reference-frequency", type=float)
    p.add_argument("--title")
    a = ap.parse_args()
    cmd_run(a) if a.cmd == "run" else cmd_plot(a)


if __name__ == "__main__":
    main()
