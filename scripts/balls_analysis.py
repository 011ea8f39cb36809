#!/usr/bin/env python3
"""Analysis of a two-ball collision run from its H5MD trajectory (positions and
velocities of every node) and its mesh (MSH 2.2, one physical volume per ball).

Per frame: each ball's mass, centre of mass, centre-of-mass velocity, angular momentum about its
centre and spin w = I^-1 L, kinetic energy split into translation (M V^2/2), rotation (w.L/2) and
the rest (vibration), the neo-Hookean elastic energy of each ball, and the contact force and energy
recomputed here from the positions with the deck's contact_model, k and d0 or their defaults
(doc/contact.md): node_face (default), k/2 (d0 - d)^2 over (boundary node of one ball, boundary
triangle of the other), d the point-triangle distance; node_node, k/2 (d0 - r)^2 over pairs of
boundary nodes of different balls. Contact start and end: where the smallest such distance crosses
d0 (interpolated between frames).

Printed: the contact start, end and duration against Hertz's T = 2.868 (m*^2/(R* E*^2 v))^(1/5),
the balls' velocities and spins before and after, the normal coefficient of restitution, the
energy split after separation with the balance against the initial energy, the total linear and
angular momentum spreads over the run, and the peak contact force against Hertz's.

usage: balls_analysis.py DECK.nml [--traj FILE.h5] [--mesh FILE.msh] [--radius 0.1] [--plot OUT.png]
                         [--snapshots OUT.png] [--json OUT.json] [--label TEXT]
(the deck gives mesh_file, trajectory_file, mass_density, lambda, mu, contact_model,
contact_stiffness and contact_distance; paths are relative to the deck's directory)
"""
import argparse
import json
import os
import re
import sys

import numpy as np

from point_triangle import boundary_faces, closest_on_triangles
from terrace_tools import h5md


def deck_values(path):
    text = open(path).read()
    text = "\n".join(line.split("!")[0] for line in text.splitlines())

    def num(key, default=None):
        m = re.search(r"\b" + key + r"\s*=\s*([-+0-9.eEdD]+)", text)
        return float(m.group(1).replace("d", "e").replace("D", "e")) if m else default

    def word(key, default=None):
        m = re.search(r"\b" + key + r"\s*=\s*'([^']*)'", text)
        return m.group(1) if m else default
    return dict(mesh=word("mesh_file"), traj=word("trajectory_file"), thermo=word("thermo_file"),
                rho=num("mass_density"), lam=num("lambda"), mu=num("mu"),
                k=num("contact_stiffness"), d0=num("contact_distance"), integrator=word("style", ""),
                model=(word("contact_model") or "node_face").lower())


def read_msh22(path):
    lines = open(path).read().split("\n")
    i = lines.index("$Nodes")
    n = int(lines[i + 1])
    x = np.array([[float(v) for v in lines[i + 2 + k].split()[1:4]] for k in range(n)])
    tags = [int(lines[i + 2 + k].split()[0]) for k in range(n)]
    assert tags == list(range(1, n + 1)), "node tags must be 1..N"
    i = lines.index("$Elements")
    m = int(lines[i + 1])
    tets, body = [], []
    for k in range(m):
        v = [int(t) for t in lines[i + 2 + k].split()]
        if v[1] != 4:
            continue
        nt = v[2]
        body.append(v[3] if nt >= 1 else 1)
        tets.append(v[3 + nt:7 + nt])
    return x, np.array(tets) - 1, np.array(body)


def boundary(tets, n):
    faces = boundary_faces(tets)
    is_b = np.zeros(n, bool)
    is_b[faces.ravel()] = True
    edges = np.concatenate([np.linalg.norm(X[faces[:, a]] - X[faces[:, (a + 1) % 3]], axis=1) for a in range(3)])
    return is_b, edges.mean(), faces, edges.max()


def node_face_pairs(x, nodes, faces, reach):
    """(node, face) pairs of nodes against faces whose centroid is within reach: the vectors
    p - c (closest point) and the distances."""
    cen = x[faces].mean(1)
    dd = np.linalg.norm(x[nodes][:, None, :] - cen[None, :, :], axis=2)
    i, q = np.nonzero(dd < reach)
    p = x[nodes[i]]
    fa, fb, fc = x[faces[q, 0]], x[faces[q, 1]], x[faces[q, 2]]
    w = closest_on_triangles(p, fa, fb, fc)
    dv = p - (w[:, 0:1] * fa + w[:, 1:2] * fb + w[:, 2:3] * fc)
    return dv, np.sqrt((dv * dv).sum(1))


