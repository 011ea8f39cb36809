#!/usr/bin/env python3
"""Cost of energy stepping against velocity Verlet on the same scenes (one rank).

For each scene: run velocity Verlet and energy stepping from the same state, read the run logs,
and print events/s, mean event interval, ray evaluations per event, force passes per event, the
wall time of one event divided by the wall time of one Verlet step, and the simulated time per
wall second of both. Scenes: the seven-atom argon cluster (h = 16 K k_B, Verlet 10 fs), Rahman's
liquid argon (864 atoms, h = 2e-3 eV, Verlet 10 fs) and 32,000 LJ atoms (lj units, liquid at
T* ~ 0.75 from the LJ benchmark scene, h = 0.3, Verlet 0.005).

usage: es_cost.py [--terrace build/terrace]
"""
import argparse
import os
import platform
import re
import subprocess
import sys
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def run(terrace, work, name, text):
    path = os.path.join(work, name + ".nml")
    open(path, "w").write(text)
    p = subprocess.run([terrace, path], cwd=work, capture_output=True, text=True, timeout=1200)
    if p.returncode != 0:
        sys.exit(f"terrace failed on {name}:\n{p.stdout[-1500:]}\n{p.stderr[-1500:]}")
    out = p.stdout
    g = lambda pat, conv=float: conv(re.search(pat, out, re.M).group(1))
    loop = g(r"^Loop time: *([0-9.eE+-]+) s")
    n = g(r"^Loop time: .* for (\d+) ", int)
    res = {"loop": loop, "n": n}
    if "Events:" in out:
        res["evals"] = g(r"ray evaluations per event: *([0-9.]+)")
        res["passes"] = g(r"force passes per event: *([0-9.]+)")
        res["mean_dt"] = g(r"^Mean event interval: *([0-9.eE+-]+)")
        res["refl"] = g(r"^Events: \d+ \(\d+ up, \d+ down, (\d+) reflections\)", int) / max(n, 1)
    return res


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--terrace", default=os.path.join(REPO, "build", "terrace"))
    a = ap.parse_args()
    terrace = os.path.abspath(a.terrace)
    work = tempfile.mkdtemp(prefix="es_cost.")
    cpu = next((l.split(":", 1)[1].strip() for l in open("/proc/cpuinfo") if l.startswith("model name")), "?")
    commit = subprocess.run(["git", "-C", REPO, "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    print(f"machine : {cpu} ({os.cpu_count()} cores visible), {platform.platform()}")
    print(f"commit  : {commit};  binary {terrace};  work dir {work}\n")
    atoms = os.path.join(REPO, "input", "argon_frozen_2d.atoms")
    cluster = ("&run units='metal', dimension=2, {len}, seed=1 /\n"
               f"&system atoms_file='{atoms}', periodic=.false.,.false., mass=39.951 /\n"
               "&potential style='lj', epsilon=0.010323577, sigma=3.41, cutoff=0.0 /\n{integ}\n")
    # Rahman: equilibrate with Verlet (writes the start), then both integrators from it
    eq = open(os.path.join(REPO, "input", "argon_liquid.nml")).read()
    eq = eq.replace("thermo_file='argon_liquid.csv'", "thermo_file=''")
    run(terrace, work, "rahman_eq", eq)
    rahman = ("&run units='metal', dimension=3, {len}, seed=1964 /\n"
              "&system atoms_file='argon_liquid_eq.atoms', box_lo=0.0,0.0,0.0, box_hi=34.6809019,34.6809019,34.6809019,\n"
              "        periodic=.true.,.true.,.true., mass=39.948 /\n"
              "&potential style='lj', epsilon=0.0103408116, sigma=3.4, cutoff=8.5, shift=.true. /\n"
              "&neighbor skin=1.0 /\n{integ}\n")
    lj = open(os.path.join(REPO, "input", "lj_bench.nml")).read().replace("n_steps=1000", "n_steps=300")
    lj = lj.replace("&output thermo_every=100, thermo_file='' /", "&output thermo_every=100, final_atoms_file='lj_eq.atoms' /")
    lj = lj.replace("cutoff=2.5, shift=.false.", "cutoff=2.5, shift=.true.")
    run(terrace, work, "lj_eq", lj)
    big = ("&run units='lj', dimension=3, {len}, seed=1 /\n"
           "&system atoms_file='lj_eq.atoms', box_lo=0.0,0.0,0.0, box_hi=33.5919238,33.5919238,33.5919238,\n"
           "        periodic=.true.,.true.,.true., mass=1.0 /\n"
           "&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.true. /\n"
           "&neighbor skin=0.3 /\n{integ}\n")
    scenes = [
        ("7-atom cluster", cluster, "run_time=10000.0", "run_time=10000.0",
         "&integrator style='velocity_verlet', dt=0.01 /", "&integrator style='energy_stepping', terrace_height=1.378775e-3 /"),
        ("Rahman argon 864", rahman, "run_time=10.0", "run_time=1.0",
         "&integrator style='velocity_verlet', dt=0.01 /", "&integrator style='energy_stepping', terrace_height=2.0e-3 /"),
        ("LJ 32,000", big, "n_steps=200", "n_steps=2000",
         "&integrator style='velocity_verlet', dt=0.005 /", "&integrator style='energy_stepping', terrace_height=0.3 /"),
    ]
    rows = []
    for name, tmpl, vlen, elen, vv, es in scenes:
        key = name.split()[0].replace("-", "").lower()
        v = run(terrace, work, key + "_vv", tmpl.format(len=vlen, integ=vv))
        e = run(terrace, work, key + "_es", tmpl.format(len=elen, integ=es))
        dt = float(re.search(r"dt=([0-9.]+)", vv).group(1))
        t_step = v["loop"] / v["n"]
        t_event = e["loop"] / e["n"]
        rows.append((name, e["n"] / e["loop"], e["mean_dt"], e["refl"], e["evals"], e["passes"], t_event / t_step,
                     e["mean_dt"] / e["loop"] * e["n"], dt / t_step))
    print(f"{'scene':18} {'events/s':>10} {'mean dt':>10} {'refl':>6} {'evals/ev':>9} {'passes/ev':>9} "
          f"{'event/step':>10} {'ES time/s':>10} {'VV time/s':>10}")
    for r in rows:
        print(f"{r[0]:18} {r[1]:10.3e} {r[2]:10.3e} {100*r[3]:5.1f}% {r[4]:9.3f} {r[5]:9.3f} {r[6]:10.2f} "
              f"{r[7]:10.3e} {r[8]:10.3e}")
    print("\nmean dt in the run's time unit (ps, ps, tau); 'event/step' = wall time of one event / one Verlet step;"
          "\n'ES time/s', 'VV time/s' = simulated time per wall second of energy stepping and of Verlet.")


if __name__ == "__main__":
    main()
