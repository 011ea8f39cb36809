#!/usr/bin/env python3
"""Rigid walls for meshes (&potential walls, doc/contact.md "Walls").

A stiff tetrahedron (rho 1100 kg/m^3, lambda 270 MPa, mu 30 MPa; one face flat, the apex above the
face's centroid, so that the wall's forces pass through the centre of mass) dropped flat at 1 m/s
on the plane z = -0.05 (walls = 'planes', wall_stiffness = 1e3 N/m, wall_distance = 0.01 m: a
contact of ~20 ms, far slower than the tetrahedron's own vibration):
  - velocity Verlet, dt = 1e-5 s: it bounces, restitution -pz_after/pz_before within 1e-4 of 1,
    max |E - E0| < 1e-6 J;
  - energy stepping, h = 1e-5 J: |E - E0| <= h at every sample, restitution within 1e-4 of 1; at
    h = 1e-4 J: |E - E0| <= h too;
  - a checkpoint inside the contact (Verlet step 4500, energy stepping 45 ms) on 1 and 2 ranks:
    the restarted run's thermo, final state, trajectory and XDMF sidecar byte-identical.
Two such tetrahedra side by side (bodies 1 and 2, 0.3 m apart along y; so the contact between
them is a term of the sum) between the floor z = -0.05 and the ceiling z = 0.2, thrown down at
1 m/s and up at 0.8 m/s (body 2 hits with its apex, above its centre of mass): the scene plan
lists the elements, the contact and the walls; energy stepping (h = 1e-5 J) |E - E0| <= h, Verlet
(dt = 1e-5 s) < 1e-6 J; after one bounce each (0.19 s) the total P_z is reversed (Verlet: to 1 %;
energy stepping: -P_end/P_0 = 1.05 at this h, checked within 0.5 of 1).
The small cube (scripts/make_cube_mesh.py, 2 x 2 x 2 cells, 71 nodes, 0.1 m; rubber-like) thrown
obliquely with spin inside the box -0.1 .. 0.1 m (walls = 'box', default k and d0), 0.2 s:
  - energy stepping, h = 1e-3 J: |E - E0| <= h, and the centre of mass's velocity reverses along
    x, y and z (it hits several walls);
  - velocity Verlet, dt = 1e-4 s: max |E - E0| < 5e-3 J (of some 3.5 J); on 3 ranks the final positions and
    velocities are byte-identical to 1 rank's (the wall forces act on owned nodes only);
  - energy stepping's first 3000 events (past the first wall contact) on 3 ranks within 1e-10 of 1
    rank's thermo (the walls' energies are summed over the ranks: round-off only, which the many
    collisions of a longer run amplify).
usage: check_walls.py TERRACE OUTDIR
"""
import os
import subprocess

import numpy as np
from terrace_tools import summary

from mesh_checks import check, compare_restart, cube_mesh, finish, read, run as run_terrace, start

terrace, out = start()

TET = """$MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
4
1 0 0 0
2 0.1 0 0
3 0.05 0.086602540378443865 0
4 0.05 0.028867513459481288 0.08
$EndNodes
$Elements
1
1 4 2 1 1 1 2 3 4
$EndElements
"""


def tet_deck(integrator, length, outputs):
    return f"""&run units='si', dimension=3, {length}, seed=1 /
&system mesh_file='tet.msh', mass_density=1100.0, periodic=.false.,.false.,.false.,
        velocity(:,1)=0.0,0.0,-1.0 /
&potential style='neohookean', lambda=2.7e8, mu=3.0e7, walls='planes', wall_planes=0.0,0.0,-0.05, 0.0,0.0,1.0,
           wall_stiffness=1.0e3, wall_distance=0.01 /
&integrator {integrator} /
&output {outputs} /
"""


def cube_deck(integrator, length, outputs):
    return f"""&run units='si', dimension=3, {length}, seed=1 /
&system mesh_file='cube2.msh', mass_density=1100.0, periodic=.false.,.false.,.false.,
        box_lo=-0.1,-0.1,-0.1, box_hi=0.1,0.1,0.1,
        velocity(:,1)=2.0,1.3,0.7, angular_velocity(:,1)=0.0,10.0,30.0 /
&potential style='neohookean', lambda=2.7e6, mu=3.0e5, walls='box' /
&integrator {integrator} /
&output {outputs} /
"""


def run(name, text, np_=1, mesh="tet"):
    d = os.path.join(out, name)
    os.makedirs(d)
    if mesh == "tet":
        open(os.path.join(d, "tet.msh"), "w").write(TET)
    else:
        cube_mesh(os.path.join(d, "cube2.msh"))
    open(os.path.join(d, "run.nml"), "w").write(text)
    r = run_terrace(terrace, d, np_, timeout=600)
    check(r.returncode == 0, f"{name} on {np_} rank(s) ran (exit {r.returncode}) {r.stderr.strip()[-300:]}")
    return d


