"""Shared helpers of the terrace-analyze regression tests: run the program (1 or more ranks),
read its CSV curves, and write small H5MD files with h5py in the layouts other writers use."""
import os
import subprocess
import sys

import h5py
import numpy as np

from terrace_tools import h5md

MPI_ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")


def run(binary, args, nprocs=1, cwd=None, check=True):
    """Run terrace-analyze with args; returns (exit status, stdout, stderr)."""
    cmd = [binary] + list(args)
    if nprocs > 1:
        cmd = ["mpirun", "--oversubscribe", "-np", str(nprocs)] + cmd
    p = subprocess.run(cmd, cwd=cwd, env=MPI_ENV, capture_output=True, text=True, timeout=300)
    if check and p.returncode != 0:
        sys.stdout.write(p.stdout)
        sys.stderr.write(p.stderr)
        raise SystemExit(f"FAIL: {' '.join(cmd)} exited {p.returncode}")
    return p.returncode, p.stdout, p.stderr


def read_csv(path):
    """(header names, columns as a 2-D array)."""
    with open(path) as f:
        header = f.readline().strip().split(",")
    data = np.loadtxt(path, delimiter=",", skiprows=1, ndmin=2)
    return header, data


write_h5md = h5md.write_synthetic


class Checks:
    """Collects pass/fail lines; exit status 1 if any failed."""

    def __init__(self):
        self.failed = 0

    def check(self, ok, what):
        print(("ok    " if ok else "FAIL  ") + what)
        if not ok:
            self.failed += 1

    def finish(self):
        print(f"{'FAILED' if self.failed else 'PASSED'} ({self.failed} failed)")
        sys.exit(1 if self.failed else 0)
