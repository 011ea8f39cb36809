"""The run summary against the run log on the screen and the thermo CSV of the same run."""
import json
import os
import re
import signal
import subprocess
import time
import zlib

import numpy as np
import pytest

from terrace_tools import summary, thermo

from .conftest import MPI_ENV

LJ = """&run units='lj', dimension=3, n_steps={steps}, seed=87287 /
&system lattice='fcc', density=0.8442, cells=5,5,5, periodic=.true.,.true.,.true., mass=1.0, temperature=1.44 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&output thermo_every=10, thermo_file='thermo.csv'{extra} /
"""

ES = """&run units='metal', dimension=3, run_time=0.5, seed=147 /
&system atoms_file='{repo}/input/argon_ico147.atoms', periodic=.false.,.false.,.false., mass=39.951,
        temperature=20.0 /
&potential style='lj', epsilon=0.010323577, sigma=3.41, cutoff=8.525, shift=.true. /
&integrator style='energy_stepping', terrace_height=5.0e-4 /
&neighbor skin=1.0 /
&output thermo_interval=0.1, thermo_file='es.csv', trajectory_file='es.h5', final_atoms_file='es_final.atoms' /
"""


def log_value(text, pattern, conv=float):
    m = re.search(pattern, text, re.M)
    assert m, f"no line matching {pattern!r} in the run log"
    return conv(m.group(1))


@pytest.mark.parametrize("np_", [1, 2])
def test_verlet_summary_equals_log_and_csv(run, np_):
    p = run("lj", LJ.format(steps=200, extra=""), np_=np_)
    s = summary.read(run.path("lj.summary.json"))
    t = thermo.read(run.path("thermo.csv"))
    natoms = summary.get(s, "run/atoms")
    assert natoms == 500 == summary.get(s, "timing/atoms")
    # the figures of the run log, to the digits it prints
    assert round(summary.get(s, "timing/loop_time_s"), 4) == pytest.approx(
        log_value(p.stdout, r"^Loop time: ([0-9.]+) s"), abs=1e-12)
    assert summary.get(s, "timing/steps") == log_value(p.stdout, r"^Loop time: .* for (\d+) steps", int) == 200
    assert summary.get(s, "neighbor/builds") == log_value(p.stdout, r"^Neighbour list builds: (\d+)", int)
    for ph in ("Pair", "Neigh", "Comm", "Output", "Search", "Other"):
        avg = log_value(p.stdout, r"^%s\s+([0-9.]+)" % ph)
        assert summary.get(s, f"timing/phases/{ph}/avg_s") == pytest.approx(avg, abs=0.6e-4)
    drift_log = log_value(p.stdout, r"^Energy drift:\s+(\S+) energy/atom/time")
    assert summary.get(s, "conservation/energy_drift_per_atom_time") == pytest.approx(drift_log, rel=1e-4)
    # ... and equal to what the thermo CSV gives (same doubles, printed with 17 digits)
    assert summary.get(s, "conservation/energy_drift_per_atom_time") == pytest.approx(
        thermo.energy_drift(t, natoms), rel=1e-12)
    assert summary.get(s, "conservation/momentum_change") == pytest.approx(thermo.momentum_change(t), rel=1e-6,
                                                                          abs=1e-15)
    assert summary.get(s, "run/simulated_time") == pytest.approx(t["time"][-1], rel=1e-15)
    # the last thermo sample: the CSV's last row (17 digits both)
    for k in ("step", "time", "temp", "pe", "ke", "etotal", "press"):
        assert summary.get(s, "thermo_last/" + k) == pytest.approx(t[k][-1], rel=1e-15, abs=1e-300)
    mem = log_value(p.stdout, r"^Peak memory: ([0-9.]+) MiB")
    assert summary.get(s, "memory/peak_mib_all_ranks") == pytest.approx(mem, abs=0.051)
    # identity of the run
    assert summary.get(s, "deck/crc32") == "%08x" % zlib.crc32(open(run.path("lj.nml"), "rb").read())
    assert summary.get(s, "deck/path") == "lj.nml"
    assert summary.get(s, "machine/ranks") == np_
    assert summary.get(s, "units/style") == "lj" and summary.get(s, "units/time") == "tau"
    assert re.fullmatch(r"([0-9a-f]{40})?", summary.get(s, "terrace/git_commit"))
    assert summary.get(s, "terrace/version") == log_value(
        subprocess.run([run.terrace, "--version"], capture_output=True, text=True).stdout, r"(\d+\.\d+\.\d+)", str)
    assert summary.get(s, "exit/reason") == "finished" and summary.get(s, "exit/status") == 0
    assert summary.get(s, "outputs") == {"thermo_file": "thermo.csv", "summary_file": "lj.summary.json"}
    # no temporary file is left
    assert not [f for f in os.listdir(run.cwd) if f.endswith(".terrace-partial")]