def neohookean_energy(x, tets, dminv, v0, lam, mu):
    ds = np.stack([x[tets[:, a]] - x[tets[:, 0]] for a in (1, 2, 3)], axis=2)   # (ne, 3, 3) columns
    F = ds @ dminv
    J = np.linalg.det(F)
    lnJ = np.log(J)
    return v0 * (0.5 * lam * lnJ ** 2 - mu * lnJ + 0.5 * mu * (np.sum(F * F, axis=(1, 2)) - 3))


def hertz(mstar, rstar, estar, v, nt=4000):
    """Hertz contact of two spheres: duration and the force-time curve (m* d'' = -K d^1.5)."""
    K = 4.0 / 3.0 * estar * np.sqrt(rstar)
    T = 2.868 * (mstar ** 2 / (rstar * estar ** 2 * v)) ** 0.2
    dt = 1.2 * T / nt
    d, u, t = 0.0, v, 0.0
    ts, fs = [0.0], [0.0]

    def acc(dd):
        return -K * max(dd, 0.0) ** 1.5 / mstar
    while True:
        k1 = (u, acc(d)); k2 = (u + dt / 2 * k1[1], acc(d + dt / 2 * k1[0]))
        k3 = (u + dt / 2 * k2[1], acc(d + dt / 2 * k2[0])); k4 = (u + dt * k3[1], acc(d + dt * k3[0]))
        d += dt / 6 * (k1[0] + 2 * k2[0] + 2 * k3[0] + k4[0])
        u += dt / 6 * (k1[1] + 2 * k2[1] + 2 * k3[1] + k4[1])
        t += dt
        if d <= 0:
            ts.append(t); fs.append(0.0)
            break
        ts.append(t); fs.append(K * d ** 1.5)
    return T, np.array(ts), np.array(fs)


ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
ap.add_argument("deck")
ap.add_argument("--traj")
ap.add_argument("--mesh")
ap.add_argument("--radius", type=float, default=0.1)
ap.add_argument("--plot")
ap.add_argument("--json")
ap.add_argument("--snapshots", help="PNG: cross-sections z ~ 0 of the balls before, during and after the contact")
ap.add_argument("--label", default="")
a = ap.parse_args()
here = os.path.dirname(os.path.abspath(a.deck))
dv = deck_values(a.deck)
mesh_path = a.mesh or os.path.join(here, dv["mesh"])
traj_path = a.traj or os.path.join(here, dv["traj"])
X, tets, body = read_msh22(mesh_path)
n = len(X)
lam, mu, rho = dv["lam"], dv["mu"], dv["rho"]
E = mu * (3 * lam + 2 * mu) / (lam + mu)
nu = lam / (2 * (lam + mu))
is_b, hb, bfaces, max_edge = boundary(tets, n)
model = dv["model"]
d0 = dv["d0"] or (0.5 * hb if model == "node_face" else hb)
kc = dv["k"] or E * hb
nodebody = np.zeros(n, int)
for b in (1, 2):
    nodebody[np.unique(tets[body == b])] = b
dm = np.stack([X[tets[:, a]] - X[tets[:, 0]] for a in (1, 2, 3)], axis=2)
v0 = np.linalg.det(dm) / 6
dminv = np.linalg.inv(dm)
mass = np.zeros(n)
for c in range(4):
    np.add.at(mass, tets[:, c], rho * v0 / 4)
edge_ref = np.concatenate([np.linalg.norm(X[bfaces[:, q]] - X[bfaces[:, (q + 1) % 3]], axis=1) for q in range(3)])
b1 = np.where(is_b & (nodebody == 1))[0]
b2 = np.where(is_b & (nodebody == 2))[0]
faces1 = bfaces[nodebody[bfaces[:, 0]] == 1]
faces2 = bfaces[nodebody[bfaces[:, 0]] == 2]

fr = h5md.read(traj_path, unwrap=False)
order = np.argsort(fr["id"])
pos, vel, time = fr["x"][:, order], fr["v"][:, order], fr["time"]
nf = len(time)

