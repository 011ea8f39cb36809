"""GROMACS outputs the benchmarks use: md.log's timing and performance lines, .xvg tables
(gmx energy), .gro coordinate files."""
import re

import numpy as np


def parse_md_log(text):
    """md.log's closing figures: {'core_s', 'wall_s', 'percent', 'ns_per_day', 'hours_per_ns'}
    (None where a line is missing). 'wall_s' is GROMACS's 'Time: ... wall t (s)' of the MD loop."""
    r = dict.fromkeys(("core_s", "wall_s", "percent", "ns_per_day", "hours_per_ns"))
    m = re.findall(r"^\s*Time:\s+([0-9.eE+-]+)\s+([0-9.eE+-]+)\s+([0-9.eE+-]+)", text, re.M)
    if m:
        r["core_s"], r["wall_s"], r["percent"] = (float(v) for v in m[-1])
    m = re.findall(r"^Performance:\s+([0-9.eE+-]+)\s+([0-9.eE+-]+)", text, re.M)
    if m:
        r["ns_per_day"], r["hours_per_ns"] = (float(v) for v in m[-1])
    return r


def read_md_log(path):
    with open(path) as f:
        return parse_md_log(f.read())


def read_xvg(path):
    """An .xvg table: (legends [column names after the first], array (rows, columns))."""
    legends, rows = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("@"):
                m = re.match(r'@\s+s\d+\s+legend\s+"(.*)"', line)
                if m:
                    legends.append(m.group(1))
            elif line.startswith("#") or not line.strip():
                continue
            else:
                rows.append([float(w) for w in line.split()])
    return legends, np.array(rows)


def read_gro(path):
    """A .gro file: (names (N,), x (N, 3) in nm, box (3,) in nm, title)."""
    with open(path) as f:
        lines = f.read().splitlines()
    title, n = lines[0], int(lines[1])
    names = [ln[10:15].strip() for ln in lines[2:2 + n]]
    x = np.array([[float(ln[20:28]), float(ln[28:36]), float(ln[36:44])] for ln in lines[2:2 + n]])
    box = np.array([float(w) for w in lines[2 + n].split()[:3]])
    return names, x, box, title
