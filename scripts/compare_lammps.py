#!/usr/bin/env python3
"""Compare Terrace output with a LAMMPS reference (or with another Terrace run).

Subcommands
-----------
lammps     Terrace vs LAMMPS for one scene.
             --lammps-log LOG        LAMMPS log with thermo rows
                                     'Step Time Temp PotEng KinEng TotEng Press'
                                     (thermo_modify norm no, i.e. extensive).
             --lammps-forces DUMP    LAMMPS dump/write_dump 'custom ... id fx fy fz'.
             --terrace-thermo CSV    Terrace thermo CSV (header starts with
                                     step,time,temp,pe,ke,etotal,press).
             --terrace-forces FILE   Terrace forces file ('#' comments, then
                                     'id fx fy fz' lines).
           Checks
             * step 0: pe and press (and also temp, ke, etotal, which only
               depend on the velocities read from the data file) agree to
               --tol-static (default 1e-10), relative difference.
             * step 0 forces: the two files hold the same atom ids, and for
               every atom i and every component c
                   |f_T[i,c] - f_L[i,c]| <= tol_force * max(|F_L[i]|, F_rms)
               where |F_L[i]| is the magnitude of LAMMPS's force vector on
               atom i and F_rms = sqrt(sum_i |F_L[i]|^2 / N) is the RMS force
               magnitude over all atoms.  tol_force = --tol-force, which
               defaults to --tol-static.  (The F_rms floor keeps atoms with an
               accidentally tiny net force from demanding impossible
               absolute precision.)
             * step --step (default 100): temp, pe, ke, etotal, press agree to
               --tol-dynamic (default 1e-8), relative difference.
terrace    Terrace CSV vs Terrace CSV (e.g. rank-count invariance): every
           column present in both files, on every step present in both
           files, agrees to --tol (default 1e-8) relative difference
           (or to --atol absolute, if given).
lammps-to-terrace
           Testing aid: convert a LAMMPS log + force dump into files in the
           Terrace formats (thermo CSV and forces file), so that this script
           can be checked against itself.

Relative difference throughout: rel(a, b) = |a - b| / max(|b|, tiny), with b
the reference (LAMMPS, or the second CSV) and tiny = --tiny (default 1e-300).

Exit status: 0 all checks pass; 1 some check failed; 2 unreadable/missing
input (bad file, missing step, column or atom).

Only the Python standard library is needed.
"""

import argparse
import math
import sys

THERMO_KEYS = ("step", "time", "temp", "pe", "ke", "etotal", "press")

# LAMMPS thermo header names -> Terrace CSV column names
LAMMPS_COLS = {
    "Step": "step",
    "Time": "time",
    "Temp": "temp",
    "PotEng": "pe",
    "KinEng": "ke",
    "TotEng": "etotal",
    "Press": "press",
    # lower-case variants, in case someone uses thermo_modify/other styles
    "step": "step", "time": "time", "temp": "temp", "pe": "pe",
    "ke": "ke", "etotal": "etotal", "press": "press",
}


class InputError(Exception):
    """Raised for unreadable or incomplete input files (exit status 2)."""


def to_float(tok):
    """Parse a number, accepting Fortran 'D' exponents."""
    t = tok.strip()
    try:
        return float(t)
    except ValueError:
        return float(t.replace("D", "E").replace("d", "e"))


def open_text(path):
    try:
        return open(path, "r")
    except OSError as exc:
        raise InputError(f"cannot open {path}: {exc}")


# --------------------------------------------------------------------------
# parsers
# --------------------------------------------------------------------------

