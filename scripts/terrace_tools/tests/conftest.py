"""Fixtures: the terrace binary ($TERRACE, else build/terrace of this checkout) and a helper that
runs a deck in a fresh directory ($TERRACE_TEST_DIR/<test> under CTest, else pytest's tmp_path)."""
import os
import shutil
import subprocess
import sys

import pytest

REPO = os.path.abspath(os.path.join(os.path.dirname(__file__), "..", "..", ".."))
MPI_ENV = {"OMPI_ALLOW_RUN_AS_ROOT": "1", "OMPI_ALLOW_RUN_AS_ROOT_CONFIRM": "1",
           "OMPI_MCA_rmaps_base_oversubscribe": "1"}


@pytest.fixture(scope="module")
def terrace():
    path = os.environ.get("TERRACE") or os.path.join(REPO, "build", "terrace")
    if not os.access(path, os.X_OK):
        pytest.skip(f"no terrace binary at {path} (build first: bash scripts/build.sh)")
    return os.path.abspath(path)


@pytest.fixture
def workdir(request, tmp_path):
    root = os.environ.get("TERRACE_TEST_DIR")
    if not root:
        return str(tmp_path)
    d = os.path.join(root, request.node.name.replace("[", "_").replace("]", ""))
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    return d


class Run:
    def __init__(self, terrace, cwd):
        self.terrace, self.cwd = terrace, cwd

    def __call__(self, name, deck, np_=1, check=True, timeout=300):
        with open(os.path.join(self.cwd, name + ".nml"), "w") as f:
            f.write(deck)
        cmd = [self.terrace, name + ".nml"]
        if np_ > 1:
            cmd = ["mpirun", "--oversubscribe", "-np", str(np_)] + cmd
        p = subprocess.run(cmd, cwd=self.cwd, capture_output=True, text=True, timeout=timeout,
                           env=dict(os.environ, **MPI_ENV))
        if check and p.returncode != 0:
            raise AssertionError(f"terrace {name}.nml exited {p.returncode}:\n{p.stdout[-2000:]}\n{p.stderr[-2000:]}")
        return p

    def path(self, name):
        return os.path.join(self.cwd, name)


@pytest.fixture
def run(terrace, workdir):
    return Run(terrace, workdir)


@pytest.fixture(scope="module")
def python():
    return sys.executable
