#!/usr/bin/env python3
"""No script, test or document reads Terrace's screen log by pattern: a run's figures come from its
run summary (&output summary_file; terrace_tools.summary), not from the lines the run prints.

Looks at every file git tracks or would add (not ignored) outside src/, or at the files under the
folders given: Python, shell, CMake, Markdown and text. A line is a log parser when it names a line
of Terrace's screen log that carries a run's figures (the closing run log: 'Loop time:', the phase
table, 'Neighbour list builds', 'Peak memory', 'Energy drift:', 'Events:', ...; 'checkpoint: step')
and matches text on the same line: a regular expression (re.*, grep, sed, awk, a '^...' pattern,
CMake's PASS_REGULAR_EXPRESSION), a substring test (startswith, find, index, count, 'in'), or a
phase-table row picked by its first word (awk $1 == "Pair", '^(Pair|Neigh) +[0-9]'). Comment lines
are not read. LAMMPS's and GROMACS's logs are other programs' outputs and are not counted ('Loop
time of' is LAMMPS's line, 'Loop time:' Terrace's); nor are tests of what the screen tells its
reader (the plan `terrace --check` prints, a note, an error line): they check text, not figures.
It also counts sys.path hacks (sys.path.insert / append / assignment, site.addsitedir): the
package is found through PYTHONPATH or `pip install -e scripts`.

    python3 scripts/check_no_log_parsing.py [--pytest] [FOLDER ...]

--pytest also runs the package's pytest tests (scripts/terrace_tools/tests, as the test command
does) and counts the tests that passed from pytest's JUnit XML report. Prints the counts; exit
status 1 when a log parser or a sys.path hack is found (each is listed as FILE:LINE: text) or a
pytest test failed.
"""
import os
import re
import subprocess
import sys
import tempfile
import xml.etree.ElementTree as ET

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SELF = {os.path.join("scripts", "check_no_log_parsing.py"),
        os.path.join("scripts", "terrace_tools", "tests", "test_no_log_parsing.py")}
SUFFIXES = (".py", ".sh", ".cmake", ".txt", ".md", ".nml.in")

# Lines of Terrace's screen log that carry a run's figures (src/io/run_log.f90, the integrators'
# closing lines, the scene plan). 'Loop time' not followed by ' of' (LAMMPS's 'Loop time of').
MARKERS = re.compile(
    r"Loop time(?! of)|Performance: atom-steps|avg time \(s\)|Neighbour list builds|Neighbour list schedule"
    r"|List pairs|Cluster pairs|Peak memory|Energy drift(?: \(econserve\))?:|Events:|Event rate:|Mean event interval"
    r"|Pair crossings:|ray evaluations per event|Total energy \(first, last|checkpoint: step")
# ... matched as text on the same line
MATCHING = re.compile(
    r"\bre\.(?:search|match|fullmatch|findall|finditer|sub|compile|split)\b|\bgrep\b|\bsed\b|\bawk\b"
    r"|REGULAR_EXPRESSION|\.startswith\(|\.endswith\(|\.find\(|\.index\(|\.count\(|['\"]\s+in\s+\w"
    r"|\br['\"]\^|['\"]\^")
# a phase-table row picked by its first word: a regular expression or awk on Pair, Neigh, Comm, ...
PHASE = r"(?:Pair|Neigh|Comm|Output|Search|Other)"
PHASE_ROW = re.compile(
    r"\^\(?" + PHASE + r"(?:[|)]|(?=[ \\])(?!(?: |\\s|[+*])*\\?\||(?: |\\s)+Coeffs)(?: |\\s))|\(" + PHASE + r"\|" + PHASE + r"|\$1 *== *\"" + PHASE + r"\""
    r"|startswith\(['\"]" + PHASE + r"['\"]")
# ... except on LAMMPS's timing table, whose rows ('Pair    | ...') awk splits at '|'
LAMMPS_TABLE = re.compile(r"-F\s*['\"]\|['\"]")
SYS_PATH = re.compile(r"\bsys\.path\.(?:insert|append|extend)\(|\bsys\.path\s*(?:\+?=|\[)|\bsite\.addsitedir\(")


def files(roots):
    """Files to look at: those under the given folders, or every file git tracks or would add
    (untracked, not ignored) outside src/."""
    if roots:
        for root in roots:
            for d, _, names in os.walk(root):
                for n in sorted(names):
                    yield os.path.join(d, n)
        return
    out = subprocess.run(["git", "-C", REPO, "ls-files", "--cached", "--others", "--exclude-standard"],
                         capture_output=True, text=True, check=True).stdout
    for rel in out.splitlines():
        if rel.startswith("src/") or rel in SELF or "bad_inputs/" in rel:
            continue
        yield os.path.join(REPO, rel)


def code_part(line, suffix):
    """The line without a comment that fills it (Python, shell, CMake: '#'; Markdown is all text)."""
    s = line.strip()
    if suffix != ".md" and s.startswith("#"):
        return ""
    return line


def scan(paths):
    """([(file, line number, text)] of log parsers, [...] of sys.path hacks)."""
    parsers, hacks = [], []
    for path in paths:
        if not path.endswith(SUFFIXES) and os.path.basename(path) != "CMakeLists.txt":
            continue
        suffix = os.path.splitext(path)[1]
        try:
            with open(path, encoding="utf-8", errors="replace") as f:
                lines = f.read().splitlines()
        except OSError:
            continue
        rel = os.path.relpath(path, REPO)
        for k, line in enumerate(lines, 1):
            text = code_part(line, suffix)
            if not text:
                continue
            if (MARKERS.search(text) and MATCHING.search(text)) or \
                    (PHASE_ROW.search(text) and not LAMMPS_TABLE.search(text)):
                parsers.append((rel, k, line.strip()))
            if suffix != ".md" and SYS_PATH.search(text):
                hacks.append((rel, k, line.strip()))
    return parsers, hacks


def pytest_counts():
    """(passed, failed) tests of scripts/terrace_tools/tests, run as the test command runs them."""
    with tempfile.TemporaryDirectory() as tmp:
        report = os.path.join(tmp, "pytest.xml")
        env = dict(os.environ)
        env["PYTHONPATH"] = os.path.join(REPO, "scripts") + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
        subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", f"--junitxml={report}",
                        os.path.join(REPO, "scripts", "terrace_tools", "tests")], env=env)
        total = failed = skipped = 0
        for suite in ET.parse(report).getroot().iter("testsuite"):
            total += int(suite.get("tests", 0))
            failed += int(suite.get("failures", 0)) + int(suite.get("errors", 0))
            skipped += int(suite.get("skipped", 0))
        return total - failed - skipped, failed


def main(argv):
    run_pytest = "--pytest" in argv
    roots = [a for a in argv if a != "--pytest"]
    parsers, hacks = scan(files(roots))
    for what, found in (("log parser", parsers), ("sys.path hack", hacks)):
        for rel, k, text in found:
            print(f"{rel}:{k}: {what}: {text}")
    print(f"log parsers: {len(parsers)}")
    print(f"sys.path hacks: {len(hacks)}")
    ok = not parsers and not hacks
    if run_pytest:
        passed, failed = pytest_counts()
        print(f"pytest tests passed: {passed} (failed: {failed})")
        ok = ok and failed == 0
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