def parse_lammps_log(path):
    """Return {step: {key: value}} from all thermo blocks of a LAMMPS log.

    A thermo block starts at a header line whose first token is 'Step' and
    ends at the 'Loop time' line.  Lines inside a block that are not a row of
    numbers of the header's length (WARNING lines etc.) are ignored.  If a
    step occurs in several blocks (e.g. step 0 of 'run 0' and of the next
    run) the values must agree exactly-ish; the last one is kept.
    """
    rows = {}
    header = None
    with open_text(path) as fh:
        for line in fh:
            toks = line.split()
            if not toks:
                continue
            if toks[0] == "Step" and len(toks) > 1:
                header = [LAMMPS_COLS.get(t, t) for t in toks]
                continue
            if header is None:
                continue
            if line.startswith("Loop time of"):   # (LAMMPS's line after the thermo rows)
                header = None
                continue
            if len(toks) != len(header):
                continue
            try:
                vals = [to_float(t) for t in toks]
            except ValueError:
                continue
            rec = dict(zip(header, vals))
            step = int(round(rec["step"]))
            if step in rows:
                for k, v in rec.items():
                    old = rows[step].get(k)
                    if old is not None and rel_diff(v, old, 1e-300) > 1e-12:
                        print(f"warning: {path}: step {step} {k} differs between "
                              f"thermo blocks ({old!r} vs {v!r}); using the later",
                              file=sys.stderr)
            rows[step] = rec
    if not rows:
        raise InputError(f"{path}: no thermo rows found (expected a header line "
                         f"starting with 'Step')")
    return rows


def parse_terrace_csv(path):
    """Return (columns, {step: {col: value}}) from a Terrace thermo CSV."""
    rows = {}
    cols = None
    with open_text(path) as fh:
        for lineno, line in enumerate(fh, 1):
            s = line.strip()
            if not s or s.startswith("#"):
                continue
            if cols is None:
                cols = [c.strip() for c in s.split(",")]
                if cols[:len(THERMO_KEYS)] != list(THERMO_KEYS):
                    raise InputError(
                        f"{path}:{lineno}: header must start with "
                        f"'{','.join(THERMO_KEYS)}', got '{s}'")
                continue
            toks = s.split(",")
            if len(toks) != len(cols):
                raise InputError(f"{path}:{lineno}: {len(toks)} fields, header "
                                 f"has {len(cols)}")
            try:
                vals = [to_float(t) for t in toks]
            except ValueError:
                raise InputError(f"{path}:{lineno}: non-numeric field in '{s}'")
            rec = dict(zip(cols, vals))
            step = int(round(rec["step"]))
            if step in rows:
                raise InputError(f"{path}:{lineno}: step {step} appears twice")
            rows[step] = rec
    if cols is None:
        raise InputError(f"{path}: empty file (no header)")
    if not rows:
        raise InputError(f"{path}: header but no data rows")
    return cols, rows


def parse_lammps_dump(path):
    """Return {id: (fx, fy, fz)} from the first snapshot of a LAMMPS text dump."""
    forces = {}
    natoms = None
    cols = None
    with open_text(path) as fh:
        lines = iter(fh)
        for line in lines:
            if line.startswith("ITEM: NUMBER OF ATOMS"):
                natoms = int(next(lines).split()[0])
            elif line.startswith("ITEM: ATOMS"):
                cols = line.split()[2:]
                break
        if cols is None or natoms is None:
            raise InputError(f"{path}: not a LAMMPS text dump (no 'ITEM: ATOMS')")
        try:
            ii = cols.index("id")
            ix, iy, iz = cols.index("fx"), cols.index("fy"), cols.index("fz")
        except ValueError:
            raise InputError(f"{path}: dump columns {cols} lack id fx fy fz")
        for _ in range(natoms):
            toks = next(lines, "").split()
            if len(toks) != len(cols):
                raise InputError(f"{path}: truncated ATOMS section")
            aid = int(toks[ii])
            if aid in forces:
                raise InputError(f"{path}: atom id {aid} appears twice")
            forces[aid] = (to_float(toks[ix]), to_float(toks[iy]), to_float(toks[iz]))
    return forces


