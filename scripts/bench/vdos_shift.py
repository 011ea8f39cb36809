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

  PYTHONPATH=scripts python3 scripts/bench/vdos_shift.py run --deck input/cu_eam.nml --style velocity_verlet \
      --values 0.001,0.002,0.005,0.01,0.02 --interval 0.02 --run-time 20 --band 6,8.5 \
      --correlation-time 2 --skip 2 --out /tmp/vdos_shift/cu --label cu_verlet
  PYTHONPATH=scripts python3 scripts/bench/vdos_shift.py plot --tables A.csv B.csv --out doc/figures/x.png \
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

from terrace_tools import analysis, summary, thermo

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


def set_seed(text, seed):
    m = re.search(r"&run\b[^/]*/", text, re.IGNORECASE | re.DOTALL)
    grp = m.group(0)
    if re.search(r"\bseed\s*=", grp, re.IGNORECASE):
        grp2 = re.sub(r"\bseed\s*=\s*[^,/\s]+", f"seed={seed}", grp, flags=re.IGNORECASE)
    else:
        grp2 = grp[:-1].rstrip() + f", seed={seed} /"
    return text.replace(grp, grp2)


def vdos_metrics(path, band):
    data = analysis.array(path)
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
    if a.seed is not None:
        text = set_seed(text, a.seed)
    key = a.key or ("dt" if a.style == "velocity_verlet" else "terrace_height")
    band = [float(v) for v in a.band.split(",")]
    rows = []
    for value in a.values.split(","):
        tag = f"{a.label}_{key}_{value}"
        traj = os.path.join(os.path.abspath(a.out), tag + ".h5")
        deck = replace_group(text, "integrator", f"&integrator style='{a.style}', {key}={value} /")
        deck = replace_group(deck, "output", f"&output thermo_interval={a.thermo_interval or a.interval * 50}, "
                             f"thermo_file='{tag}.csv', trajectory_file='{traj}', "
                             f"trajectory_interval={a.interval}, trajectory_fields='velocity', overwrite=.true., "
                             f"summary_file='{os.path.join(os.path.abspath(a.out), tag + '.summary.json')}' /")
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
        figures = summary.run_figures(os.path.join(a.out, tag + ".summary.json"))
        if figures.get("mean_dt") is not None:
            mean_step = figures["mean_dt"]
        loop = figures["loop"]
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
        thermo_path = os.path.join(a.out, tag + ".csv")
        th = thermo.read(thermo_path)
        kept = th["time"] >= a.skip                                # the analysed part
        temp = th["temp"][kept].mean()
        etot = th["etotal"][kept]                                  # K + V with the untruncated V
        de_rms = etot.std()
        de_max = np.abs(etot - etot[0]).max()
        refl = (th["reflections"][-1] / max(th["events"][-1], 1)
                if "reflections" in th else 0.0)
        rows.append(dict(style=a.style, key=key, value=float(value), mean_step=mean_step, peak=peak,
                         centroid=centroid, nu_rms=nu_rms, temperature=temp, de_rms=de_rms, de_max=de_max,
                         reflections=refl, loop_time=loop if loop is not None else wall))
        print(f"{a.style:16s} {key}={value:10s} mean step {mean_step:.5g}  T {temp:7.2f}  peak {peak:.4f}  "
              f"centroid {centroid:.4f}  nu_rms {nu_rms:.4f}  dE rms {de_rms:.3g} max {de_max:.3g}  "
              f"refl {100 * refl:.1f} %  loop {rows[-1]['loop_time']:.1f} s", flush=True)
    table = os.path.join(a.out, f"vdos_shift_{a.label}.csv")
    with open(table, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=list(rows[0].keys()))
        w.writeheader()
        w.writerows(rows)
    print(f"wrote {table}")


def load_tables(paths, average_seeds):
    """Read the sweep tables (rows sorted by the step parameter, dt or h: a seed whose trapped run
    has a shorter mean step than a smaller h's keeps its rows in line with the other seeds'). With
    average_seeds, tables whose labels differ only by a '_seed<N>' suffix are runs of the same sweep
    from other initial velocities: they are replaced by their mean, with the standard error of the
    mean in <key>_err."""
    tables = []
    for path in paths:
        rows = list(csv.DictReader(open(path)))
        col = lambda k: np.array([float(r[k]) for r in rows])
        order = np.argsort(col("value"), kind="stable")
        t = {k: col(k)[order] for k in rows[0] if k not in ("style", "key")}
        t["label"] = os.path.basename(path).replace("vdos_shift_", "").replace(".csv", "")
        t["style"] = rows[0]["style"]
        t["key"] = rows[0]["key"]
        tables.append(t)
    if not average_seeds:
        return tables
    groups = {}
    for t in tables:
        groups.setdefault(re.sub(r"_seed\d+$", "", t["label"]), []).append(t)
    out = []
    for label, ts in groups.items():
        n = min(len(t["mean_step"]) for t in ts)
        m = {k: np.mean([t[k][:n] for t in ts], axis=0) for k in ts[0] if k not in ("label", "style", "key")}
        for k in ("centroid", "peak"):
            m[k + "_err"] = (np.std([t[k][:n] for t in ts], axis=0, ddof=1) / np.sqrt(len(ts))
                             if len(ts) > 1 else np.zeros(n))
        m.update(label=f"{label} (mean of {len(ts)})", style=ts[0]["style"], key=ts[0]["key"], runs=len(ts))
        out.append(m)
    return out