def thermo(d):
    return np.genfromtxt(os.path.join(d, "thermo.csv"), delimiter=",", names=True)


# ---- the tetrahedron dropped flat on a wall
for name, integ, h in (("tet_vv", "style='velocity_verlet', dt=1.0e-5", None),
                       ("tet_es5", "style='energy_stepping', terrace_height=1.0e-5", 1e-5),
                       ("tet_es4", "style='energy_stepping', terrace_height=1.0e-4", 1e-4)):
    t = thermo(run(name, tet_deck(integ, "run_time=0.12", "thermo_interval=0.002, thermo_file='thermo.csv'")))
    e = -t["pz"][-1] / t["pz"][0]
    de = np.max(np.abs(t["etotal"] - t["etotal"][0]))
    if h is None:
        check(abs(e - 1) < 1e-4, f"{name}: bounces with restitution {e:.7f} (within 1e-4 of 1)")
        check(de < 1e-6, f"{name}: max |E - E0| = {de:.2e} J < 1e-6 J")
    else:
        check(de <= h, f"{name}: max |E - E0| = {de:.3e} J <= h = {h:g} J")
        if h == 1e-5:
            check(abs(e - 1) < 1e-4, f"{name}: bounces with restitution {e:.7f} (within 1e-4 of 1)")

# ---- checkpoint inside the wall contact, bitwise restart
ckpt_out = ("thermo_interval=0.001, thermo_file='thermo.csv', trajectory_file='traj.h5', trajectory_interval=0.002, "
            "final_atoms_file='final.txt', checkpoint_file='restart.h5', ")
for label, integ, length, ckpt in (("Verlet", "style='velocity_verlet', dt=1.0e-5", "n_steps=5999", "checkpoint_every=4500"),
                                   ("energy stepping", "style='energy_stepping', terrace_height=1.0e-4", "run_time=0.06",
                                    "checkpoint_interval=0.045")):
    for np_ in (1, 2):
        tag = f"restart_{label.split()[0].lower()}_np{np_}"
        a = run(tag + "_straight", tet_deck(integ, length, ckpt_out + ckpt), np_)
        b = os.path.join(out, tag + "_restarted")
        os.makedirs(b)
        open(os.path.join(b, "tet.msh"), "w").write(TET)
        t = thermo(a)
        at = 0.045
        pe = t["pe"][np.argmin(np.abs(t["time"] - at))]
        check(pe > 0, f"{label}, {np_} rank(s): the checkpoint at {at} s is inside the wall contact (pe = {pe:.3e} J)")
        compare_restart(terrace, a, b, np_, f"{label}, {np_} rank(s)",
                        tet_deck(integ, length, ckpt_out + ckpt).replace("&system ", "&system read_checkpoint='restart.h5', "),
                        "(checkpoint in the contact)")

# ---- two bodies between two walls: the elements, the contact and the walls as one sum
TWO = """$MeshFormat
2.2 0 8
$EndMeshFormat
$Nodes
8
1 0 0 0
2 0.1 0 0
3 0.05 0.086602540378443865 0
4 0.05 0.028867513459481288 0.08
5 0.2 0.3 0
6 0.3 0.3 0
7 0.25 0.386602540378443865 0
8 0.25 0.328867513459481288 0.08
$EndNodes
$Elements
2
1 4 2 1 1 1 2 3 4
2 4 2 2 2 5 6 7 8
$EndElements
"""


def two_deck(integrator):
    return f"""&run units='si', dimension=3, run_time=0.19, seed=1 /
&system mesh_file='two.msh', mass_density=1100.0, periodic=.false.,.false.,.false.,
        velocity(:,1)=0.0,0.0,-1.0, velocity(:,2)=0.0,0.0,0.8 /
&potential style='neohookean', lambda=2.7e8, mu=3.0e7, contact_stiffness=1.0e4, contact_distance=0.01,
           walls='planes', wall_planes=0.0,0.0,-0.05, 0.0,0.0,1.0, 0.0,0.0,0.2, 0.0,0.0,-1.0,
           wall_stiffness=1.0e3, wall_distance=0.01 /
&integrator {integrator} /
&output thermo_interval=0.002, thermo_file='thermo.csv', final_atoms_file='final.txt' /
"""


