#!/usr/bin/env python3
"""Time reversal of energy stepping on the seven-atom argon cluster.

For each run length T: run T forward (final state written with final_atoms_file), reverse the
velocities and run T again; the positions must come back to the initial ones. The error grows
with T as the cluster's chaos amplifies the root tolerance and round-off; the table shows how.
Asserts max |x_back - x0| <= --bound (Angstrom) for runs up to --assert-events events.

usage: time_reversal.py TERRACE OUTDIR [--bound 1e-8] [--assert-events 100]
"""
import argparse
import os
import subprocess
import sys

from terrace_tools import summary

DECK = """&run units='metal', dimension=2, run_time={T}, seed=1 /
&system atoms_file='{atoms}', periodic=.false.,.false., mass=39.951{rev} /
&potential style='lj', epsilon=0.010323577, sigma=3.41, cutoff=0.0 /
&integrator style='energy_stepping', terrace_height=1.378775e-3, root_tolerance=1e-12 /
&output final_atoms_file='{out}' /
"""


def read_atoms(path):
    rows = []
    for line in open(path):
        line = line.split("#")[0].split()
        if line:
            rows.append([float(x) for x in line[1:]])
    return rows


def run(terrace, work, name, text):
    deck = os.path.join(work, name + ".nml")
    open(deck, "w").write(text)
    p = subprocess.run([terrace, deck], cwd=work, capture_output=True, text=True, timeout=300)
    if p.returncode != 0:
        print(p.stdout[-2000:], p.stderr[-2000:])
        raise SystemExit(f"FAIL: terrace failed on {deck}")
    return summary.get(os.path.join(work, name + ".summary.json"), "energy_stepping/events", 0)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("terrace")
    ap.add_argument("outdir")
    ap.add_argument("--bound", type=float, default=1e-8)
    ap.add_argument("--assert-events", type=int, default=100)
    a = ap.parse_args()
    repo = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    os.makedirs(a.outdir, exist_ok=True)
    init = os.path.join(repo, "input", "argon_frozen_2d.atoms")
    x0 = read_atoms(init)
    print(f"{'T (ps)':>8} {'events':>8} {'max|x_back - x0| (A)':>22} {'max|v_back + v0| (A/ps)':>24}")
    ok = True
    for T in (0.5, 1.0, 2.0, 5.0, 10.0, 20.0):
        n = run(a.terrace, a.outdir, f"fwd_{T}", DECK.format(T=T, atoms=init, rev="", out=f"fwd_{T}.atoms"))
        run(a.terrace, a.outdir, f"back_{T}", DECK.format(T=T, atoms=f"fwd_{T}.atoms", rev=", reverse_velocities=.true.",
                                                          out=f"back_{T}.atoms"))
        xb = read_atoms(os.path.join(a.outdir, f"back_{T}.atoms"))
        dx = max(abs(p[d] - q[d]) for p, q in zip(xb, x0) for d in range(3))
        dv = max(abs(p[d] + q[d]) for p, q in zip(xb, x0) for d in range(3, 6))
        flag = ""
        if n <= a.assert_events:
            flag = " ok" if dx <= a.bound else " FAIL"
            ok = ok and dx <= a.bound
        print(f"{T:8.1f} {n:8d} {dx:22.3e} {dv:24.3e}{flag}")
    print("PASS" if ok else "FAIL")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
