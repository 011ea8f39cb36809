#!/usr/bin/env python3
"""The comparison table of scripts/bench/barostat_npt.sh: density and isothermal compressibility
kappa_T = <dV^2> / (k_B T <V>) of each run, with standard errors from BLOCKS block averages (kappa_T
computed per block), LAMMPS's `fix npt` (lmp_npt.log, its production run) against each Terrace style
(<style>.csv, rows after --eq ps). A style passes when both quantities lie within 2 combined
standard errors of LAMMPS's.

usage: barostat_npt_table.py [--blocks 20] [--eq 100] [--temperature 94.4] WORKDIR
"""
import argparse
import os
import sys

import numpy as np

KB = 8.617343e-5            # eV/K (metal units, as LAMMPS)
EV_PER_A3_TO_BAR = 1.6021765e6
AMU_G = 1.66053906660e-24   # g
N, MASS = 864, 39.948


def lammps_volumes(path):
    """Volumes of the last run's thermo block (the production run after reset_timestep)."""
    blocks, cur, cols = [], None, None
    for line in open(path):
        w = line.split()
        if w[:1] == ["Step"]:
            cols = w
            cur = []
            blocks.append(cur)
            continue
        if cur is not None:
            if w and w[0].lstrip("-").isdigit() and len(w) == len(cols):
                cur.append(float(w[cols.index("Volume")]))
            elif w[:2] == ["Loop", "time"]:
                cur = None
    return np.array(blocks[-1])


def terrace_volumes(path, eq):
    with open(path) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1)
    t, v = data[:, header.index("time")], data[:, header.index("vol")]
    return v[t > eq]


def stats(v, blocks, temperature):
    """(density, its SE, kappa_T in 1/bar, its SE, samples)."""
    rho = N * MASS * AMU_G / (v * 1e-24)
    nb = len(v) // blocks
    dens, kap = [], []
    for b in range(blocks):
        vb = v[b * nb:(b + 1) * nb]
        dens.append(rho[b * nb:(b + 1) * nb].mean())
        kap.append(vb.var() / (KB * temperature * vb.mean()) / EV_PER_A3_TO_BAR)
    dens, kap = np.array(dens), np.array(kap)
    kall = v.var() / (KB * temperature * v.mean()) / EV_PER_A3_TO_BAR
    return rho.mean(), dens.std(ddof=1) / np.sqrt(blocks), kall, kap.std(ddof=1) / np.sqrt(blocks), len(v)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("work")
    ap.add_argument("--blocks", type=int, default=20)
    ap.add_argument("--eq", type=float, default=100.0)
    ap.add_argument("--temperature", type=float, default=94.4)
    a = ap.parse_args()
    rows = {}
    lp = os.path.join(a.work, "lmp_npt.log")
    if os.path.exists(lp):
        rows["LAMMPS fix npt"] = stats(lammps_volumes(lp), a.blocks, a.temperature)
    for style in ("c_rescale", "mc", "mttk", "mc_es"):
        p = os.path.join(a.work, style + ".csv")
        if os.path.exists(p):
            rows["Terrace " + style] = stats(terrace_volumes(p, a.eq), a.blocks, a.temperature)
    print(f"{'run':18s} {'samples':>8s} {'density (g/cm^3)':>22s} {'kappa_T (1e-4/bar)':>22s}  within 2 SE of LAMMPS")
    ref = rows.get("LAMMPS fix npt")
    ok = True
    for name, (d, sd, k, sk, n) in rows.items():
        verdict = ""
        if ref is not None and name != "LAMMPS fix npt":
            zd = abs(d - ref[0]) / np.hypot(sd, ref[1])
            zk = abs(k - ref[2]) / np.hypot(sk, ref[3])
            good = zd <= 2 and zk <= 2
            ok &= good
            verdict = f"density {zd:.2f} SE, kappa {zk:.2f} SE: {'yes' if good else 'NO'}"
        print(f"{name:18s} {n:8d} {d:12.5f} +- {sd:7.5f} {k*1e4:12.4f} +- {sk*1e4:6.4f}  {verdict}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
