#!/usr/bin/env python3
"""Spinning neo-Hookean cube, small mesh (2 x 2 x 2 cells of the talk's subdivision,
71 nodes, 192 tetrahedra, 0.1 m, rubber-like: rho 1100 kg/m^3, lambda 2.7 MPa, mu 0.3 MPa, spin
100 rad/s about z):
  - energy stepping (h = 1e-3 J, 1000 events): K + k h constant to 1e-12 relative, |E - E0| <= h,
    linear momentum and angular momentum conserved to round-off; the same 1000 events on 2 and 4
    ranks: events, time and pe identical to 1 rank's (the element forces
    are summed per node in element order and the energies, ray sums and kick sums are exact sums,
    so the dynamics has the same bits on any number of ranks), etotal and lz within 1e-10 relative
    (their kinetic and angular-momentum sums are plain sums: round-off only);
  - velocity Verlet at dt = 1e-4 s: max |E - E0| below 1e-3 J, L_z to round-off, the thermo of 200
    steps on 2 and 4 ranks within 1e-10 relative of 1 rank; at dt = 8e-4 s the
    run is unstable and stops with one clear error line and a non-zero exit.
usage: check_mesh_cube.py TERRACE OUTDIR
"""
import os
import sys

import numpy as np
from terrace_tools import summary

from mesh_checks import check, cube_mesh, failed, run as run_terrace, start

terrace, out = start()
cube_mesh(os.path.join(out, "cube2.msh"))


def deck(name, integrator, length, thermo):
    text = f"""&run units='si', dimension=3, {length}, seed=1 /
&system mesh_file='cube2.msh', mass_density=1100.0, periodic=.false.,.false.,.false.,
        angular_velocity(:,1)=0.0,0.0,100.0 /
&potential style='neohookean', lambda=2.7e6, mu=3.0e5 /
&integrator {integrator} /
&output {thermo}, thermo_file='{name}.csv' /
"""
    open(os.path.join(out, name + ".nml"), "w").write(text)


def run(name, np_=1):
    return run_terrace(terrace, out, np_, name + ".nml", timeout=600)


h = 1.0e-3
for np_ in (1, 2, 4):
    deck(f"es_np{np_}", f"style='energy_stepping', terrace_height={h}", "n_steps=1000", "thermo_every=50")
    r = run(f"es_np{np_}", np_)
    check(r.returncode == 0, f"energy stepping on {np_} rank(s) ran (exit {r.returncode}) {r.stderr.strip()[:200]}")
    if np_ == 1:
        # the screen says what a mesh's temp column is; the run summary counts the mesh's 71 nodes
        check("not a temperature of the solid" in r.stdout, "the screen explains the mesh's temp column")
        nodes = summary.get(os.path.join(out, "es_np1.summary.json"), "run/atoms", None)
        check(nodes == 71, f"the run summary counts the mesh's nodes: run/atoms = {nodes} (cube2.msh: 71)")
if failed:
    sys.exit(1)
t = {n: np.genfromtxt(os.path.join(out, f"es_np{n}.csv"), delimiter=",", names=True) for n in (1, 2, 4)}
a = t[1]
e0 = a["etotal"][0]
check(np.ptp(a["e_terraced"]) <= 1e-12 * abs(e0), f"K + k h constant: spread {np.ptp(a['e_terraced']):.2e} J")
# V - V_h lies in [0, h) at every state, so |E - E0| < h, up to the event solver's edge tolerance (1e-9 h)
check(np.max(np.abs(a["etotal"] - e0)) <= h * (1 + 1e-6), f"|K + V - E0| <= h: {np.max(np.abs(a['etotal'] - e0)) / h:.9f} h")
pscale = 1100 * 1e-3 * 100 * 0.05
for c in ("px", "py", "pz"):
    check(np.max(np.abs(a[c] - a[c][0])) <= 1e-12 * pscale, f"{c} conserved: {np.max(np.abs(a[c] - a[c][0])):.2e}")
lz0 = a["lz"][0]
for c in ("lx", "ly", "lz"):
    check(np.max(np.abs(a[c] - a[c][0])) <= 1e-12 * abs(lz0), f"{c} conserved: {np.max(np.abs(a[c] - a[c][0])):.2e} "
          f"(L_z = {lz0:.4e})")
check(len(a) == 21 and a["events"][-1] == 1000, f"1000 events in 21 thermo rows ({len(a)} rows)")
for n in (2, 4):
    b = t[n]
    check(len(b) == len(a), f"{n} ranks: {len(b)} thermo rows as 1 rank's {len(a)}")
    if len(b) != len(a):
        continue
    for c in ("events", "time", "pe"):
        d = np.max(np.abs(a[c] - b[c]) / np.maximum(np.abs(a[c]), 1e-300))
        check(np.array_equal(a[c], b[c]), f"1 vs {n} ranks, first 1000 events: {c} identical (max relative difference {d:.1e})")
    for c in ("etotal", "lz"):
        d = np.max(np.abs(a[c] - b[c]) / np.maximum(np.abs(a[c]), 1e-300))
        check(d <= 1e-10, f"1 vs {n} ranks, first 1000 events: {c} within {d:.1e}")
deck("vv", "style='velocity_verlet', dt=1.0e-4", "run_time=0.02", "thermo_interval=0.001")
r = run("vv")
check(r.returncode == 0, f"velocity Verlet at dt = 1e-4 s ran (exit {r.returncode})")
v = np.genfromtxt(os.path.join(out, "vv.csv"), delimiter=",", names=True)
check(np.max(np.abs(v["etotal"] - v["etotal"][0])) < 1e-3, f"Verlet max |E - E0| = {np.max(np.abs(v['etotal'] - v['etotal'][0])):.2e} J")
check(np.max(np.abs(v["lz"] - v["lz"][0])) <= 1e-12 * abs(v["lz"][0]), "Verlet L_z conserved")
# Verlet thermo on 1, 2 and 4 ranks (200 steps)
for n in (1, 2, 4):
    deck(f"vv_np{n}", "style='velocity_verlet', dt=1.0e-4", "n_steps=200", "thermo_every=20")
    r = run(f"vv_np{n}", n)
    check(r.returncode == 0, f"velocity Verlet on {n} rank(s) ran (exit {r.returncode})")
w = {n: np.genfromtxt(os.path.join(out, f"vv_np{n}.csv"), delimiter=",", names=True) for n in (1, 2, 4)}
for n in (2, 4):
    for c in ("pe", "ke", "etotal", "lz"):
        d = np.max(np.abs(w[1][c] - w[n][c]) / np.maximum(np.abs(w[1][c]), 1e-300))
        check(d <= 1e-10, f"Verlet 1 vs {n} ranks, 200 steps: {c} within {d:.1e}")
deck("vv_unstable", "style='velocity_verlet', dt=8.0e-4", "run_time=0.02", "thermo_interval=0.0008")
r = run("vv_unstable")
errors = [l for l in r.stderr.splitlines() if l.startswith("terrace: error")]
check(r.returncode != 0 and len(errors) == 1 and "unstable" in errors[0] and "Backtrace" not in r.stderr,
      f"Verlet at dt = 8e-4 s stops with one error line: {errors[0] if errors else r.stderr[:200]}")
sys.exit(1 if failed else 0)
