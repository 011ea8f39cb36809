#!/usr/bin/python3
"""Validation of Terrace's thermostats on Rahman's liquid argon (864 atoms, 1.374 g/cm^3, 94.4 K).

usage: scripts/thermostat_validation.py [--quick] [--out DIR] [--cases a,b,...] [--np N]
                                        [--terrace BIN] [--analyze BIN] [--markdown FILE]
                                        [--length PS] [--seed N] [--phase PS]

One equilibration run (fcc start at 184 K, which melts, held at 94.4 K by Langevin) writes the
liquid; every case then starts from it and runs `--length` ps (1000; --quick 200), thermo every
0.1 ps, a frame every 1 ps:
  vv_langevin, vv_csvr, vv_nose_hoover, vv_andersen   velocity Verlet at 10 fs, damping 1 ps
  es_andersen                                         energy stepping (h = 2e-3 eV), Andersen 1 ps
  es_csvr                                             energy stepping (h = 2e-3 eV), CSVR 1 ps every 0.1 ps
  es_andersen_global                                  energy stepping (h = 2e-3 eV), every velocity every 1 ps
  vv_nve                                              velocity Verlet, no thermostat (drift reference)
and the script reports, after dropping the first 20 ps:
  1. canonical kinetic energy: K is Gamma(Nf/2, k_B T); a Kolmogorov-Smirnov test (scipy) on
     samples 2 tau_int apart (tau_int, the integrated autocorrelation time of K, by the initial
     positive sequence), and T from the mean (2<K>/(Nf k_B)) and from the width (sqrt(2 var K /
     Nf)/k_B), each with a 20-block standard error, against the target;
  2. configurational agreement: <V>, <P> and the first peak of g(r) (position and height, by
     terrace-analyze over ten blocks of frames, --rdf-blocks) with block standard errors, and their largest
     difference between cases in combined standard errors;
  3. the drift of econserve (etotal - ecouple; e_terraced - ecouple for energy stepping) per atom
     per ns, a least-squares slope.
With --phase P (e.g. 1.0, the interval of es_andersen_global) it also prints, for each case, the
means of T, V and P over the samples at each phase of period P (time mod P, one row per thermo
interval) and each phase's difference from the mean over all phases, paired over 20 blocks: a
thermostat acting at the multiples of P that leaves the canonical distribution invariant gives the
same means at every phase (stationarity), so a phase dependence beyond the errors would show a
bias of its action or of its timing.
Numbers in doc/thermostats.md come from this script (its --markdown output).
"""
import argparse
import math
import os
import subprocess
import sys

import numpy as np
from scipy import stats

here = os.path.dirname(os.path.abspath(__file__))
repo = os.path.dirname(here)
KB = 8.617343e-5          # eV/K, as Terrace's metal units
T_TARGET = 94.4
N_ATOMS = 864
BOX = 34.6809019          # 6 fcc cells of 5.780150 A

COMMON = """&potential style='lj', epsilon=0.0103408116, sigma=3.4, cutoff=8.5, shift=.true. /
&neighbor skin=1.0 /
"""
CASES = {
    "vv_langevin": ("velocity_verlet", "style='langevin', temperature=94.4, damping=1.0"),
    "vv_csvr": ("velocity_verlet", "style='csvr', temperature=94.4, damping=1.0"),
    "vv_nose_hoover": ("velocity_verlet", "style='nose_hoover', temperature=94.4, damping=1.0, chain_length=3"),
    "vv_andersen": ("velocity_verlet", "style='andersen', temperature=94.4, damping=1.0"),
    "es_andersen": ("energy_stepping", "style='andersen', temperature=94.4, damping=1.0"),
    "es_csvr": ("energy_stepping", "style='csvr', temperature=94.4, damping=1.0, interval=0.1"),
    "es_andersen_global": ("energy_stepping", "style='andersen', temperature=94.4, damping=1.0, interval=1.0"),
    "vv_nve": ("velocity_verlet", None),
}


def run(cmd, cwd, log):
    with open(os.path.join(cwd, log), "w") as f:
        r = subprocess.run(cmd, cwd=cwd, stdout=f, stderr=subprocess.STDOUT)
    if r.returncode != 0:
        sys.exit(f"FAIL: {' '.join(cmd)} in {cwd} (see {log})")


def terrace_cmd(args, deck):
    if args.np > 1:
        return ["mpirun", "--oversubscribe", "-np", str(args.np), args.terrace, deck]
    return [args.terrace, deck]