for name, integ, bound in (("two_es", "style='energy_stepping', terrace_height=1.0e-5", 1e-5),
                           ("two_vv", "style='velocity_verlet', dt=1.0e-5", 1e-6)):
    d = os.path.join(out, name)
    os.makedirs(d)
    open(os.path.join(d, "two.msh"), "w").write(TWO)
    open(os.path.join(d, "run.nml"), "w").write(two_deck(integ))
    if name == "two_es":
        r = subprocess.run([terrace, "--check", "run.nml"], cwd=d, capture_output=True, text=True)
        plan = [ln for ln in r.stdout.splitlines() if "potential  :" in ln]
        check(r.returncode == 0 and plan and "neohookean" in plan[0] and "contact (node_face) between 2 bodies" in plan[0]
              and "walls: 2 planes against 8 boundary nodes" in plan[0],
              "two bodies with walls: the scene plan lists the elements, the contact and the walls")
    r = run_terrace(terrace, d, 1, timeout=600)
    check(r.returncode == 0, f"{name} ran (exit {r.returncode}) {r.stderr.strip()[-300:]}")
    if r.returncode != 0:
        continue
    t = thermo(d)
    de = np.max(np.abs(t["etotal"] - t["etotal"][0]))
    check(de <= bound, f"{name}: two bodies, contact and walls: max |E - E0| = {de:.3e} J <= {bound:g} J")
    if name == "two_es":
        # V on its terrace at every sample: V - k h in [0, h] (k h = e_terraced - ke), to about twice
        # the search's tolerance (raised to 1.18e-4 h here); and the search at that tolerance: about one
        # ray evaluation per event. (With a tolerance below the round-off of the stiff elements'
        # energies, 1e-9 h, it took 87-106 and its kicks overshot the levels: V - k h reached
        # 1.000534 h in a Debug build.)
        band = (t["pe"] - (t["e_terraced"] - t["ke"]))/1e-5
        check(band.min() >= -2.5e-4 and band.max() <= 1 + 2.5e-4,
              f"two_es: V - k h within [0, h] at every sample: [{band.min():.6f}, {band.max():.6f}] h")
        per = summary.get(os.path.join(d, "run.summary.json"), "energy_stepping/ray_evaluations_per_event",
                          float("inf"))
        check(per <= 3, f"two_es: {per:.3f} ray evaluations per event (at most 3)")
    ratio = -t["pz"][-1] / t["pz"][0]
    tol = 0.01 if name == "two_vv" else 0.5       # energy stepping's restitution converges slowly in h
    check(abs(ratio - 1) < tol, f"{name}: each body bounced off its wall: P_z {t['pz'][0]:.5f} -> {t['pz'][-1]:.5f} "
          f"kg m/s (-ratio {ratio:.4f}, within {tol:g} of 1)")

# ---- the cube thrown inside the box of walls
t = thermo(run("cube_es", cube_deck("style='energy_stepping', terrace_height=1.0e-3", "run_time=0.2",
                                    "thermo_interval=0.002, thermo_file='thermo.csv'"), mesh="cube"))
de = np.max(np.abs(t["etotal"] - t["etotal"][0]))
check(de <= 1e-3, f"cube in the box, energy stepping: max |E - E0| = {de:.3e} J <= h = 1e-3 J")
flips = [int(np.sum(np.diff(np.sign(t[c])) != 0)) for c in ("px", "py", "pz")]
check(all(f >= 1 for f in flips), f"cube in the box: the centre of mass reverses along x, y, z {flips} times")

vv = {}
for np_ in (1, 3):
    d = run(f"cube_vv_np{np_}", cube_deck("style='velocity_verlet', dt=1.0e-4", "run_time=0.2",
                                          "thermo_interval=0.002, thermo_file='thermo.csv', final_atoms_file='final.txt'"),
            np_, mesh="cube")
    vv[np_] = d
t = thermo(vv[1])
de = np.max(np.abs(t["etotal"] - t["etotal"][0]))
check(de < 5e-3, f"cube in the box, Verlet dt = 1e-4 s: max |E - E0| = {de:.2e} J < 5e-3 J")
check(read(os.path.join(vv[1], "final.txt")) == read(os.path.join(vv[3], "final.txt")),
      "cube in the box, Verlet, 2000 steps: final positions and velocities on 3 ranks byte-identical to 1 rank's")

es = {}
for np_ in (1, 3):
    es[np_] = thermo(run(f"cube_es_np{np_}", cube_deck("style='energy_stepping', terrace_height=1.0e-3",
                                                        "n_steps=3000", "thermo_every=100, thermo_file='thermo.csv'"),
                         np_, mesh="cube"))
hit = es[1]["time"][np.argmax(np.abs(es[1]["px"] - es[1]["px"][0]) > 1e-3)]
check(es[1]["time"][-1] > hit > 0, f"the first 3000 events reach t = {es[1]['time'][-1] * 1e3:.1f} ms, past the first wall "
      f"contact ({hit * 1e3:.1f} ms)")
for c in ("time", "pe", "ke", "etotal", "px", "lz"):
    a, b = es[1][c], es[3][c]
    scale = max(np.max(np.abs(a)), 1e-300)
    d = np.max(np.abs(a - b)) / scale
    check(d <= 1e-10, f"cube in the box, energy stepping 1 vs 3 ranks, 3000 events: {c} within {d:.1e} (relative to its "
          "largest value)")
finish()