def parse_terrace_forces(path):
    """Return {id: (fx, fy, fz)} from a Terrace forces file."""
    forces = {}
    last = None
    with open_text(path) as fh:
        for lineno, line in enumerate(fh, 1):
            s = line.strip()
            if not s or s.startswith("#"):
                continue
            toks = s.split()
            if len(toks) != 4:
                raise InputError(f"{path}:{lineno}: expected 'id fx fy fz', got '{s}'")
            try:
                aid = int(toks[0])
                f = (to_float(toks[1]), to_float(toks[2]), to_float(toks[3]))
            except ValueError:
                raise InputError(f"{path}:{lineno}: non-numeric field in '{s}'")
            if aid in forces:
                raise InputError(f"{path}:{lineno}: atom id {aid} appears twice")
            if last is not None and aid < last:
                print(f"warning: {path}:{lineno}: ids not sorted ({aid} after {last})",
                      file=sys.stderr)
            last = aid
            forces[aid] = f
    if not forces:
        raise InputError(f"{path}: no force lines")
    return forces


# --------------------------------------------------------------------------
# comparison helpers
# --------------------------------------------------------------------------

def rel_diff(a, b, tiny):
    if math.isnan(a) or math.isnan(b):
        return math.inf
    return abs(a - b) / max(abs(b), tiny)


def fmt(x):
    return f"{x:.17g}"


class Table:
    def __init__(self, title, left, right):
        self.title = title
        self.left, self.right = left, right
        self.rows = []
        self.nfail = 0

    def add(self, name, a, b, tol, tiny, atol=None):
        r = rel_diff(a, b, tiny)
        ok = r <= tol or (atol is not None and abs(a - b) <= atol)
        if not ok:
            self.nfail += 1
        self.rows.append((name, fmt(a), fmt(b), f"{r:.3e}", f"{tol:.1e}",
                          "ok" if ok else "FAIL"))
        return ok

    def show(self):
        hdr = ("quantity", self.left, self.right, "rel.diff", "tol", "")
        w = [max(len(str(r[i])) for r in self.rows + [hdr]) for i in range(6)]
        print(f"== {self.title}")
        print("  ".join(str(h).ljust(w[i]) for i, h in enumerate(hdr)).rstrip())
        for r in self.rows:
            print("  ".join(str(c).ljust(w[i]) for i, c in enumerate(r)).rstrip())
        print()


def get_step(rows, step, path):
    if step not in rows:
        raise InputError(f"{path}: no thermo row for step {step} "
                         f"(steps present: {sorted(rows)[:10]}...)")
    return rows[step]


def compare_forces(ft, fl, tol, tiny):
    """Return (ok, messages)."""
    msgs = []
    ids_t, ids_l = set(ft), set(fl)
    if ids_t != ids_l:
        only_t = sorted(ids_t - ids_l)[:10]
        only_l = sorted(ids_l - ids_t)[:10]
        msgs.append(f"atom ids differ: {len(ids_t)} in Terrace, {len(ids_l)} in "
                    f"LAMMPS; only Terrace: {only_t}; only LAMMPS: {only_l}")
        return False, msgs
    n = len(fl)
    mags = {i: math.sqrt(sum(c * c for c in f)) for i, f in fl.items()}
    frms = math.sqrt(sum(m * m for m in mags.values()) / n)
    fmax = max(mags.values())
    worst = (-1.0, None, None, 0.0)
    max_abs = 0.0
    nbad = 0
    for i in sorted(fl):
        scale = max(mags[i], frms, tiny)
        for c in range(3):
            d = abs(ft[i][c] - fl[i][c])
            if math.isnan(ft[i][c]):
                d = math.inf
            max_abs = max(max_abs, d)
            e = d / scale
            if e > tol:
                nbad += 1
            if e > worst[0]:
                worst = (e, i, "xyz"[c], d)
    ok = nbad == 0
    print("== step 0 per-atom forces: |dF| <= tol * max(|F_lammps(atom)|, F_rms)")
    print(f"  atoms                  {n}")
    print(f"  F_rms / max |F|        {frms:.6g} / {fmax:.6g}")
    print(f"  max |dF| (absolute)    {max_abs:.3e}")
    print(f"  max normalised error   {worst[0]:.3e}  (atom {worst[1]}, f{worst[2]})  "
          f"tol {tol:.1e}  {'ok' if ok else 'FAIL'}")
    if worst[1] is not None:
        i = worst[1]
        print(f"  worst atom {i} terrace: {' '.join(fmt(x) for x in ft[i])}")
        print(f"  worst atom {i} lammps:  {' '.join(fmt(x) for x in fl[i])}")
    print()
    if not ok:
        msgs.append(f"{nbad} force components out of tolerance (worst normalised "
                    f"error {worst[0]:.3e} > {tol:.1e}, atom {worst[1]} f{worst[2]})")
    return ok, msgs