def equilibrate(args):
    d = os.path.join(args.out, "equilibrate")
    os.makedirs(d, exist_ok=True)
    if os.path.exists(os.path.join(d, "eq.atoms")):
        return os.path.join(d, "eq.atoms")
    deck = f"""&run units='metal', dimension=3, run_time=50.0, seed=1964 /
&system lattice='fcc', lattice_constant=5.780150, cells=6,6,6, periodic=.true.,.true.,.true.,
        mass=39.948, temperature=184.0 /
{COMMON}&integrator style='velocity_verlet', dt=0.01 /
&thermostat style='langevin', temperature=94.4, damping=0.5 /
&output thermo_interval=1.0, thermo_file='thermo.csv', final_atoms_file='eq.atoms' /
"""
    open(os.path.join(d, "eq.nml"), "w").write(deck)
    run(terrace_cmd(args, "eq.nml"), d, "terrace.log")
    return os.path.join(d, "eq.atoms")


def production(args, name, eq):
    integrator, thermostat = CASES[name]
    d = os.path.join(args.out, name)
    os.makedirs(d, exist_ok=True)
    if os.path.exists(os.path.join(d, "done")):
        return d
    integ = "style='velocity_verlet', dt=0.01" if integrator == "velocity_verlet" else \
        "style='energy_stepping', terrace_height=2.0e-3"
    ts = f"&thermostat {thermostat} /\n" if thermostat else ""
    deck = f"""&run units='metal', dimension=3, run_time={args.length}, seed={args.seed} /
&system atoms_file='{eq}', box_lo=0.0,0.0,0.0, box_hi={BOX},{BOX},{BOX},
        periodic=.true.,.true.,.true., mass=39.948 /
{COMMON}&integrator {integ} /
{ts}&output thermo_interval=0.1, thermo_file='thermo.csv', trajectory_file='traj.h5', trajectory_interval=1.0,
        trajectory_fields='position', overwrite=.true. /
"""
    open(os.path.join(d, "run.nml"), "w").write(deck)
    run(terrace_cmd(args, "run.nml"), d, "terrace.log")
    open(os.path.join(d, "done"), "w").write("")
    return d


