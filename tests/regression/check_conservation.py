#!/usr/bin/env python3
"""Conservation checks on a Terrace thermo CSV (velocity Verlet, NVE).

Asserts that the total linear momentum (px, py, pz) stays at its initial value to round-off:
|P(t) - P(0)| <= tol * sqrt(N m_avg k T)-scale, given here as an absolute bound --p-tol, and that the
total energy stays within --e-tol (relative to |E0|) of its initial value. Prints the energy drift
per atom per time unit from a least-squares fit of etotal(t).

usage: check_conservation.py THERMO.csv NATOMS [--p-tol 1e-10] [--e-tol 1e-3]
"""
import argparse
import csv
import sys


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("csv")
    ap.add_argument("natoms", type=int)
    ap.add_argument("--p-tol", type=float, default=1e-10)
    ap.add_argument("--e-tol", type=float, default=1e-3)
    a = ap.parse_args()
    rows = list(csv.DictReader(open(a.csv)))
    if len(rows) < 3:
        print(f"FAIL: {a.csv}: need at least 3 thermo rows, got {len(rows)}")
        return 1
    f = lambda r, k: float(r[k].replace("D", "E"))
    p0 = [f(rows[0], k) for k in ("px", "py", "pz")]
    dp = max(max(abs(f(r, k) - p0[i]) for i, k in enumerate(("px", "py", "pz"))) for r in rows)
    e0 = f(rows[0], "etotal")
    de = max(abs(f(r, "etotal") - e0) for r in rows)
    t = [f(r, "time") for r in rows]
    e = [f(r, "etotal") for r in rows]
    n = len(t)
    tm, em = sum(t) / n, sum(e) / n
    slope = sum((ti - tm) * (ei - em) for ti, ei in zip(t, e)) / sum((ti - tm) ** 2 for ti in t)
    print(f"max |P(t) - P(0)|        = {dp:.3e}   (bound {a.p_tol:.1e})")
    print(f"max |E(t) - E0| / |E0|   = {de / abs(e0):.3e}   (bound {a.e_tol:.1e})")
    print(f"energy drift (fit)       = {slope / a.natoms:.3e} energy/atom/time")
    ok = dp <= a.p_tol and de / abs(e0) <= a.e_tol
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
