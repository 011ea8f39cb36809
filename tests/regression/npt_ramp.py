#!/usr/bin/env python3
"""A barostat under a temperature ramp follows the thermostat's present target temperature.

A dilute LJ gas (256 atoms, rho* about 0.02, where the gas is nearly ideal) under the Monte Carlo
barostat at P* = 0.04 while `&thermostat temperature = 2, temperature_end = 4` ramps the target over
the run. For an ideal gas the Monte Carlo barostat samples V from V^N exp(-P V / k T) with the k T of
its acceptance rule, whatever the atoms' own temperature: its mean is (N + 1) k T / P. Over the last
fifth of the run (targets 3.6 to 4) the mean volume must be within --tol (10 %) of
(N + 1) k <T_target> / P; a barostat that kept the starting k T would give about (N + 1) 2 / P there,
half of it. Also checks the thermostat did ramp: the mean temperature of that fifth within 10 % of
<T_target>. With --couple aniso the same with couple = 'aniso'.

usage: npt_ramp.py TERRACE OUTDIR [--couple iso|aniso] [--tol 0.1]
"""
import argparse
import csv
import os
import subprocess
import sys

N, P, T0, T1, DT, STEPS = 256, 0.04, 2.0, 4.0, 0.005, 60000

DECK = """&run units='lj', dimension=3, n_steps={steps}, seed=2718 /
&system lattice='fcc', density=0.02, cells=4,4,4, periodic=.true.,.true.,.true., mass=1.0, temperature={t0} /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.true. /
&integrator style='velocity_verlet', dt={dt} /
&neighbor skin=0.5 /
&thermostat style='csvr', temperature={t0}, temperature_end={t1}, damping=0.5 /
&barostat style='mc', pressure={p}, couple='{couple}' /
&output thermo_every=100, thermo_file='thermo.csv' /
"""


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("terrace")
    ap.add_argument("outdir")
    ap.add_argument("--couple", default="iso")
    ap.add_argument("--tol", type=float, default=0.1)
    a = ap.parse_args()
    os.makedirs(a.outdir, exist_ok=True)
    with open(os.path.join(a.outdir, "run.nml"), "w") as f:
        f.write(DECK.format(steps=STEPS, t0=T0, t1=T1, dt=DT, p=P, couple=a.couple))
    r = subprocess.run([os.path.abspath(a.terrace), "run.nml"], cwd=a.outdir, capture_output=True, text=True,
                       timeout=900)
    if r.returncode != 0:
        print(f"FAIL: terrace exited {r.returncode}:\n{r.stdout[-2000:]}{r.stderr[-2000:]}")
        return 1
    rows = list(csv.DictReader(open(os.path.join(a.outdir, "thermo.csv"))))
    last = [row for row in rows if int(row["step"]) > 0.8 * STEPS]
    target = [T0 + (T1 - T0) * int(row["step"]) / STEPS for row in last]
    t_mean = sum(target) / len(target)
    v_mean = sum(float(row["vol"]) for row in last) / len(last)
    temp = sum(float(row["temp"]) for row in last) / len(last)
    v_expected = (N + 1) * t_mean / P
    ratio = v_mean / v_expected
    print(f"last fifth: <T_target> = {t_mean:.3f}, <temp> = {temp:.3f}, <V> = {v_mean:.1f}, "
          f"(N + 1) k <T_target> / P = {v_expected:.1f}, ratio {ratio:.3f} (allowed 1 +- {a.tol}); "
          f"with the starting k T: {(N + 1) * T0 / P:.1f}")
    ok = abs(ratio - 1) < a.tol and abs(temp / t_mean - 1) < 0.1
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