def tau_int(x):
    """Integrated autocorrelation time (in samples) by Geyer's initial positive sequence."""
    x = np.asarray(x) - np.mean(x)
    n = len(x)
    f = np.fft.rfft(x, 2 * n)
    acf = np.fft.irfft(f * np.conj(f))[:n] / (x.var() * n)
    tau = 0.5
    for k in range(1, n // 2, 2):
        pair = acf[k] + acf[k + 1] if k + 1 < n else acf[k]
        if pair <= 0:
            break
        tau += pair
    return max(tau, 0.5)


def blocks(x, nb=20):
    m = len(x) // nb
    return np.array([np.mean(x[i * m:(i + 1) * m]) for i in range(nb)])


def block_stat(x, fn, nb=20):
    m = len(x) // nb
    v = np.array([fn(x[i * m:(i + 1) * m]) for i in range(nb)])
    return fn(x), v.std(ddof=1) / math.sqrt(nb)


def rdf_peak(args, d, nframes, nblocks):
    """First peak of g(r) (position, height) over blocks of frames: mean and standard error."""
    per = nframes // nblocks
    pos, hei = [], []
    for b in range(nblocks):
        first = 21 + b * per           # frames 1..21 are the first 20 ps
        last = first + per - 1
        prefix = f"rdf_b{b}"
        cmd = [args.analyze, "--trajectory_file=traj.h5", "--compute=rdf", f"--output_prefix={prefix}",
               f"--first_frame={first}", f"--last_frame={last}", "--rdf_bins=400"]
        run(cmd, d, f"{prefix}.log")
        g = np.genfromtxt(os.path.join(d, f"{prefix}_rdf.csv"), delimiter=",", names=True)
        r = g[g.dtype.names[0]]; y = g[g.dtype.names[1]]
        i = int(np.argmax(y))
        a, bb, c = np.polyfit(r[i - 2:i + 3], y[i - 2:i + 3], 2)   # parabola through the top
        pos.append(-bb / (2 * a)); hei.append(c - bb * bb / (4 * a))
    pos, hei = np.array(pos), np.array(hei)
    return (pos.mean(), pos.std(ddof=1) / math.sqrt(nblocks)), (hei.mean(), hei.std(ddof=1) / math.sqrt(nblocks))


def analyse(args, name, d):
    th = np.genfromtxt(os.path.join(d, "thermo.csv"), delimiter=",", names=True)
    keep = th["time"] >= 20.0
    t = th["time"][keep]; ke = th["ke"][keep]; pe = th["pe"][keep]; press = th["press"][keep]
    nf = float(np.median(2 * th["ke"][1:] / (KB * th["temp"][1:])))
    res = {"name": name, "samples": len(ke), "nf": nf, "length": th["time"][-1]}
    tau = tau_int(ke)
    stride = max(1, int(math.ceil(2 * tau)))
    sub = ke[::stride]
    kt = KB * T_TARGET
    ks = stats.kstest(sub, stats.gamma(a=nf / 2, scale=kt).cdf)
    res.update(tau_ps=tau * (t[1] - t[0]), n_ks=len(sub), ks_d=ks.statistic, ks_p=ks.pvalue)
    res["t_mean"] = block_stat(ke, lambda x: 2 * np.mean(x) / (nf * KB))
    res["t_width"] = block_stat(ke, lambda x: math.sqrt(2 * np.var(x, ddof=1) / nf) / KB)
    res["pe"] = block_stat(pe, np.mean)
    res["press"] = block_stat(press, np.mean)
    if "econserve" in th.dtype.names:
        ec = th["econserve"] if "e_terraced" not in th.dtype.names else th["e_terraced"] - th["ecouple"]
    elif "e_terraced" in th.dtype.names:
        ec = th["e_terraced"]
    else:
        ec = th["etotal"]
    slope = np.polyfit(th["time"], ec, 1)[0]              # eV/ps
    res["drift"] = slope / N_ATOMS * 1000.0                 # eV/atom/ns
    nframes = int(round((t[-1] - 20.0) / 1.0))
    res["rdf_pos"], res["rdf_height"] = rdf_peak(args, d, nframes, args.rdf_blocks)
    return res


def phase_table(name, d, period, nb=20):
    """Means of T, V and P at each phase (time mod period), and each phase's difference from the mean
    over all phases, paired block by block (nb blocks of whole periods): its standard error is
    that of the difference, far smaller than that of the mean."""
    th = np.genfromtxt(os.path.join(d, "thermo.csv"), delimiter=",", names=True)
    keep = th["time"] >= 20.0
    t = th["time"][keep]
    dt = float(np.median(np.diff(t)))
    nphase = int(round(period / dt))
    ph = np.rint((t % period) / dt).astype(int) % nphase
    blk = np.minimum((np.arange(len(t)) * nb) // len(t), nb - 1)
    out = [f"{name}: means by phase of period {period} ps (time mod {period}); differences from the mean over "
           f"all phases paired over {nb} blocks",
           "| phase (ps) | samples | T (K) | T − mean (K) | ⟨V⟩ (eV) | V − mean (eV) | ⟨P⟩ (bar) | P − mean (bar) |",
           "|---|---|---|---|---|---|---|---|"]
    worst = {}
    for k in range(nphase):
        sel = ph == k
        row = [f"| {k * dt:.2f} | {int(sel.sum())}"]
        for key, f1, f2 in (("temp", "{:.3f}", "{:+.3f} ± {:.3f}"), ("pe", "{:.4f}", "{:+.4f} ± {:.4f}"),
                            ("press", "{:.1f}", "{:+.1f} ± {:.1f}")):
            x = th[key][keep]
            diff = np.array([x[(blk == j) & sel].mean() - x[blk == j].mean() for j in range(nb)])
            m, e = diff.mean(), diff.std(ddof=1) / math.sqrt(nb)
            worst[key] = max(worst.get(key, 0.0), abs(m) / e)
            row.append(f1.format(x[sel].mean()))
            row.append(f2.format(m, e))
        out.append(" | ".join(row) + " |")
    out.append("- largest |phase − mean| in standard errors: " +
               ", ".join(f"{k} {v:.2f}" for k, v in worst.items()) + f" (over {nphase} phases)")
    return "\n".join(out)


def markdown(results):
    out = []
    out.append("| case | run (ps) | N_f | samples (KS) | tau_K (ps) | KS D | KS p | T from ⟨K⟩ (K) | "
               "T from width of K (K) | econserve drift (eV/atom/ns) |")
    out.append("|---|---|---|---|---|---|---|---|---|---|")
    for r in results:
        z1 = (r["t_mean"][0] - T_TARGET) / r["t_mean"][1]
        z2 = (r["t_width"][0] - T_TARGET) / r["t_width"][1]
        ks = f"{r['ks_d']:.4f} | {r['ks_p']:.3f}" if r["name"] != "vv_nve" else "- | -"
        out.append(f"| {r['name']} | {r['length']:.0f} | {r['nf']:.0f} | {r['n_ks']} | {r['tau_ps']:.3f} | {ks} | "
                   f"{r['t_mean'][0]:.3f} ± {r['t_mean'][1]:.3f} ({z1:+.1f} SE) | "
                   f"{r['t_width'][0]:.2f} ± {r['t_width'][1]:.2f} ({z2:+.1f} SE) | {r['drift']:.3e} |")
    out.append("")
    out.append("| case | ⟨V⟩ (eV) | ⟨P⟩ (bar) | g(r) peak r (A) | g(r) peak height |")
    out.append("|---|---|---|---|---|")
    for r in results:
        out.append(f"| {r['name']} | {r['pe'][0]:.4f} ± {r['pe'][1]:.4f} | {r['press'][0]:.1f} ± {r['press'][1]:.1f} | "
                   f"{r['rdf_pos'][0]:.4f} ± {r['rdf_pos'][1]:.4f} | {r['rdf_height'][0]:.4f} ± {r['rdf_height'][1]:.4f} |")
    out.append("")
    thermo = [r for r in results if r["name"] != "vv_nve"]
    for key, label in (("pe", "⟨V⟩"), ("press", "⟨P⟩"), ("rdf_pos", "g(r) peak position"),
                       ("rdf_height", "g(r) peak height")):
        worst = (0.0, "", "")
        for i, a in enumerate(thermo):
            for b in thermo[i + 1:]:
                z = abs(a[key][0] - b[key][0]) / math.hypot(a[key][1], b[key][1])
                if z > worst[0]:
                    worst = (z, a["name"], b["name"])
        out.append(f"- {label}: largest difference between thermostatted cases {worst[0]:.2f} combined SE "
                   f"({worst[1]} vs {worst[2]})")
    return "\n".join(out)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="200 ps per case instead of 1000")
    p.add_argument("--length", type=float, default=None, help="ps per case")
    p.add_argument("--out", default="thermostat_validation")
    p.add_argument("--seed", type=int, default=2014,
                   help="&run seed of the production runs (the thermostats' random numbers; default 2014)")
    p.add_argument("--cases", default=",".join(CASES))
    p.add_argument("--np", type=int, default=1)
    p.add_argument("--terrace", default=os.path.join(repo, "build", "terrace"))
    p.add_argument("--analyze", default=os.path.join(repo, "build", "terrace-analyze"))
    p.add_argument("--markdown", default=None, help="also write the tables to this file")
    p.add_argument("--rdf-blocks", type=int, default=10,
                   help="blocks of frames for the g(r) peak's standard error (default 10: at 1000 ps, 98-frame "
                        "blocks; the error of a 10-block error is itself about 24 %%)")
    p.add_argument("--phase", type=float, default=0.0,
                   help="also tabulate T, V and P by phase of this period (ps), e.g. a scheduled thermostat's interval")
    args = p.parse_args()
    if args.length is None:
        args.length = 200.0 if args.quick else 1000.0
    args.terrace = os.path.abspath(args.terrace); args.analyze = os.path.abspath(args.analyze)
    args.out = os.path.abspath(args.out)
    os.makedirs(args.out, exist_ok=True)
    os.environ.update(OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    eq = equilibrate(args)
    results = []
    for name in args.cases.split(","):
        d = production(args, name, eq)
        results.append(analyse(args, name, d))
        print(f"{name}: done", flush=True)
    text = (f"Rahman argon, 864 atoms, target {T_TARGET} K, first 20 ps of each case dropped, "
            f"`scripts/thermostat_validation.py{' --quick' if args.quick else ''}`, seed {args.seed}\n\n" + markdown(results))
    if args.phase > 0:
        for name in args.cases.split(","):
            text += "\n\n" + phase_table(name, os.path.join(args.out, name), args.phase)
    print(text)
    if args.markdown:
        open(args.markdown, "w").write(text + "\n")


if __name__ == "__main__":
    main()
