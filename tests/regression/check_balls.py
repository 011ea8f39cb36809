#!/usr/bin/env python3
"""Two colliding rubber balls with contact, coarse mesh (scripts/make_ball_mesh.py
--refine 3: 208 nodes and 672 tetrahedra per ball, R = 0.1 m, gap 35 mm; rho 1100 kg/m^3,
lambda 2.7 MPa, mu 0.3 MPa; ball 2 at 1 m/s along -x with 10 rad/s about z; default contact,
node_face):
  - energy stepping (h = 1e-3 J), the whole collision: linear and angular momentum of the two balls
    conserved to 1e-12 relative through the contact (thermo px..lz), |E - E0| <= h at every sample,
    and from the trajectory (scripts/balls_analysis.py): contact begins and ends, duration within
    15 % of Hertz, 0.85 < e < 1.1 (the spinning faceted ball may feed a little spin into the normal
    motion), translation + rotation + vibration + elastic after separation equal to the initial
    energy within h; the same without spin: 0.85 < e < 1 and the balance within h;
  - velocity Verlet (dt = 2e-5 s): max |E - E0| < 1e-4 J, P to round-off, L to 1e-10 relative, and
    the restitution within 0.02 of energy stepping's (their difference at these settings: 0.009);
  - ranks: energy stepping's first 1000 events (through the start of the contact) and Verlet's first
    1000 steps on 2 and 4 ranks within 1e-10 relative of 1 rank.
The mesh needs the gmsh Python package: installed into ~/.cache/terrace-venv when missing; when
that is not possible (offline), the test is SKIPPED (exit 77).
usage: check_balls.py TERRACE OUTDIR
"""
import json
import os
import subprocess
import sys

import numpy as np

from mesh_checks import REPO, ball_mesh, check, failed, run as run_terrace, start

terrace, out = start()

ball_mesh(os.path.join(out, "balls.msh"), 3, 0.035)


def deck(name, integrator, length, outputs, spin=10.0):
    text = f"""&run units='si', dimension=3, {length}, seed=1 /
&system mesh_file='balls.msh', mass_density=1100.0, periodic=.false.,.false.,.false.,
        velocity(:,2)=-1.0,0.0,0.0, angular_velocity(:,2)=0.0,0.0,{spin} /
&potential style='neohookean', lambda=2.7e6, mu=3.0e5 /
&integrator {integrator} /
&output {outputs}, thermo_file='{name}.csv' /
"""
    open(os.path.join(out, name + ".nml"), "w").write(text)


def run(name, np_=1):
    r = run_terrace(terrace, out, np_, name + ".nml", timeout=600)
    check(r.returncode == 0, f"{name} on {np_} rank(s) ran (exit {r.returncode}) {r.stderr.strip()[:300]}")
    return r


def analyse(name):
    subprocess.run([sys.executable, os.path.join(REPO, "scripts", "balls_analysis.py"), os.path.join(out, name + ".nml"),
                    "--json", os.path.join(out, name + ".json")], check=True)
    return json.load(open(os.path.join(out, name + ".json")))


h = 1.0e-3
deck("es", f"style='energy_stepping', terrace_height={h}", "run_time=0.065",
     "thermo_interval=0.0005, trajectory_file='es.h5', trajectory_interval=0.0005")
run("es")
deck("vv", "style='velocity_verlet', dt=2.0e-5", "run_time=0.065",
     "thermo_interval=0.0005, trajectory_file='vv.h5', trajectory_interval=0.0005")
run("vv")
if failed:
    sys.exit(1)
a = np.genfromtxt(os.path.join(out, "es.csv"), delimiter=",", names=True)
e0 = a["etotal"][0]
check(np.max(np.abs(a["etotal"] - e0)) <= h * (1 + 1e-6), f"ES |K + V - E0| <= h: {np.max(np.abs(a['etotal'] - e0)) / h:.6f} h")
pscale = np.max(np.abs([a["px"][0], a["py"][0], a["pz"][0]]))
lscale = np.max(np.abs([a["lx"][0], a["ly"][0], a["lz"][0]]))
for c in ("px", "py", "pz"):
    d = np.max(np.abs(a[c] - a[c][0]))
    check(d <= 1e-12 * pscale, f"ES {c} conserved through the contact: {d:.2e} (|P| = {pscale:.3g})")
for c in ("lx", "ly", "lz"):
    d = np.max(np.abs(a[c] - a[c][0]))
    check(d <= 1e-12 * lscale, f"ES {c} conserved through the contact: {d:.2e} (|L| = {lscale:.3g})")
