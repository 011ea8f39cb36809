#!/usr/bin/env python3
"""Figures and numbers of doc/analysis.md from the CSVs of scripts/bench/analysis_examples.sh,
next to published values:
  Cu:    neutron-scattering phonon dispersion (Svensson, Brockhouse & Rowe, Phys. Rev. 155, 619
         (1967)): the highest frequency is about 7.2-7.3 THz; the VDOS has a transverse peak near 5 THz
         and a longitudinal peak near 7 THz.
  Argon: Rahman, Phys. Rev. 136, A405 (1964), 864 atoms at 94.4 K and 1.374 g/cm^3: g(r) first peak
         at about 3.7 A with height about 3; S(q) first peak near 2.0 A^-1; D = 2.43e-5 cm^2/s.
usage: analysis_figures.py WORK_DIR FIGURE_DIR
"""
import os
import sys

import numpy as np

from terrace_tools import analysis, thermo
from terrace_tools.plotting import plt, save

work, figs = sys.argv[1], sys.argv[2]
load = analysis.array                       # terrace-analyze's CSVs as (rows, columns) arrays


# ---------------------------------------------------------------- Cu VDOS
d = load(os.path.join(work, "cu", "cu_vdos.csv"))
nu, g = d[:, 0], d[:, 1] / 12000.0                      # per degree of freedom: integrates to 1
t_cu = thermo.read(os.path.join(work, "cu", "prod.csv"))["temp"].mean()
mt, ml = (nu > 3) & (nu < 6), (nu > 6) & (nu < 8.5)
pt, pl = nu[mt][np.argmax(g[mt])], nu[ml][np.argmax(g[ml])]
il = np.flatnonzero(ml)[np.argmax(g[ml])]
half = nu[il:][np.argmax(g[il:] < 0.5 * g[il])]
print(f"Cu (Cu_u3.eam, 4000 atoms, {t_cu:.0f} K): transverse peak {pt:.2f} THz, longitudinal peak {pl:.2f} THz, "
      f"half maximum above it at {half:.2f} THz")
fig, ax = plt.subplots(figsize=(6.5, 4))
ax.plot(nu, g, lw=1.2, label=f"Terrace, Cu_u3.eam, {t_cu:.0f} K (VACF 5 ps, Hann)")
ax.axvspan(7.2, 7.3, color="tab:red", alpha=0.3, label="highest frequency, neutron data (7.2-7.3 THz)")
ax.axvline(5.0, color="grey", ls=":", lw=1, label="transverse / longitudinal peaks (~5, ~7 THz)")
ax.axvline(7.0, color="grey", ls=":", lw=1)
ax.set_xlim(0, 10)
ax.set_xlabel("frequency (THz)")
ax.set_ylabel("VDOS per degree of freedom (1/THz)")
ax.legend(fontsize=7, loc="upper left")
save(fig, os.path.join(figs, "analysis_cu_vdos.png"), dpi=120)

# ---------------------------------------------------------------- argon g(r), S(q), MSD
a = os.path.join(work, "argon")
t_ar = thermo.read(os.path.join(a, "prod.csv"))["temp"]
rdf, sq, msd, dif = (load(os.path.join(a, f"argon_{k}.csv")) for k in ("rdf", "sq", "msd", "diffusion"))
i, j = np.argmax(rdf[:, 1]), np.argmax(sq[:, 1])
far = (rdf[:, 0] > 12) & (rdf[:, 0] < 17)
print(f"argon ({t_ar.mean():.1f} +- {t_ar.std():.1f} K): g(r) peak {rdf[i, 1]:.2f} at {rdf[i, 0]:.2f} A "
      f"(Rahman: ~3 at 3.7 A); g over 12-17 A {rdf[far, 1].mean():.4f}; S(q) peak {sq[j, 1]:.2f} at "
      f"{sq[j, 0]:.2f} A^-1 (~2.0); D = {dif[0, 6]:.3e} +- {dif[0, 7]:.1e} cm^2/s "
      f"(blocks mean {dif[0, 2] * 1e-4:.3e}; Rahman 2.43e-5 at 94.4 K)")
fig, axes = plt.subplots(1, 3, figsize=(13, 3.8))
axes[0].plot(rdf[:, 0], rdf[:, 1], lw=1.2, label=f"Terrace, {t_ar.mean():.1f} K")
axes[0].plot([3.7], [3.0], "rx", ms=8, label="Rahman 1964: ~3 at 3.7 A")
axes[0].axhline(1, color="grey", lw=0.5)
axes[0].set_xlabel("r (A)")
axes[0].set_ylabel("g(r)")
axes[0].legend(fontsize=8)
axes[1].plot(sq[:, 0], sq[:, 1], ".-", lw=1, ms=3, label="Terrace (reciprocal lattice, bins 0.05 A^-1)")
axes[1].axvline(2.0, color="tab:red", ls=":", label="first peak ~2.0 A^-1")
axes[1].set_xlabel("q (1/A)")
axes[1].set_ylabel("S(q)")
axes[1].legend(fontsize=8, loc="lower right")
axes[2].plot(msd[:, 0], msd[:, 1], lw=1.2, label="MSD (5 blocks: band = standard error)")
axes[2].fill_between(msd[:, 0], msd[:, 1] - msd[:, 2], msd[:, 1] + msd[:, 2], alpha=0.3)
tt = np.linspace(0, msd[-1, 0], 50)
axes[2].plot(tt, 6 * 2.43e-5 * 1e4 * tt, "r--", lw=1, label="6 D t, Rahman D = 2.43e-5 cm^2/s")
axes[2].set_xlabel("t (ps)")
axes[2].set_ylabel("MSD (A^2)")
axes[2].set_title(f"D = {dif[0, 6]:.3e} +- {dif[0, 7]:.1e} cm^2/s", fontsize=9)
axes[2].legend(fontsize=8)
save(fig, os.path.join(figs, "analysis_argon_liquid.png"), dpi=120)
print(f"wrote {figs}/analysis_cu_vdos.png, {figs}/analysis_argon_liquid.png")