rows = []
for t in range(nf):
    x, v = pos[t], vel[t]
    rec = {"t": time[t]}
    for b in (1, 2):
        sel = nodebody == b
        m, xb, vb = mass[sel], x[sel], v[sel]
        M = m.sum()
        c = (m[:, None] * xb).sum(0) / M
        V = (m[:, None] * vb).sum(0) / M
        r = xb - c
        u = vb - V
        L = (m[:, None] * np.cross(r, u)).sum(0)
        I = np.eye(3) * (m * (r * r).sum(1)).sum() - (m[:, None, None] * r[:, :, None] * r[:, None, :]).sum(0)
        w = np.linalg.solve(I, L)
        K = 0.5 * (m * (vb * vb).sum(1)).sum()
        Kt = 0.5 * M * V @ V
        Kr = 0.5 * w @ L
        el = neohookean_energy(x, tets[body == b], dminv[body == b], v0[body == b], lam, mu).sum()
        rec.update({f"M{b}": M, f"c{b}": c, f"V{b}": V, f"w{b}": w, f"K{b}": K, f"Kt{b}": Kt, f"Kr{b}": Kr,
                    f"el{b}": el})
    if model == "node_face":
        # force on ball 1 from ball 2: on its nodes from ball 2's faces, minus that on ball 2's nodes
        fvec = np.zeros(3)
        rs = []
        for nodes, fc, sg in ((b1, faces2, 1.0), (b2, faces1, -1.0)):
            d, r = node_face_pairs(x, nodes, fc, d0 + max_edge)
            if len(r) == 0:
                continue
            inside = r < d0
            fvec += sg * ((kc * (d0 - r[inside]) / r[inside])[:, None] * d[inside]).sum(0)
            rs.append(r)
        r = np.concatenate(rs) if rs else np.array([np.inf])
        inside = r < d0
    else:
        d = x[b1][:, None, :] - x[b2][None, :, :]
        r = np.sqrt((d * d).sum(2))
        inside = r < d0
        fmag = np.where(inside, kc * (d0 - r), 0.0)
        fvec = (fmag[:, :, None] * d / np.maximum(r, 1e-300)[:, :, None]).sum((0, 1))   # force on ball 1 from ball 2
    # boundary edges against the reference: the contact list's cutoff allows them 25 % (doc/contact.md)
    le = np.concatenate([np.linalg.norm(x[bfaces[:, q]] - x[bfaces[:, (q + 1) % 3]], axis=1) for q in range(3)])
    rec["stretch"] = (le / edge_ref).max() - 1
    rec["longest"] = le.max() / max_edge - 1
    rec["rmin"] = r.min()
    rec["Fc"] = np.linalg.norm(fvec)
    rec["Ec"] = (0.5 * kc * (d0 - r[inside]) ** 2).sum()
    rec["P"] = (mass[:, None] * v).sum(0)
    rec["L"] = (mass[:, None] * np.cross(x, v)).sum(0)
    rows.append(rec)

tt = np.array([r["t"] for r in rows])
rmin = np.array([r["rmin"] for r in rows])
Fc = np.array([r["Fc"] for r in rows])
Etot = np.array([r["K1"] + r["K2"] + r["el1"] + r["el2"] + r["Ec"] for r in rows])
inc = np.where(rmin < d0)[0]
if len(inc) == 0:
    sys.exit("balls_analysis.py: the balls never came within the contact distance")
i0, i1 = inc[0], inc[-1]
if i1 == nf - 1:
    sys.exit("balls_analysis.py: the balls are still in contact at the last frame (run longer)")


def cross_time(i, j):
    # where rmin crosses d0 between frames i and j (linear)
    return tt[i] + (d0 - rmin[i]) / (rmin[j] - rmin[i]) * (tt[j] - tt[i])


