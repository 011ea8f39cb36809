"""scripts/check_no_log_parsing.py: the repository reads no figure from Terrace's screen log and has
no sys.path hack; a planted parser of each kind is found (the check can fail)."""
import os
import subprocess
import sys

from .conftest import REPO

CHECKER = os.path.join(REPO, "scripts", "check_no_log_parsing.py")

# one parser of each kind a script might write, and a sys.path hack
PLANTED = {
    "ab.sh": """loop=$(sed -n 's/^Loop time: *\\([0-9.]*\\) s.*/\\1/p' "$log")
ph=$(awk '$1=="Pair"||$1=="Neigh"{printf " %s %s", $1, $2}' run.log)
grep -q "^Peak memory" run.log || exit 1
pair=$(awk '/^Pair /{print $2}' run.log)
""",
    "cost.py": """import re, sys
sys.path.insert(0, '..')
events = int(re.search(r'Events: (\\d+)', log).group(1))
if line.startswith('Neighbour list builds'):
    pass
rows = re.findall(r'^(Pair|Neigh|Comm) +([0-9.]+)', text, re.M)
""",
}
# not counted: LAMMPS's log, comments, prints of the summary's figures
NOT_PARSERS = {
    "lammps.sh": """t=$(sed -n 's/^Loop time of \\([0-9.eE+-]*\\) on .*/\\1/p' lammps.log | tail -1)
# Terrace's "Loop time:" line used to be read with grep; now: the run summary
echo "Loop time: $(python3 -m terrace_tools.summary get run.summary.json timing/loop_time_s) s"
p=$(awk -F'|' '/^Pair /{gsub(/ /,"",$3); print $3}' lammps.log | tail -1)
n=$(awk '/^Neigh  *\\|/{print $7}' lammps.log)
grep -q '^Pair Coeffs' data.lmp
""",
    "ok.py": """from terrace_tools import summary
print('Events: %d' % summary.get('run.summary.json', 'energy_stepping/events'))
""",
}


def check(folder):
    return subprocess.run([sys.executable, CHECKER, str(folder)], capture_output=True, text=True)


def test_repository_reads_no_log_and_hacks_no_path():
    p = subprocess.run([sys.executable, CHECKER], capture_output=True, text=True, cwd=REPO)
    assert p.returncode == 0, p.stdout + p.stderr
    assert "log parsers: 0" in p.stdout.splitlines() and "sys.path hacks: 0" in p.stdout.splitlines()


def test_planted_parsers_are_found(tmp_path):
    for name, text in PLANTED.items():
        (tmp_path / name).write_text(text)
    p = check(tmp_path)
    assert p.returncode == 1
    lines = p.stdout.splitlines()
    assert "log parsers: 7" in lines, p.stdout
    assert "sys.path hacks: 1" in lines, p.stdout
    found = {(ln.split(":")[0].split(os.sep)[-1], int(ln.split(":")[1])) for ln in lines if ": log parser: " in ln}
    assert found == {("ab.sh", 1), ("ab.sh", 2), ("ab.sh", 3), ("ab.sh", 4), ("cost.py", 3), ("cost.py", 4),
                     ("cost.py", 6)}


def test_lammps_logs_comments_and_prints_are_not_parsers(tmp_path):
    for name, text in NOT_PARSERS.items():
        (tmp_path / name).write_text(text)
    p = check(tmp_path)
    assert p.returncode == 0, p.stdout
    assert "log parsers: 0" in p.stdout.splitlines()
