"""terrace-analyze's CSV outputs (PREFIX_vdos.csv, _vacf.csv, _rdf.csv, _sq.csv, _msd.csv,
_diffusion.csv; doc/analysis.md): an optional '# ' comment line, a header of column names, then
rows of numbers, as the thermo CSV."""
import numpy as np

from terrace_tools import thermo


def read(path):
    """{column: float array} in the file's column order ({} for a missing or empty file)."""
    return thermo.read(path)


def array(path):
    """The rows as one (rows, columns) array, columns in the header's order."""
    t = read(path)
    if not t:
        raise ValueError(f"{path}: no rows")
    return np.column_stack(list(t.values()))