def test_energy_stepping_summary(run):
    from .conftest import REPO
    p = run("es", ES.format(repo=REPO), np_=2)
    s = summary.read(run.path("es.summary.json"))
    t = thermo.read(run.path("es.csv"))
    m = re.search(r"^Events: (\d+) \((\d+) up, (\d+) down, (\d+) reflections\)", p.stdout, re.M)
    events, ups, downs, refl = (int(v) for v in m.groups())
    es = s["energy_stepping"]
    assert (es["events"], es["ups"], es["downs"], es["reflections"]) == (events, ups, downs, refl)
    assert es["events"] == int(t["events"][-1]) and es["reflections"] == int(t["reflections"][-1])
    assert es["mean_event_interval"] == pytest.approx(t["time"][-1] / es["events"], rel=1e-14)
    assert es["ray_evaluations_per_event"] == pytest.approx(
        log_value(p.stdout, r"ray evaluations per event: ([0-9.]+)"), abs=5e-4)
    assert es["terrace_height"] == t["terrace_height"][0]
    assert es["conserved_first"] == pytest.approx(t["e_terraced"][0], rel=1e-13)
    assert es["conserved_last"] == pytest.approx(t["e_terraced"][-1], rel=1e-13)
    assert summary.get(s, "timing/events") == events
    assert summary.get(s, "neighbor/prunes") == log_value(p.stdout, r": (\d+) prunes", int)
    assert summary.get(s, "units/length") == "Angstrom" and summary.get(s, "units/style") == "metal"
    out = summary.get(s, "outputs")
    assert out == {"thermo_file": "es.csv", "trajectory_file": "es.h5", "topology_file": "es.topology.data",
                   "final_atoms_file": "es_final.atoms", "summary_file": "es.summary.json"}
    for f in out.values():
        assert os.path.isfile(run.path(f))


def test_walltime_stop_writes_summary_with_reason(run):
    deck = LJ.format(steps=10**7, extra=", checkpoint_file='ck.h5'").replace("seed=87287 /",
                                                                             "seed=87287, walltime_limit=2.0 /")
    p = run("wall", deck, check=False, timeout=120)
    assert p.returncode == 3, p.stderr
    s = summary.read(run.path("wall.summary.json"))
    assert summary.get(s, "exit/reason") == "walltime_limit"
    assert summary.get(s, "exit/status") == 3
    assert summary.get(s, "exit/detail") == "walltime_limit reached"
    steps = [int(v) for v in re.findall(r"^checkpoint: step (\d+)", p.stdout, re.M)]
    assert summary.get(s, "checkpoint/step") == steps[-1]
    assert summary.get(s, "outputs/checkpoint_file") == "ck.h5"
    assert "simulated_time" not in s["run"]


def test_signal_stop_writes_summary_with_reason(run):
    deck = LJ.format(steps=10**7, extra=", checkpoint_file='ck.h5'")
    with open(run.path("sig.nml"), "w") as f:
        f.write(deck)
    proc = subprocess.Popen([run.terrace, "sig.nml"], cwd=run.cwd, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=dict(os.environ, **MPI_ENV))
    # wait for the run to be under way (its first thermo line), then ask it to stop
    t0 = time.time()
    while time.time() - t0 < 60 and not os.path.exists(run.path("thermo.csv")):
        time.sleep(0.2)
    time.sleep(1.0)
    proc.send_signal(signal.SIGTERM)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 3, err
    s = summary.read(run.path("sig.summary.json"))
    assert summary.get(s, "exit/reason") == "signal"
    assert summary.get(s, "exit/detail") == "SIGTERM received"


def test_failed_run_and_empty_name_write_none(run):
    p = run("bad", LJ.format(steps=10, extra="").replace("cutoff=2.5", "cutoff=-1.0"), check=False)
    assert p.returncode == 1
    assert not os.path.exists(run.path("bad.summary.json"))
    run("off", LJ.format(steps=10, extra=", summary_file=''"))
    assert not [f for f in os.listdir(run.cwd) if "summary" in f]
    run("named", LJ.format(steps=10, extra=", summary_file='sub.json'"))
    assert summary.get(run.path("sub.json"), "outputs/summary_file") == "sub.json"


def test_command_line(run, python):
    run("cli", LJ.format(steps=20, extra=""))
    path = run.path("cli.summary.json")
    package_parent = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([package_parent, os.environ.get("PYTHONPATH", "")]))
    got = subprocess.run([python, "-m", "terrace_tools.summary", "get", path, "timing/loop_time_s"],
                         capture_output=True, text=True, env=env)
    assert got.returncode == 0
    assert float(got.stdout) == json.load(open(path))["timing"]["loop_time_s"]
    missing = subprocess.run([python, "-m", "terrace_tools.summary", "get", path, "timing/nothing"],
                             capture_output=True, text=True, env=env)
    assert missing.returncode == 1
    ok = subprocess.run([python, "-m", "terrace_tools.summary", "check-deck", path], capture_output=True, text=True,
                        env=env, cwd=run.cwd)
    assert ok.returncode == 0, ok.stdout + ok.stderr
    shown = subprocess.run([python, "-m", "terrace_tools.summary", "show", path], capture_output=True, text=True,
                           env=env)
    assert "exit/reason = finished" in shown.stdout.splitlines()


def test_default_name():
    assert summary.default_name("input/run.nml") == "run.summary.json"
    assert summary.default_name("deck") == "deck.summary.json"
    assert summary.default_name("a.b.NML") == "a.b.summary.json"