es = analyse("es")
check(es["t_start"] > 0 and es["t_end"] < 0.064, f"ES contact from {es['t_start'] * 1e3:.2f} to {es['t_end'] * 1e3:.2f} ms")
check(abs(es["ratio"] - 1) < 0.15, f"ES contact {es['duration'] * 1e3:.2f} ms vs Hertz {es['hertz_T'] * 1e3:.2f} ms "
      f"(ratio {es['ratio']:.3f})")
# With 10 rad/s (surface speed 1 m/s, the approach speed) the faceted balls trade some spin for
# normal motion (the contact normals of a polyhedron do not pass through the ball's centre), so e
# may exceed 1 a little on this coarse mesh (node_face: 1.03; node_node gave up to 1.34); without
# spin no energy can feed the normal motion and e < 1 is asserted on a run of its own below.
check(0.85 < es["restitution"] < 1.1, f"ES restitution with spin {es['restitution']:.4f} (within 0.1 of 1)")
check(abs(es["balance"]) <= h, f"ES energy after separation: translation {es['Kt_after']:.5f} + rotation "
      f"{es['Kr_after']:.5f} + vibration {es['Kvib_after']:.5f} + elastic {es['el_after']:.5f} - E0 = "
      f"{es['balance']:.2e} J (h = {h:g})")
v = np.genfromtxt(os.path.join(out, "vv.csv"), delimiter=",", names=True)
dE = np.max(np.abs(v["etotal"] - v["etotal"][0]))
check(dE < 1e-4, f"Verlet max |E - E0| = {dE:.2e} J")
for c in ("px", "py", "pz"):
    d = np.max(np.abs(v[c] - v[c][0]))
    check(d <= 1e-12 * pscale, f"Verlet {c}: {d:.2e}")
for c in ("lx", "ly", "lz"):
    d = np.max(np.abs(v[c] - v[c][0]))
    check(d <= 1e-10 * lscale, f"Verlet {c}: {d:.2e}")
vv = analyse("vv")
check(abs(vv["restitution"] - es["restitution"]) < 0.02, f"restitution: Verlet {vv['restitution']:.4f}, "
      f"energy stepping {es['restitution']:.4f}")
check(abs(vv["duration"] - es["duration"]) < 0.02 * vv["duration"], f"duration: Verlet {vv['duration'] * 1e3:.3f} ms, "
      f"energy stepping {es['duration'] * 1e3:.3f} ms")
# no spin: the normal restitution is below 1 (energy goes into vibration, none comes from rotation)
deck("es0", f"style='energy_stepping', terrace_height={h}", "run_time=0.065",
     "thermo_interval=0.0005, trajectory_file='es0.h5', trajectory_interval=0.0005", spin=0.0)
run("es0")
es0 = analyse("es0")
check(0.85 < es0["restitution"] < 1, f"ES restitution without spin {es0['restitution']:.4f} (< 1)")
check(abs(es0["balance"]) <= h, f"ES energy balance after separation without spin: {es0['balance']:.2e} J (h = {h:g})")
# ranks
for n in (1, 2, 4):
    deck(f"es_np{n}", f"style='energy_stepping', terrace_height={h}", "n_steps=1000", "thermo_every=100")
    run(f"es_np{n}", n)
    deck(f"vv_np{n}", "style='velocity_verlet', dt=2.0e-5", "n_steps=1000", "thermo_every=100")
    run(f"vv_np{n}", n)
if failed:
    sys.exit(1)
t = {n: np.genfromtxt(os.path.join(out, f"es_np{n}.csv"), delimiter=",", names=True) for n in (1, 2, 4)}
w = {n: np.genfromtxt(os.path.join(out, f"vv_np{n}.csv"), delimiter=",", names=True) for n in (1, 2, 4)}
check(t[1]["time"][-1] > es["t_start"], f"the first 1000 events reach t = {t[1]['time'][-1] * 1e3:.2f} ms, past the "
      f"contact start ({es['t_start'] * 1e3:.2f} ms)")
for n in (2, 4):
    for c in ("time", "pe", "etotal", "px", "lz"):
        d = np.max(np.abs(t[1][c] - t[n][c]) / np.maximum(np.abs(t[1][c]), 1e-300))
        check(d <= 1e-10, f"ES 1 vs {n} ranks, first 1000 events: {c} within {d:.1e}")
    for c in ("pe", "ke", "etotal", "lz"):
        d = np.max(np.abs(w[1][c] - w[n][c]) / np.maximum(np.abs(w[1][c]), 1e-300))
        check(d <= 1e-10, f"Verlet 1 vs {n} ranks, 1000 steps: {c} within {d:.1e}")
sys.exit(1 if failed else 0)