# --------------------------------------------------------------------------
# subcommands
# --------------------------------------------------------------------------

def cmd_lammps(a):
    lrows = parse_lammps_log(a.lammps_log)
    _, trows = parse_terrace_csv(a.terrace_thermo)
    failures = []

    tol_force = a.tol_force if a.tol_force is not None else a.tol_static

    t0 = get_step(trows, 0, a.terrace_thermo)
    l0 = get_step(lrows, 0, a.lammps_log)
    tab = Table("step 0 thermo", "terrace", "lammps")
    for k in ("pe", "press", "temp", "ke", "etotal"):
        if not tab.add(k, t0[k], l0[k], a.tol_static, a.tiny):
            failures.append(f"step 0 {k}: rel.diff {rel_diff(t0[k], l0[k], a.tiny):.3e}"
                            f" > {a.tol_static:.1e}")
    tab.show()

    if a.terrace_forces or a.lammps_forces:
        if not (a.terrace_forces and a.lammps_forces):
            raise InputError("give both --terrace-forces and --lammps-forces, or neither")
        ft = parse_terrace_forces(a.terrace_forces)
        fl = parse_lammps_dump(a.lammps_forces)
        ok, msgs = compare_forces(ft, fl, tol_force, a.tiny)
        failures += msgs

    if a.step != 0:
        ts = get_step(trows, a.step, a.terrace_thermo)
        ls = get_step(lrows, a.step, a.lammps_log)
        tab = Table(f"step {a.step} thermo", "terrace", "lammps")
        for k in ("time", "temp", "pe", "ke", "etotal", "press"):
            if not tab.add(k, ts[k], ls[k], a.tol_dynamic, a.tiny):
                failures.append(f"step {a.step} {k}: rel.diff "
                                f"{rel_diff(ts[k], ls[k], a.tiny):.3e} > {a.tol_dynamic:.1e}")
        tab.show()

    return report(failures)


def cmd_terrace(a):
    cols_a, rows_a = parse_terrace_csv(a.csv_a)
    cols_b, rows_b = parse_terrace_csv(a.csv_b)
    ignored = set(filter(None, (a.ignore or "").split(",")))
    cols = [c for c in cols_a if c in cols_b and c != "step" and c not in ignored]
    if ignored:
        print(f"note: columns not compared: {sorted(ignored)}")
    steps = sorted(set(rows_a) & set(rows_b))
    if not steps:
        raise InputError(f"no common steps between {a.csv_a} and {a.csv_b}")
    skipped_a = sorted(set(cols_a) - set(cols_b))
    skipped_b = sorted(set(cols_b) - set(cols_a))
    if skipped_a or skipped_b:
        print(f"note: columns only in A: {skipped_a}; only in B: {skipped_b}")
    if set(rows_a) != set(rows_b):
        print(f"note: {len(set(rows_a) ^ set(rows_b))} steps present in only one file "
              f"(ignored)")
    failures = []
    worst = {}
    for s in steps:
        for c in cols:
            va, vb = rows_a[s][c], rows_b[s][c]
            r = rel_diff(va, vb, a.tiny)
            ok = r <= a.tol or (a.atol is not None and abs(va - vb) <= a.atol)
            if c not in worst or r > worst[c][0]:
                worst[c] = (r, s, va, vb)
            if not ok:
                failures.append(f"step {s} {c}: {fmt(va)} vs {fmt(vb)} rel.diff {r:.3e}")
    tab = Table(f"worst step per column over {len(steps)} common steps "
                f"({steps[0]}..{steps[-1]})", "A", "B")
    for c in cols:
        r, s, va, vb = worst[c]
        tab.add(f"{c} @ {s}", va, vb, a.tol, a.tiny, a.atol)
    tab.show()
    if len(failures) > 20:
        failures = failures[:20] + [f"... and {len(failures) - 20} more"]
    return report(failures)


