#!/usr/bin/env python3
"""terrace-analyze on trajectories with exact answers.

1. VDOS of independent 3-D harmonic oscillators (8 atoms; every Cartesian component oscillates
   at one of 1.0, 2.5, 4.0 THz, with amplitude giving equal energy per degree of freedom; random
   phases). Written analytically (x = A cos(w t + p), v = -A w sin(w t + p)). Checks: the VDOS
   integrates to 3N = 24 (to 1e-9), has exactly three maxima above 5 % of the highest, each within the
   resolution 1/(M dt) of a known frequency, with areas (degrees of freedom in each band) within
   10 % of the counts; the same VDOS on 2 ranks (1e-10); the same with the time given as a scalar
   step with an offset attribute and the box as a time-dependent element (1e-12).
2. MSD of ballistic atoms in a periodic box (positions wrapped, images written): MSD(tau) =
   <|v|^2> tau^2 exactly (1e-9 relative), on 1 and 2 ranks.
3. MSD of a random walk (1000 atoms, 2000 steps) with D = 0.5 A^2/ps: D within 4 block error bars
   (10 blocks) and 5 %, error bar < 10 %.

usage: harmonic_and_msd.py TERRACE_ANALYZE WORKDIR
"""
import os
import sys

import numpy as np

from common import Checks, read_csv, run, write_h5md  # noqa: E402

exe, work = os.path.abspath(sys.argv[1]), sys.argv[2]
os.makedirs(work, exist_ok=True)
os.chdir(work)
c = Checks()
rng = np.random.default_rng(20261122)

# ---------------------------------------------------------------- 1. harmonic VDOS
freqs = np.array([1.0, 2.5, 4.0])             # THz
n_atoms, dt, n_frames, corr = 8, 0.02, 2000, 10.0
assign = rng.integers(0, 3, size=(n_atoms, 3))
assign.flat[:3] = [0, 1, 2]                   # every frequency present
omega = 2 * np.pi * freqs[assign]             # (N, 3) rad/ps
amp = 0.1 / omega                             # equal energy per degree of freedom
phase = rng.uniform(0, 2 * np.pi, size=(n_atoms, 3))
t = np.arange(n_frames) * dt
arg = omega[None] * t[:, None, None] + phase[None]
x = amp[None] * np.cos(arg) + 10.0
v = -amp[None] * omega[None] * np.sin(arg)
write_h5md("harmonic.h5", 3, positions=x, velocities=v, times=t, edges=[30.0, 30.0, 30.0],
           mass=np.full(n_atoms, 39.948))
write_h5md("harmonic_scalar_time.h5", 3, positions=x, velocities=v, scalar_time=(dt, 0.0),
           edges=[30.0, 30.0, 30.0], edges_series=True, vl_strings=False)

args = ["--compute=vdos", f"--correlation_time={corr}"]
run(exe, ["--trajectory_file=harmonic.h5", "--output_prefix=h1"] + args)
run(exe, ["--trajectory_file=harmonic.h5", "--output_prefix=h2"] + args, nprocs=2)
run(exe, ["--trajectory_file=harmonic_scalar_time.h5", "--output_prefix=hs"] + args)
_, d1 = read_csv("h1_vdos.csv")
_, d2 = read_csv("h2_vdos.csv")
_, ds = read_csv("hs_vdos.csv")
nu, g = d1[:, 0], d1[:, 1]
dnu = nu[1] - nu[0]
integral = dnu * (g.sum() - 0.5 * (g[0] + g[-1]))
c.check(abs(integral - 3 * n_atoms) < 1e-9 * 3 * n_atoms, f"VDOS integral {integral:.12f} = 3N = {3 * n_atoms}")
resolution = 1.0 / corr
peaks = [i for i in range(1, len(g) - 1) if g[i] >= g[i - 1] and g[i] > g[i + 1] and g[i] > 0.05 * g.max()]
c.check(len(peaks) == 3, f"three maxima above 5 % of the highest (found {len(peaks)} at {nu[peaks]})")
for f0 in freqs:
    near = [nu[i] for i in peaks if abs(nu[i] - f0) <= resolution]
    c.check(len(near) == 1, f"peak at {f0} THz: found {near} (resolution 1/(M dt) = {resolution} THz)")
    band = (nu > f0 - 0.6) & (nu < f0 + 0.6)
    area = dnu * g[band].sum()
    count = (freqs[assign] == f0).sum()
    c.check(abs(area - count) < 0.1 * count, f"area of the {f0} THz band {area:.3f} ~ its {count} degrees of freedom")
c.check(np.allclose(d2, d1, rtol=1e-10, atol=1e-10 * g.max()), "VDOS on 2 ranks = 1 rank (1e-10)")
c.check(np.allclose(ds, d1, rtol=1e-12, atol=1e-12 * g.max()),
        "scalar time + offset, fixed-length boundary strings, box/edges/value: same VDOS (1e-12)")

# ---------------------------------------------------------------- 2. ballistic MSD (images)
n_atoms, n_frames, dt, L = 50, 400, 0.1, 12.0
x0 = rng.uniform(0, L, size=(n_atoms, 3))
vel = rng.normal(0, 3.0, size=(n_atoms, 3))
t = np.arange(n_frames) * dt
u = x0[None] + vel[None] * t[:, None, None]
img = np.floor(u / L).astype(np.int32)
xw = u - img * L
write_h5md("ballistic.h5", 3, positions=xw, images=img, times=t, edges=[L, L, L], edges_series=True)
margs = ["--trajectory_file=ballistic.h5", "--compute=msd", "--msd_blocks=4", "--msd_max_time=4.0"]
run(exe, margs + ["--output_prefix=b1"])
run(exe, margs + ["--output_prefix=b2"], nprocs=2)
_, m1 = read_csv("b1_msd.csv")
_, m2 = read_csv("b2_msd.csv")
exact = (vel ** 2).sum(axis=1).mean() * m1[:, 0] ** 2
c.check(np.allclose(m1[:, 1], exact, rtol=1e-9, atol=1e-9), "ballistic MSD = <v^2> tau^2 with images (1e-9)")
c.check(np.allclose(m2[:, 1], m1[:, 1], rtol=1e-12, atol=1e-12 * m1[:, 1].max()), "ballistic MSD on 2 ranks = 1 rank (1e-12)")

# ---------------------------------------------------------------- 3. random walk D
n_atoms, n_frames, dt, D = 1000, 2000, 0.05, 0.5
steps = rng.normal(0, np.sqrt(2 * D * dt), size=(n_frames, n_atoms, 3))
steps[0] = 0
u = np.cumsum(steps, axis=0) + rng.uniform(0, L, size=(n_atoms, 3))[None]
img = np.floor(u / L).astype(np.int32)
write_h5md("walk.h5", 3, positions=u - img * L, images=img, times=np.arange(n_frames) * dt, edges=[L, L, L])
run(exe, ["--trajectory_file=walk.h5", "--compute=msd", "--msd_blocks=10", "--output_prefix=w"])
_, dd = read_csv("w_diffusion.csv")
d_est, d_err = dd[0, 0], dd[0, 1]
c.check(abs(d_est - D) < 4 * d_err and abs(d_est - D) < 0.05 * D,
        f"random walk: D = {d_est:.4f} +- {d_err:.4f} against 0.5")
c.check(0 < d_err < 0.1 * D, f"random walk: error bar {d_err:.4f} is below 10 %")
c.finish()
