#!/usr/bin/env python3
"""Rahman's liquid argon, run by terrace and analysed by terrace-analyze (namelist file), against
the published liquid structure and dynamics (Rahman 1964, Phys. Rev. 136, A405; Verlet 1968):
  g(r): highest peak at 3.55-3.85 A, height 2.5-3.3; g -> 1 (mean over 12-17 A within 0.02)
  S(q): highest peak at 1.85-2.10 A^-1
  D from the MSD within 20 % of 2.43e-5 cm^2/s, with a block error bar below 15 %
  VACF: negative minimum (cage back-scattering) between 0.2 and 0.6 ps
  Green-Kubo D = int <v_x(0) v_x(t)> dt (from the VACF) within 15 % of the MSD value.
usage: argon_liquid.py TERRACE TERRACE_ANALYZE DECK ANALYSIS_NML WORKDIR
"""
import os
import shutil
import subprocess
import sys

import numpy as np

from common import MPI_ENV, Checks, read_csv, run  # noqa: E402

terrace, exe, deck, nml, work = [os.path.abspath(a) for a in sys.argv[1:6]]
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
os.chdir(work)
c = Checks()
p = subprocess.run([terrace, deck], env=MPI_ENV, capture_output=True, text=True, timeout=300)
if p.returncode != 0:
    sys.stderr.write(p.stdout + p.stderr)
    raise SystemExit("FAIL: the engine run failed")
_, out, _ = run(exe, [nml], nprocs=2)
print(out)

_, rdf = read_csv("argon_rdf.csv")
r, g = rdf[:, 0], rdf[:, 1]
i = np.argmax(g)
c.check(3.55 <= r[i] <= 3.85 and 2.5 <= g[i] <= 3.3, f"g(r) peak at {r[i]:.3f} A, height {g[i]:.3f}")
far = (r > 12) & (r < 17)
c.check(abs(g[far].mean() - 1) < 0.02, f"g(r) mean over 12-17 A = {g[far].mean():.4f}")
_, sq = read_csv("argon_sq.csv")
j = np.argmax(sq[:, 1])
c.check(1.85 <= sq[j, 0] <= 2.10, f"S(q) peak at {sq[j, 0]:.3f} A^-1 (S = {sq[j, 1]:.3f})")
_, dif = read_csv("argon_diffusion.csv")
d_cm2s, err_cm2s = dif[0, 6], dif[0, 7]
c.check(abs(d_cm2s - 2.43e-5) < 0.2 * 2.43e-5 and err_cm2s < 0.15 * d_cm2s,
        f"D = {d_cm2s:.3e} +- {err_cm2s:.1e} cm^2/s (Rahman: 2.43e-5)")
_, vacf = read_csv("argon_vacf.csv")
k = np.argmin(vacf[:, 1])
c.check(vacf[k, 1] < 0 and 0.2 <= vacf[k, 0] <= 0.6, f"VACF minimum {vacf[k, 1]:.3f} at {vacf[k, 0]:.2f} ps")
dt = vacf[1, 0] - vacf[0, 0]
cxx = vacf[:, 2] / 39.948                         # <v_x(0) v_x(t)> in A^2/ps^2
d_gk = dt * (cxx.sum() - 0.5 * (cxx[0] + cxx[-1]))
d_msd = dif[0, 0]
c.check(abs(d_gk - d_msd) < 0.15 * d_msd, f"Green-Kubo D = {d_gk:.4f} A^2/ps against MSD {d_msd:.4f}")
c.finish()