t_start = cross_time(i0 - 1, i0)
t_end = cross_time(i1, i1 + 1)
duration = t_end - t_start
pre, post = rows[i0 - 1], rows[-1]
nrm = pre["c2"] - pre["c1"]
nrm /= np.linalg.norm(nrm)
vn_before = (pre["V2"] - pre["V1"]) @ nrm
nrm_after = post["c2"] - post["c1"]
nrm_after /= np.linalg.norm(nrm_after)
vn_after = (post["V2"] - post["V1"]) @ nrm_after
e_rest = -vn_after / vn_before
M = pre["M1"]
R = a.radius
mstar, rstar, estar = M / 2, R / 2, E / (2 * (1 - nu ** 2))
T, ht, hf = hertz(mstar, rstar, estar, abs(vn_before))
E0 = Etot[0]
Kt_after = post["Kt1"] + post["Kt2"]
Kr_after = post["Kr1"] + post["Kr2"]
Kvib_after = post["K1"] + post["K2"] - Kt_after - Kr_after
el_after = post["el1"] + post["el2"]
P = np.array([r["P"] for r in rows])
Lt = np.array([r["L"] for r in rows])
out = dict(label=a.label, frames=nf, d0=d0, k=kc, E=E, nu=nu, mass=M, v=abs(vn_before), t_start=t_start, t_end=t_end,
           duration=duration, hertz_T=T, ratio=duration / T, frame_dt=float(tt[1] - tt[0]), restitution=e_rest,
           peak_force=float(Fc.max()), hertz_peak_force=float(hf.max()),
           E0=E0, Kt_after=Kt_after, Kr_after=Kr_after, Kvib_after=Kvib_after, el_after=el_after,
           Ec_after=rows[-1]["Ec"], balance=Etot[-1] - E0, max_dE=float(np.abs(Etot - E0).max()),
           dP=float(np.abs(P - P[0]).max()), dL=float(np.abs(Lt - Lt[0]).max()), Lscale=float(np.abs(Lt[0]).max()),
           Pscale=float(np.abs(P[0]).max()),
           V_before=[pre["V1"].tolist(), pre["V2"].tolist()], V_after=[post["V1"].tolist(), post["V2"].tolist()],
           w_before=[pre["w1"].tolist(), pre["w2"].tolist()], w_after=[post["w1"].tolist(), post["w2"].tolist()])

print(f"two-ball collision {a.label}: {nf} frames every {out['frame_dt']:.3g} s; ball mass {M:.5g} kg, R = {R:g} m, "
      f"E = {E:.4g} Pa, nu = {nu:.4g}; contact {model}, k = {kc:.4g} N/m, d0 = {d0:.4g} m")
print(f"  contact: start {t_start * 1e3:.3f} ms, end {t_end * 1e3:.3f} ms, duration {duration * 1e3:.3f} ms; "
      f"Hertz T = {T * 1e3:.3f} ms at v = {abs(vn_before):.4g} m/s: ratio {duration / T:.4f}")
print(f"  peak contact force {Fc.max():.4g} N (Hertz {hf.max():.4g} N)")
for b in (1, 2):
    print(f"  ball {b}: V before {np.array2string(pre[f'V{b}'], precision=5)} m/s, after "
          f"{np.array2string(post[f'V{b}'], precision=5)}; spin before {np.array2string(pre[f'w{b}'], precision=4)} "
          f"rad/s, after {np.array2string(post[f'w{b}'], precision=4)}")
print(f"  normal relative velocity before {vn_before:.6g} m/s, after {vn_after:.6g} m/s: restitution e = {e_rest:.5f}")
print(f"  energy after separation (J): translation {Kt_after:.6g}, rotation {Kr_after:.6g}, vibration: kinetic "
      f"{Kvib_after:.6g} + elastic {el_after:.6g} = {Kvib_after + el_after:.6g}; contact {rows[-1]['Ec']:.3g}")
print(f"  initial energy {E0:.9g} J; after: sum {Etot[-1]:.9g} J (balance {Etot[-1] - E0:.3e} J); "
      f"max |E - E0| over the frames {out['max_dE']:.3e} J")
print(f"  vibration share of the initial normal relative kinetic energy: "
      f"{(Kvib_after + el_after) / (0.5 * mstar * vn_before ** 2):.4f} (1 - e^2 = {1 - e_rest ** 2:.4f})")
print(f"  total momentum: max |P - P0| = {out['dP']:.3e} (|P0| = {out['Pscale']:.4g}); angular momentum: "
      f"max |L - L0| = {out['dL']:.3e} (|L0| = {out['Lscale']:.4g})")
out["edge_stretch"] = max(r["stretch"] for r in rows)
out["longest_edge_growth"] = max(r["longest"] for r in rows)
print(f"  boundary edges: largest stretch {out['edge_stretch'] * 100:.2f} % of an edge's reference length; the longest "
      f"current edge {out['longest_edge_growth'] * 100:+.2f} % against the longest reference edge (contact cutoff allows +25 %)")
