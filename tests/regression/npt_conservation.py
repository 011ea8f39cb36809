#!/usr/bin/env python3
"""The conserved quantity of a barostat run (thermo econserve = etotal + P0 V + the barostat's own
energy - ecouple) on an LJ liquid at two time steps.

Runs the same deck (256 atoms, T* = 1.2, P* = 0.5, the same 5 tau) at dt and dt/2 and takes from
each run's thermo the largest excursion of econserve from its first value, per atom. Asserts that
it is small at dt (--max-err, energy per atom) and, unless --no-ratio, that it falls like dt^2: the
ratio of the two excursions within [--ratio-lo, --ratio-hi] (4 for a second-order integrator and a
complete conserved quantity; a term missing from econserve leaves a part that does not shrink with
dt). Also asserts that the box did change (the barostat acted): the volume's range over the run is
more than 0.1 % of its mean; with --aniso (couple = 'aniso') also that the edges moved apart: lx/ly
differs from its first value by more than 1e-3 somewhere in the run.

usage: npt_conservation.py TERRACE OUTDIR THERMOSTAT_LINE BAROSTAT_LINE [--dt 0.005] [--max-err ...]
"""
import argparse
import csv
import os
import subprocess
import sys

DECK = """&run units='lj', dimension=3, n_steps={n}, seed=4242 /
&system lattice='fcc', density=0.8442, cells=4,4,4, periodic=.true.,.true.,.true., mass=1.0, temperature=1.44 /
&potential style='lj/smooth/linear', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&integrator style='velocity_verlet', dt={dt!r} /
&neighbor skin=0.3 /
{thermostat}
{barostat}
&output thermo_every={every}, thermo_file='thermo.csv' /
"""


def run(terrace, outdir, dt, n, every, thermostat, barostat):
    os.makedirs(outdir, exist_ok=True)
    with open(os.path.join(outdir, "run.nml"), "w") as f:
        f.write(DECK.format(n=n, dt=dt, every=every, thermostat=thermostat, barostat=barostat))
    r = subprocess.run([terrace, "run.nml"], cwd=outdir, capture_output=True, text=True, timeout=600)
    if r.returncode != 0:
        print(f"FAIL: terrace in {outdir} exited {r.returncode}:\n{r.stdout[-2000:]}{r.stderr[-2000:]}")
        sys.exit(1)
    rows = list(csv.DictReader(open(os.path.join(outdir, "thermo.csv"))))
    ec = [float(row["econserve"]) for row in rows]
    vol = [float(row["vol"]) for row in rows]
    shape = [float(row["box_lx"]) / float(row["box_ly"]) for row in rows]
    return (max(abs(e - ec[0]) for e in ec) / 256.0, (max(vol) - min(vol)) / (sum(vol) / len(vol)),
            max(abs(q / shape[0] - 1) for q in shape))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("terrace")
    ap.add_argument("outdir")
    ap.add_argument("thermostat")
    ap.add_argument("barostat")
    ap.add_argument("--dt", type=float, default=0.005)
    ap.add_argument("--time", type=float, default=5.0)
    ap.add_argument("--max-err", type=float, default=5e-3)
    ap.add_argument("--ratio-lo", type=float, default=3.0)
    ap.add_argument("--ratio-hi", type=float, default=5.5)
    ap.add_argument("--no-ratio", action="store_true")
    ap.add_argument("--aniso", action="store_true")
    a = ap.parse_args()
    a.terrace = os.path.abspath(a.terrace)
    n = int(round(a.time / a.dt))
    err1, vr1, sh1 = run(a.terrace, os.path.join(a.outdir, "dt"), a.dt, n, 10, a.thermostat, a.barostat)
    print(f"dt = {a.dt}: max |econserve - econserve(0)| / N = {err1:.3e}; volume range / mean = {vr1:.3e}; "
          f"max |(lx/ly) / (lx/ly)(0) - 1| = {sh1:.3e}")
    ok = err1 <= a.max_err and vr1 > 1e-3
    if a.aniso:
        ok = ok and sh1 > 1e-3
    if not a.no_ratio:
        err2, vr2, sh2 = run(a.terrace, os.path.join(a.outdir, "dt2"), a.dt / 2, 2 * n, 20, a.thermostat, a.barostat)
        ratio = err1 / err2 if err2 > 0 else float("inf")
        print(f"dt = {a.dt / 2}: max |econserve - econserve(0)| / N = {err2:.3e}; ratio {ratio:.2f} "
              f"(allowed [{a.ratio_lo}, {a.ratio_hi}])")
        ok = ok and a.ratio_lo <= ratio <= a.ratio_hi
    print("PASS" if ok else f"FAIL (bound {a.max_err:.1e} per atom; the box must move by > 0.1 %)")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