def harmonic_shift(dt_ps, freq_thz):
    """Relative frequency error of Verlet for a harmonic mode: (2/dt) asin(w dt/2) / w - 1."""
    w = 2 * np.pi * freq_thz
    with np.errstate(invalid="ignore"):
        return (2 / dt_ps) * np.arcsin(w * dt_ps / 2) / w - 1


def cmd_summary(a):
    """Markdown table of the (seed-averaged) sweeps, shifts against the first table's smallest step."""
    tables = load_tables(a.tables, a.average_seeds)
    ref_c, ref_p = tables[0]["centroid"][0], tables[0]["peak"][0]
    pm = lambda v, e: f"{v:.4f} ± {e:.4f}" if e > 0 else f"{v:.4f}"
    print("| integrator | parameter | runs | mean step (fs) | T (K) | rms dE (eV) | reflections | peak (THz) | "
          "peak shift | band centroid (THz) | centroid shift | harmonic Verlet shift at the mean step |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for t in tables:
        for k in range(len(t["mean_step"])):
            ep = t.get("peak_err", np.zeros(99))[k]
            ec = t.get("centroid_err", np.zeros(99))[k]
            par = (f"dt = {1000 * t['value'][k]:g} fs" if t["style"] == "velocity_verlet"
                   else f"{t['key']} = {t['value'][k]:g}")
            hs = harmonic_shift(t["mean_step"][k], a.reference_frequency) if a.reference_frequency else np.nan
            print(f"| {t['style'].replace('_', ' ')} | {par} | {t.get('runs', 1)} | {1000 * t['mean_step'][k]:.3g} | "
                  f"{t['temperature'][k]:.1f} | {t['de_rms'][k]:.2g} | {100 * t['reflections'][k]:.1f} % | "
                  f"{pm(t['peak'][k], ep)} | {100 * (t['peak'][k] / ref_p - 1):+.2f} ± {100 * ep / ref_p:.2f} % | "
                  f"{pm(t['centroid'][k], ec)} | {100 * (t['centroid'][k] / ref_c - 1):+.2f} ± {100 * ec / ref_c:.2f} % | "
                  f"{100 * hs:+.3f} % |")


def cmd_thermo(a):
    """Per run (thermo CSVs written by 'run'): the extremes of the temperature averaged over blocks of
    --block time after --skip and, for energy stepping, the largest fraction of reflections among the
    events of one block (1.00: the state was trapped in reflections for that block)."""
    print("| run | T block min (K) | T block max (K) | largest reflection fraction in a block | at (time) |")
    print("|---|---|---|---|---|")
    for path in a.thermo:
        d = thermo.read(path)
        starts = np.arange(a.skip, d["time"][-1] - 1e-9, a.block)
        temps = [d["temp"][(d["time"] >= t0) & (d["time"] < t0 + a.block)].mean() for t0 in starts]
        line = f"| {os.path.basename(path)} | {min(temps):.1f} | {max(temps):.1f} |"
        if "reflections" in d:
            t1, r, e = d["time"][1:], np.diff(d["reflections"]), np.diff(d["events"])
            frac = [r[(t1 > t0) & (t1 <= t0 + a.block)].sum() / max(e[(t1 > t0) & (t1 <= t0 + a.block)].sum(), 1)
                    for t0 in starts]
            k = int(np.argmax(frac))
            line += f" {frac[k]:.2f} | {starts[k]:g}-{starts[k] + a.block:g} |"
        else:
            line += " – | – |"
        print(line)


def cmd_plot(a):
    import matplotlib
    from terrace_tools.plotting import plt, save
    tables = load_tables(a.tables, a.average_seeds)
    with_energy = all("de_rms" in t for t in tables)
    fig, axes = plt.subplots(1, 3 if with_energy else 2, figsize=(15 if with_energy else 10, 4.2))
    # reference: each table's smallest step, or (--common-reference) the first table's smallest step
    ref_cen = tables[0]["centroid"][0]
    ref_pk = tables[0]["peak"][0]
    for t in tables:
        step = t["mean_step"] * 1000                                  # fs
        rc, rp = (ref_cen, ref_pk) if a.common_reference else (t["centroid"][0], t["peak"][0])
        ec = t.get("centroid_err", np.zeros_like(step))
        ep = t.get("peak_err", np.zeros_like(step))
        line = axes[0].errorbar(step, 100 * (t["centroid"] / rc - 1), yerr=100 * ec / rc, fmt="o-", capsize=2,
                                label=t["label"] + " (band centroid)")[0]
        c = line.get_color()
        axes[0].errorbar(step, 100 * (t["peak"] / rp - 1), yerr=100 * ep / rp, fmt="x:", color=c, capsize=2,
                         label=t["label"] + " (peak)")
        axes[1].errorbar(step, t["centroid"], yerr=ec, fmt="o-", color=c, capsize=2, label=t["label"])
        if with_energy:
            axes[2].errorbar(t["de_rms"], 100 * (t["centroid"] / rc - 1), yerr=100 * ec / rc, fmt="o-", color=c,
                             capsize=2, label=t["label"] + " (band centroid)")
            axes[2].errorbar(t["de_rms"], 100 * (t["peak"] / rp - 1), yerr=100 * ep / rp, fmt="x:", color=c,
                             capsize=2, label=t["label"] + " (peak)")
    if a.reference_frequency:
        lo = min(t["mean_step"].min() for t in tables) * 1000
        hi = max(t["mean_step"].max() for t in tables) * 1000
        dt = np.geomspace(lo, hi, 200) if a.logx else np.linspace(1e-3, hi, 200)
        shift = harmonic_shift(dt * 1e-3, a.reference_frequency)
        axes[0].plot(dt, 100 * shift, "k--", lw=0.8,
                     label=f"Verlet, harmonic {a.reference_frequency} THz: (2/dt) asin(w dt/2)")
    for ax in axes[:2]:
        ax.set_xlabel("time step / mean event interval (fs)")
        if a.logx:
            ax.set_xscale("log")
    ref_text = "the first table's smallest step" if a.common_reference else "the smallest step"
    axes[0].set_ylabel(f"frequency shift against {ref_text} (%)")
    axes[0].legend(fontsize=7)
    axes[1].set_ylabel("band centroid (THz)")
    axes[1].legend(fontsize=7)
    if with_energy:
        axes[2].set_xscale("log")
        axes[2].set_xlabel("rms fluctuation of K + V over the analysed part (eV)")
        axes[2].set_ylabel(f"frequency shift against {ref_text} (%)")
        axes[2].legend(fontsize=7)
    if a.title:
        fig.suptitle(a.title)
    save(fig, a.out, dpi=120)
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
    r.add_argument("--seed", type=int, help="replaces the deck's &run seed (initial velocities)")
    r.add_argument("--thermo-interval", type=float,
                   help="thermo sampling (default 50 x --interval); the energy error columns use it")
    r.add_argument("--keep", action="store_true", help="keep the trajectories")
    r.add_argument("--terrace", default=os.path.join(ROOT, "build", "terrace"))
    r.add_argument("--analyze", default=os.path.join(ROOT, "build", "terrace-analyze"))
    p = sub.add_parser("plot")
    p.add_argument("--tables", nargs="+", required=True)
    p.add_argument("--out", required=True)
    p.add_argument("--reference-frequency", type=float)
    p.add_argument("--title")
    p.add_argument("--common-reference", action="store_true",
                   help="shifts against the first table's smallest step (default: each table's own)")
    p.add_argument("--logx", action="store_true", help="logarithmic step axis")
    p.add_argument("--average-seeds", action="store_true",
                   help="average tables whose labels differ only by a _seed<N> suffix (error bars: standard error)")
    q = sub.add_parser("summary")
    q.add_argument("--tables", nargs="+", required=True)
    q.add_argument("--reference-frequency", type=float)
    q.add_argument("--average-seeds", action="store_true")
    th = sub.add_parser("thermo")
    th.add_argument("thermo", nargs="+", help="thermo CSVs of the runs")
    th.add_argument("--skip", type=float, default=0.0)
    th.add_argument("--block", type=float, default=1.0)
    a = ap.parse_args()
    {"run": cmd_run, "plot": cmd_plot, "summary": cmd_summary, "thermo": cmd_thermo}[a.cmd](a)


if __name__ == "__main__":
    main()