if a.json:
    json.dump(out, open(a.json, "w"), indent=1)
if a.plot:
    import matplotlib
    from terrace_tools.plotting import plt, save
    fig, ax = plt.subplots(1, 2, figsize=(11, 4.2))
    ax[0].plot((tt - t_start) * 1e3, Fc, "o-", ms=2.5, lw=1, label=f"Terrace {a.label}")
    ax[0].plot(ht * 1e3, hf, "k--", lw=1.2, label=f"Hertz, T = {T * 1e3:.1f} ms")
    ax[0].set_xlim(-0.1 * T * 1e3, 1.3 * T * 1e3)
    ax[0].set_xlabel("time since contact start (ms)")
    ax[0].set_ylabel("contact force (N)")
    ax[0].set_title(f"contact {duration * 1e3:.1f} ms vs Hertz {T * 1e3:.1f} ms, e = {e_rest:.3f}")
    ax[0].legend()
    Kt = np.array([r["Kt1"] + r["Kt2"] for r in rows])
    Kr = np.array([r["Kr1"] + r["Kr2"] for r in rows])
    Kv = np.array([r["K1"] + r["K2"] for r in rows]) - Kt - Kr
    El = np.array([r["el1"] + r["el2"] for r in rows])
    Ec = np.array([r["Ec"] for r in rows])
    ax[1].stackplot(tt * 1e3, Kt, Kr, Kv, El, Ec, labels=["translation", "rotation", "vibration (kinetic)",
                                                          "elastic", "contact"])
    ax[1].plot(tt * 1e3, Etot, "k", lw=0.8, label="total")
    ax[1].axvspan(t_start * 1e3, t_end * 1e3, color="grey", alpha=0.15)
    ax[1].set_xlabel("time (ms)")
    ax[1].set_ylabel("energy (J)")
    ax[1].set_title("energy split (grey: contact)")
    ax[1].legend(fontsize=7, loc="lower left")
    save(fig, a.plot, dpi=110)
if a.snapshots:
    import matplotlib
    from terrace_tools.plotting import plt, save
    from matplotlib.collections import PolyCollection
    ipk = int(np.argmax(Fc))
    picks = [max(i0 - 1, 0), (i0 + ipk) // 2, ipk, (ipk + i1) // 2, min(i1 + 1 + (i1 - i0) // 4, nf - 1)]
    fig, ax = plt.subplots(1, len(picks), figsize=(3.2 * len(picks), 3.4))
    # the tetrahedra cut by the plane z = 0, drawn as their xy outline (triangles of their nodes
    # nearest the plane), coloured by the strain-energy density W (log scale)
    cut = np.ptp(np.sign(X[tets][:, :, 2]), axis=1) > 0
    vmax = None
    for k, t in enumerate(picks):
        x = pos[t]
        w = neohookean_energy(x, tets[cut], dminv[cut], v0[cut], lam, mu) / v0[cut]
        polys = []
        for e in np.where(cut)[0]:
            p = x[tets[e]]
            o = np.argsort(np.abs(p[:, 2]))[:3]
            polys.append(p[o, :2])
        wl = np.log10(np.maximum(w, 1.0))
        if vmax is None:
            vmax = np.log10(max(np.max(neohookean_energy(pos[ipk], tets[cut], dminv[cut], v0[cut], lam, mu) /
                                       v0[cut]), 10.0))
        pc = PolyCollection(polys, array=wl, cmap="viridis", edgecolors="k", linewidths=0.15, clim=(0, vmax))
        ax[k].add_collection(pc)
        c = 0.5 * (rows[t]["c1"] + rows[t]["c2"])
        ax[k].set_xlim(c[0] - 2.3 * R, c[0] + 2.3 * R)
        ax[k].set_ylim(-1.3 * R, 1.3 * R)
        ax[k].set_aspect("equal")
        ax[k].set_title(f"t = {tt[t] * 1e3:.1f} ms, F = {Fc[t]:.0f} N", fontsize=9)
        ax[k].set_xticks([]); ax[k].set_yticks([])
    fig.colorbar(pc, ax=ax, shrink=0.8, label="log10 W (J/m^3)")
    fig.suptitle(f"two rubber balls {a.label}: section z = 0 (tetrahedra cut by it), strain-energy density", fontsize=10)
    save(fig, a.snapshots, dpi=110, tight=False, bbox_inches="tight")
