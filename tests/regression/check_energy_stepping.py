#!/usr/bin/env python3
"""Conservation checks on an energy-stepping thermo CSV.

  * the terraced energy K + k h (column e_terraced) is constant to --eh-tol relative;
  * the true energy stays in the band the method guarantees: |K + V - E0| <= h (1 + --band-slack),
    E0 the initial K + V;
  * total linear momentum stays at its initial value within --p-tol (absolute);
  * with --angular, the angular momentum (lx, ly, lz) too, within --l-tol (absolute);
  * with --max-rays-per-event X, the event solver's cost: the ray evaluations per event that the run
    log beside the CSV (terrace.log) reports are at most X.
Prints the measured figures and the number of events.

usage: check_energy_stepping.py THERMO.csv [--eh-tol 1e-12] [--p-tol 1e-10] [--angular --l-tol 1e-10]
                                [--max-rays-per-event X]
"""
import argparse
import csv
import os
import sys

from terrace_tools import summary


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("csv")
    ap.add_argument("--eh-tol", type=float, default=1e-12)
    ap.add_argument("--band-slack", type=float, default=1e-6)
    ap.add_argument("--p-tol", type=float, default=1e-10)
    ap.add_argument("--angular", action="store_true")
    ap.add_argument("--l-tol", type=float, default=1e-10)
    ap.add_argument("--min-events", type=int, default=1)
    ap.add_argument("--max-rays-per-event", type=float, default=None)
    a = ap.parse_args()
    rows = list(csv.DictReader(open(a.csv)))
    val = lambda r, k: float(r[k].replace("D", "E"))
    if len(rows) < 2:
        print(f"FAIL: {a.csv}: fewer than 2 thermo rows")
        return 1
    h = val(rows[0], "terrace_height")
    eh0 = val(rows[0], "e_terraced")
    e0 = val(rows[0], "etotal")
    eh_dev = max(abs(val(r, "e_terraced") - eh0) for r in rows) / abs(eh0)
    band = max(abs(val(r, "etotal") - e0) for r in rows)
    p0 = [val(rows[0], k) for k in ("px", "py", "pz")]
    dp = max(abs(val(r, k) - p0[i]) for r in rows for i, k in enumerate(("px", "py", "pz")))
    l0 = [val(rows[0], k) for k in ("lx", "ly", "lz")]
    dl = max(abs(val(r, k) - l0[i]) for r in rows for i, k in enumerate(("lx", "ly", "lz")))
    events = int(val(rows[-1], "events"))
    print(f"events                      {events}")
    print(f"max |E_h(t) - E_h(0)|/|E_h| {eh_dev:.3e}   (bound {a.eh_tol:.1e})")
    print(f"max |K + V - E0| / h        {band / h:.6f}   (bound 1 + {a.band_slack:.0e})")
    print(f"max |P(t) - P(0)|           {dp:.3e}   (bound {a.p_tol:.1e})")
    print(f"max |L(t) - L(0)|           {dl:.3e}   " + (f"(bound {a.l_tol:.1e})" if a.angular else "(not checked)"))
    ok = (eh_dev <= a.eh_tol and band <= h * (1 + a.band_slack) and dp <= a.p_tol
          and (not a.angular or dl <= a.l_tol) and events >= a.min_events)
    if a.max_rays_per_event is not None:
        path = os.path.join(os.path.dirname(os.path.abspath(a.csv)), "deck.summary.json")   # run_and_check.sh's
        rays = summary.get(path, "energy_stepping/ray_evaluations_per_event", float("inf")) \
            if os.path.exists(path) else float("inf")
        print(f"ray evaluations per event   {rays:.3f}   (bound {a.max_rays_per_event})")
        ok = ok and rays <= a.max_rays_per_event
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
