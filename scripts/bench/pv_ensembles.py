#!/usr/bin/env python3
"""The checks of scripts/bench/pv_ensembles.sh: physical_validation.ensemble.check on Terrace's
thermo files (metal units; rows after --eq ps). Prints one line per check: the estimated and the
true ratio (beta_2/beta_1, or the pressure difference) and the deviation in standard deviations;
exits 1 when any check lies beyond 3 of them.

usage: pv_ensembles.py [--eq 50] [--styles "c_rescale mc"] [--thermostats "..."] WORKDIR
"""
import argparse
import io
import os
import contextlib
import sys

import numpy as np
import physical_validation as pv

N = 864
UNITS = pv.data.UnitData(kb=8.617343e-5, energy_conversion=96.485332, length_conversion=0.1,
                         volume_conversion=1e-3, temperature_conversion=1.0, pressure_conversion=1.0,
                         time_conversion=1.0, energy_str="eV", length_str="A", volume_str="A^3",
                         temperature_str="K", pressure_str="bar", time_str="ps")


def load(path, eq):
    with open(path) as f:
        header = f.readline().strip().split(",")
    d = np.loadtxt(path, delimiter=",", skiprows=1)
    keep = d[:, header.index("time")] > eq
    col = lambda k: d[keep, header.index(k)] if k in header else None
    return col("pe"), col("vol")


def sim(path, eq, t, p=None, volume=None):
    pe, vol = load(path, eq)
    if p is None:
        ens = pv.data.EnsembleData("NVT", natoms=N, volume=volume, temperature=t)
        obs = pv.data.ObservableData(potential_energy=pe)
    else:
        ens = pv.data.EnsembleData("NPT", natoms=N, pressure=p, temperature=t)
        obs = pv.data.ObservableData(potential_energy=pe, volume=vol)
    return pv.data.SimulationData(units=UNITS, ensemble=ens, observables=obs)


def check(name, a, b):
    out = io.StringIO()
    try:
        with contextlib.redirect_stdout(out):
            q = pv.ensemble.check(a, b, verbosity=0)
    except Exception as e:      # too little overlap between the two state points' distributions
        print(f"{name:44s} FAIL: {str(e).splitlines()[0][:160]}")
        return False
    q = np.atleast_1d(q)
    worst = float(np.max(np.abs(q)))
    ok = worst <= 3
    print(f"{name:44s} deviation from the true ratio: {', '.join(f'{x:.2f}' for x in q)} sigma  "
          f"{'pass' if ok else 'FAIL'}")
    return ok


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("work")
    ap.add_argument("--eq", type=float, default=50.0)
    ap.add_argument("--styles", default="c_rescale mc")
    ap.add_argument("--thermostats", default="langevin csvr nose_hoover andersen")
    a = ap.parse_args()
    os.chdir(a.work)
    ok = True
    for s in a.styles.split():
        base = sim(f"npt_{s}_T94.4_P1.csv", a.eq, 94.4, 1.0)
        ok &= check(f"NPT {s}: 94.4 K vs 97 K at 1 bar", base, sim(f"npt_{s}_T97_P1.csv", a.eq, 97.0, 1.0))
        ok &= check(f"NPT {s}: 1 bar vs 31 bar at 94.4 K", base, sim(f"npt_{s}_T94.4_P31.csv", a.eq, 94.4, 31.0))
    vol = (6 * 5.780150) ** 3
    for t in a.thermostats.split():
        ok &= check(f"NVT {t}: 94.4 K vs 97 K", sim(f"nvt_{t}_T94.4.csv", a.eq, 94.4, volume=vol),
                    sim(f"nvt_{t}_T97.csv", a.eq, 97.0, volume=vol))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