def cmd_lammps_to_terrace(a):
    lrows = parse_lammps_log(a.lammps_log)
    with open(a.out_thermo, "w") as fh:
        fh.write(",".join(THERMO_KEYS) + "\n")
        for s in sorted(lrows):
            r = lrows[s]
            fh.write(",".join([str(s)] + [fmt(r[k]) for k in THERMO_KEYS[1:]]) + "\n")
    if a.lammps_forces:
        fl = parse_lammps_dump(a.lammps_forces)
        with open(a.out_forces, "w") as fh:
            fh.write(f"# converted from {a.lammps_forces}\n# id fx fy fz\n")
            for i in sorted(fl):
                fh.write(f"{i} {' '.join(fmt(x) for x in fl[i])}\n")
    return 0


def report(failures):
    if failures:
        print("FAIL:", file=sys.stderr)
        for f in failures:
            print(f"  {f}", file=sys.stderr)
        print(f"FAIL ({len(failures)} problem(s))")
        return 1
    print("PASS")
    return 0


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                epilog="See the module docstring for the exact criteria.",
                                formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = p.add_subparsers(dest="cmd", required=True)

    q = sub.add_parser("lammps", help="Terrace vs LAMMPS reference")
    q.add_argument("--lammps-log", required=True)
    q.add_argument("--lammps-forces")
    q.add_argument("--terrace-thermo", required=True)
    q.add_argument("--terrace-forces")
    q.add_argument("--step", type=int, default=100,
                   help="dynamic comparison step (0 to skip; default 100)")
    q.add_argument("--tol-static", type=float, default=1e-10)
    q.add_argument("--tol-force", type=float, default=None,
                   help="force tolerance (default: --tol-static)")
    q.add_argument("--tol-dynamic", type=float, default=1e-8)
    q.add_argument("--tiny", type=float, default=1e-300)
    q.set_defaults(func=cmd_lammps)

    q = sub.add_parser("terrace", help="Terrace CSV vs Terrace CSV (B is the reference)")
    q.add_argument("csv_a")
    q.add_argument("csv_b")
    q.add_argument("--tol", type=float, default=1e-8)
    q.add_argument("--atol", type=float, default=None,
                   help="also accept |a-b| <= atol (for columns that are ~0)")
    q.add_argument("--tiny", type=float, default=1e-300)
    q.add_argument("--ignore", default="",
                   help="comma-separated columns not to compare (cost statistics such as evals_per_event)")
    q.set_defaults(func=cmd_terrace)

    q = sub.add_parser("lammps-to-terrace",
                       help="testing aid: write LAMMPS output in Terrace formats")
    q.add_argument("--lammps-log", required=True)
    q.add_argument("--lammps-forces")
    q.add_argument("--out-thermo", required=True)
    q.add_argument("--out-forces", default="forces0.txt")
    q.set_defaults(func=cmd_lammps_to_terrace)

    a = p.parse_args(argv)
    try:
        return a.func(a)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
