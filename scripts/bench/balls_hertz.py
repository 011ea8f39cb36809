#!/usr/bin/env python3
"""Contact duration and restitution of the two rubber balls against Hertz: mesh
refinements x approach speeds, velocity Verlet and energy stepping, and Verlet's largest stable
step on each mesh. Set-up of input/balls_*.nml (R = 0.1 m, rho 1100 kg/m^3, lambda 2.7 MPa,
mu 0.3 MPa, ball 2 thrown at ball 1 along -x, default contact: node_face), without spin by
default: on these faceted meshes a spinning ball trades some spin for normal motion (e > 1 at
0.5 m/s with 10 rad/s on refine 4: 1.34 with node_node, 1.07 with node_face).

usage: balls_hertz.py TERRACE OUTDIR [--refine 3 4 6] [--speeds 0.5 1 2] [--h 1e-3] [--no-es]
                      [--stability] [--spin W] [--dt DT] [--contact-stiffness K] [--contact-model M]
Prints one table row per case: nodes, d0, speed, Hertz T, then for each integrator the measured
contact duration, its ratio to T, the restitution e, the wall time, and for energy stepping the
number of events and the mean event interval. --stability: Verlet's largest stable dt on each mesh
(runs through the collision at growing dt until |E - E0| exceeds 1 % of E0 or the run stops).
"""
import argparse
import json
import os
import re
import subprocess
import sys
import time

import numpy as np

from terrace_tools import summary

ap = argparse.ArgumentParser()
ap.add_argument("terrace")
ap.add_argument("out")
ap.add_argument("--refine", type=float, nargs="+", default=[3, 4, 6])
ap.add_argument("--speeds", type=float, nargs="+", default=[0.5, 1.0, 2.0])
ap.add_argument("--h", type=float, default=1e-3)
ap.add_argument("--dt", type=float, default=2e-5, help="Verlet step (scaled with the mesh size: dt * 4 / refine)")
ap.add_argument("--no-es", action="store_true")
ap.add_argument("--spin", type=float, default=0.0, help="ball 2's angular velocity about z (rad/s; the decks: 10)")
ap.add_argument("--stability", action="store_true")
ap.add_argument("--contact-stiffness", type=float, default=None, help="contact_stiffness (N/m; default: the engine's)")
ap.add_argument("--contact-model", default=None, help="contact_model ('node_face', the default, or 'node_node')")
a = ap.parse_args()
terrace = os.path.abspath(a.terrace)
repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
os.makedirs(a.out, exist_ok=True)
R = 0.1


def make_mesh(refine):
    path = os.path.join(a.out, f"balls_r{refine:g}.msh")
    r = subprocess.run([sys.executable, os.path.join(repo, "scripts", "make_ball_mesh.py"), path, "--refine", str(refine)],
                       check=True, capture_output=True, text=True)
    nodes = int(re.search(r"(\d+) nodes", r.stdout).group(1))      # per ball
    return os.path.basename(path), nodes


def deck(name, mesh, v, integrator, run_time, traj=True):
    contact = "" if a.contact_stiffness is None else f", contact_stiffness={a.contact_stiffness:g}"
    contact += "" if a.contact_model is None else f", contact_model='{a.contact_model}'"
    outputs = f"thermo_interval=0.0005, thermo_file='{name}.csv'"
    if traj:
        outputs += f", trajectory_file='{name}.h5', trajectory_interval=0.0002"
    open(os.path.join(a.out, name + ".nml"), "w").write(f"""&run units='si', dimension=3, run_time={run_time:.6g}, seed=1 /
&system mesh_file='{mesh}', mass_density=1100.0, periodic=.false.,.false.,.false.,
        velocity(:,2)={-v:g},0.0,0.0, angular_velocity(:,2)=0.0,0.0,{a.spin:g} /
&potential style='neohookean', lambda=2.7e6, mu=3.0e5{contact} /
&integrator {integrator} /
&output {outputs}, overwrite=.true. /
""")


def run(name):
    t0 = time.time()
    r = subprocess.run([terrace, name + ".nml"], cwd=a.out, capture_output=True, text=True)
    return r, time.time() - t0


def analyse(name):
    subprocess.run([sys.executable, os.path.join(repo, "scripts", "balls_analysis.py"), os.path.join(a.out, name + ".nml"),
                    "--json", os.path.join(a.out, name + ".json")], check=True, capture_output=True)
    return json.load(open(os.path.join(a.out, name + ".json")))


print(f"# two rubber balls, R = {R} m, spin {a.spin:g} rad/s; Verlet dt = {a.dt:g} s x 4/refine; energy stepping h = {a.h:g} J")
print("| refine | nodes/ball | d0 (mm) | v (m/s) | Hertz T (ms) | Verlet T (ms) | /Hertz | e Verlet | ES T (ms) | /Hertz "
      "| e ES | ES events | ES mean dt (s) | wall Verlet (s) | wall ES (s) |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for refine in a.refine:
    mesh, nodes = make_mesh(refine)
    gap = 2 * R / refine
    for v in a.speeds:
        hertz_guess = 0.0367 * v ** -0.2
        run_time = gap / v + 1.4 * hertz_guess + 0.005
        tag = f"r{refine:g}_v{v:g}"
        dt = a.dt * 4 / refine
        deck("vv_" + tag, mesh, v, f"style='velocity_verlet', dt={dt:.4g}", run_time)
        r, wall_vv = run("vv_" + tag)
        if r.returncode != 0:
            print(f"| {refine:g} | {nodes} | Verlet failed: {r.stderr.strip()[:100]} |")
            continue
        s = analyse("vv_" + tag)
        row = (f"| {refine:g} | {nodes} | {s['d0'] * 1e3:.1f} | {v:g} | {s['hertz_T'] * 1e3:.2f} | "
               f"{s['duration'] * 1e3:.2f} | {s['ratio']:.3f} | {s['restitution']:.4f} |")
        if not a.no_es:
            deck("es_" + tag, mesh, v, f"style='energy_stepping', terrace_height={a.h:g}", run_time)
            r, wall_es = run("es_" + tag)
            e = analyse("es_" + tag)
            figures = summary.run_figures(os.path.join(a.out, "es_" + tag + ".summary.json"))
            ev, mdt = figures["events"], figures["mean_dt"]
            row += (f" {e['duration'] * 1e3:.2f} | {e['ratio']:.3f} | {e['restitution']:.4f} | {ev} | {float(mdt):.3g} |"
                    f" {wall_vv:.1f} | {wall_es:.1f} |")
        else:
            row += f" | | | | | {wall_vv:.1f} | |"
        print(row, flush=True)
if a.stability:
    print("\n# Verlet's largest stable step (v = 1 m/s, through the collision; stable: |E - E0| < 1 % of E0)")
    for refine in a.refine:
        mesh, nodes = make_mesh(refine)
        run_time = 2 * R / refine + 0.06
        last = None
        for f in (0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0):
            dt = f * 4e-5 * 4 / refine
            deck(f"st_r{refine:g}", mesh, 1.0, f"style='velocity_verlet', dt={dt:.4g}", run_time, traj=False)
            r, _ = run(f"st_r{refine:g}")
            ok = r.returncode == 0
            if ok:
                t = np.genfromtxt(os.path.join(a.out, f"st_r{refine:g}.csv"), delimiter=",", names=True)
                ok = np.max(np.abs(t["etotal"] - t["etotal"][0])) < 0.01 * abs(t["etotal"][0])
            if not ok:
                break
            last = dt
        print(f"refine {refine:g} ({nodes} nodes/ball): stable up to dt = {last:.3g} s, unstable at {dt:.3g} s")
