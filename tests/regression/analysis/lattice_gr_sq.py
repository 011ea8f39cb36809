#!/usr/bin/env python3
"""terrace-analyze g(r) and S(q) on structures with exact answers.

1. Perfect fcc lattice (a = 4, 4x4x4 cells, 256 atoms; two frames, the second translated by a
   random vector and wrapped): the running coordination number n(r) between the neighbour shells is
   12, 18, 42, 54, 78, 86, 134 (shells of 12, 6, 24, 12, 24, 8, 48 at a sqrt(k/2)); g(r) is zero
   between the shells; the same on 2 ranks.
2. S(q) of that lattice: |rho(q)|^2 / N is N on the fcc reciprocal lattice (h, k, l all even or all
   odd, in units 2 pi / a) and 0 elsewhere, so sum over bins of (vectors x S) = N x (number of such
   vectors with 0 < |q| <= q_max in a half-space) = 256 x 29 for q_max = 6 (to 1e-8).
3. A free 13-atom cuboctahedron (non-periodic box): the pair-distance density integrates to 1 and
   n(r) after the first shell is 2 x 36 / 13 (12 bonds of the centre, 24 on the surface).

usage: lattice_gr_sq.py TERRACE_ANALYZE WORKDIR
"""
import itertools
import os
import sys

import numpy as np

from common import Checks, read_csv, run, write_h5md  # noqa: E402

exe, work = os.path.abspath(sys.argv[1]), sys.argv[2]
os.makedirs(work, exist_ok=True)
os.chdir(work)
c = Checks()
rng = np.random.default_rng(7)

a, cells = 4.0, 4
L = a * cells
basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
sites = np.array([(np.array(cell) + b) * a for cell in itertools.product(range(cells), repeat=3) for b in basis])
n = len(sites)
frame2 = np.mod(sites + rng.uniform(0, L, 3), L)
x = np.stack([sites, frame2])
write_h5md("fcc.h5", 3, positions=x, times=[0.0, 1.0], edges=[L, L, L])
args = ["--trajectory_file=fcc.h5", "--compute=rdf,sq", "--rdf_bins=800", "--sq_q_max=6.0"]
run(exe, args + ["--output_prefix=f1"])
run(exe, args + ["--output_prefix=f2"], nprocs=2)
_, r1 = read_csv("f1_rdf.csv")
_, r2 = read_csv("f2_rdf.csv")
r, g, ncum = r1[:, 0], r1[:, 1], r1[:, 2]
shells = a * np.sqrt(np.arange(1, 9) / 2.0)           # 2.83, 4, 4.90, 5.66, 6.32, 6.93, 7.48, 8
expected = [12, 18, 42, 54, 78, 86, 134]
for k, want in enumerate(expected):
    rm = 0.5 * (shells[k] + shells[k + 1])
    i = np.searchsorted(r, rm)
    c.check(abs(ncum[i] - want) < 1e-9, f"n(r = {rm:.3f}) = {ncum[i]:.6f}, expected {want}")
off = np.ones_like(r, dtype=bool)
for s in shells:
    off &= np.abs(r - s) > 0.02
c.check(np.all(g[off] == 0), "g(r) = 0 between the shells")
c.check(np.allclose(r2, r1, rtol=1e-12, atol=0), "g(r) on 2 ranks = 1 rank")

_, sq = read_csv("f1_sq.csv")
hkl = [v for v in itertools.product(range(-4, 5), repeat=3) if any(v)
       and (all(t % 2 == 0 for t in v) or all(t % 2 != 0 for t in v))
       and np.linalg.norm(v) * 2 * np.pi / a <= 6.0]
bragg_half = len(hkl) // 2
total = (sq[:, 1] * sq[:, 2]).sum()
c.check(abs(total - n * bragg_half) < 1e-8 * n * bragg_half,
        f"sum of S over q vectors = {total:.9f} = N x {bragg_half} Bragg vectors = {n * bragg_half}")
q111 = 2 * np.pi / a * np.sqrt(3)
i = np.argmin(np.abs(sq[:, 0] - q111))
c.check(sq[i, 1] > 1.0, f"S(q) bin at the (111) reflection q = {sq[i, 0]:.4f} is a Bragg peak (S = {sq[i, 1]:.2f})")

# ---------------------------------------------------------------- free cuboctahedron
d = 2.5
cub = [np.zeros(3)] + [d / np.sqrt(2) * np.array(v) for v in itertools.product([-1, 0, 1], repeat=3)
                       if sum(abs(t) for t in v) == 2]
cub = np.array(cub) + 20.0
write_h5md("cluster.h5", 3, positions=cub[None], times=[0.0], boundary=["none"] * 3)
run(exe, ["--trajectory_file=cluster.h5", "--compute=rdf", "--rdf_bins=500", "--rdf_r_max=10.0",
          "--output_prefix=cl"])
hdr, cl = read_csv("cl_rdf.csv")
dr = cl[1, 0] - cl[0, 0]
c.check(hdr[1].startswith("pair_density"), f"free cluster: column 2 is the pair-distance density ({hdr[1]})")
c.check(abs(cl[:, 1].sum() * dr - 1) < 1e-12, f"free cluster: integral of p(r) = {cl[:, 1].sum() * dr:.15f}")
i = np.searchsorted(cl[:, 0], 0.5 * (d + d * np.sqrt(2)))
c.check(abs(cl[i, 2] - 72 / 13) < 1e-12, f"free cluster: n(r) after the first shell = {cl[i, 2]:.6f} = 72/13")
c.finish()
