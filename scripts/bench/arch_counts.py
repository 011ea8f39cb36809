#!/usr/bin/env python3
"""Counts that show the code's layout, from the Fortran sources of src/ (.f90 and included .inc):

  - modules outside the input, run, analysis and app layers that name config_t;
  - `select case` on a thermostat style, and tests of a thermostat style, in integrators/;
  - quoted style names (potential, thermostat, integrator) outside their factories, their style
    registries (the tables of each family's names, keys and capabilities: potentials/potential_styles.f90,
    integrators/integrator_styles.f90, minimize/minimize_styles.f90) and the styles' own files, by file;
  - the longest procedure in integrators/; procedures over 100 lines (each listed);
  - the largest argument count (the procedures over 14 listed).

usage: arch_counts.py [REPO]          (default: the repository this script is in)
A procedure's length runs from its first to its `end` line, internal procedures included; an
argument count is that of its dummy arguments. `duplicates --repo src` is the other count the
architecture section of doc/architecture.md quotes; it is a separate tool.
"""
import os
import re
import sys

HEAD = re.compile(r"^\s*(?:(?:pure|elemental|recursive|impure|module)\s+)*"
                  r"(?:(?:integer|real|logical|character|type|class|complex)(?:\s*\([^)]*\))?\s+)*"
                  r"(subroutine|function)\s+(\w+)\s*(\([^)]*\)?)?", re.I)
END = re.compile(r"^\s*end\s+(subroutine|function)\b", re.I)
POTENTIALS = ["lj", "lj/smooth/linear", "eam", "eam/alloy", "eam/fs", "neohookean", "hard_sphere", "square_well",
              "stepped"]
THERMOSTATS = ["langevin", "csvr", "nose_hoover", "andersen"]
INTEGRATORS = ["velocity_verlet", "energy_stepping", "event_driven"]
# the places that may name styles: the factories and the style registries
FACTORIES = {"run/potential_factory.f90", "thermostat/thermostat_factory.f90", "potentials/potential_styles.f90",
             "integrators/integrator_styles.f90", "minimize/minimize_styles.f90"}
# a style's own files may name its variants (EAM's file formats 'eam/alloy', 'eam/fs'); units.f90's
# 'lj' is the unit system, not the potential
OWN = ("potentials/", "thermostat/", "core/units.f90")


def fortran_files(src):
    for root, _, files in os.walk(src):
        for name in sorted(files):
            if name.endswith((".f90", ".inc")):
                path = os.path.join(root, name)
                yield os.path.relpath(path, src), path


def procedures(lines):
    """(name, first line, length, argument count) of every procedure, internal ones included."""
    stack, out = [], []
    i = 0
    while i < len(lines):
        code = lines[i].split("!", 1)[0]
        start = i
        while code.rstrip().endswith("&") and i + 1 < len(lines):
            i += 1
            code = code.rstrip()[:-1] + " " + lines[i].split("!", 1)[0].strip().lstrip("&")
        if END.match(code):
            if stack:
                name, first, nargs = stack.pop()
                out.append((name, first + 1, i - first + 1, nargs))
        else:
            m = HEAD.match(code)
            if m and not re.match(r"^\s*end\b", code, re.I) and "procedure" not in code.split("(")[0].lower():
                args = (m.group(3) or "").strip("()").replace(" ", "")
                stack.append((m.group(2), start, len([a for a in args.split(",") if a])))
        i += 1
    return out


def main(argv):
    repo = os.path.abspath(argv[1]) if len(argv) > 1 else \
        os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    src = os.path.join(repo, "src")
    config_users, ts_branches, literals, procs = [], [], {}, []
    names = POTENTIALS + THERMOSTATS + INTEGRATORS
    literal = re.compile(r"""['"](%s)['"]""" % "|".join(re.escape(n) for n in names))
    for rel, path in fortran_files(src):
        layer = rel.split(os.sep)[0]
        lines = open(path, encoding="utf-8", errors="replace").read().split("\n")
        code = [line.split("!", 1)[0] for line in lines]
        if layer not in ("input", "run", "analysis", "app") and any(re.search(r"\bconfig_t\b", c) for c in code):
            config_users.append(rel)
        if layer == "integrators":
            for n, c in enumerate(code, 1):
                if re.search(r"select\s+case\s*\(\s*\w*%style", c, re.I) or re.search(r"\bts%style\b|thermostat_(langevin|csvr|nose_hoover|andersen)\b", c):
                    ts_branches.append(f"{rel}:{n}")
        if rel not in FACTORIES and not rel.startswith(OWN):
            hits = sum(len(literal.findall(c)) for c in code)
            if hits:
                literals[rel] = hits
        for name, first, length, nargs in procedures(lines):
            procs.append((rel, name, first, length, nargs))
    print(f"modules below the input layer that name config_t: {len(config_users)}"
          + (" (" + ", ".join(config_users) + ")" if config_users else ""))
    print(f"thermostat style branches in integrators/: {len(ts_branches)}"
          + (" (" + ", ".join(ts_branches) + ")" if ts_branches else ""))
    print(f"quoted style names outside the factories: {sum(literals.values())} in {len(literals)} files"
          + "".join(f"\n    {k}: {v}" for k, v in sorted(literals.items(), key=lambda kv: -kv[1])))
    integ = [p for p in procs if p[0].startswith("integrators")]
    if integ:
        longest = max(integ, key=lambda p: p[3])
        print(f"longest procedure in integrators/: {longest[1]} ({longest[0]}:{longest[2]}), {longest[3]} lines")
    long_ = sorted([p for p in procs if p[3] > 100], key=lambda p: -p[3])
    print(f"procedures over 100 lines: {len(long_)}"
          + "".join(f"\n    {p[3]:4d}  {p[1]} ({p[0]}:{p[2]})" for p in long_))
    most = max(procs, key=lambda p: p[4])
    many = sorted([p for p in procs if p[4] > 14], key=lambda p: -p[4])
    print(f"largest argument count: {most[4]} ({most[1]}, {most[0]}:{most[2]}); over 14: {len(many)}"
          + "".join(f"\n    {p[4]:3d}  {p[1]} ({p[0]}:{p[2]})" for p in many))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
