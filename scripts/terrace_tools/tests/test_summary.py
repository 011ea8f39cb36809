"""The run summary against independent records of the same run: the deck, the thermo CSV, the
checkpoint file, its own identities (phases that add up to the loop time), and the files it lists."""
import json
import os
import re
import signal
import subprocess
import time
import zlib

import h5py
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


@pytest.mark.parametrize("np_", [1, 2])
def test_verlet_summary_against_deck_and_csv(run, np_):
    run("lj", LJ.format(steps=200, extra=""), np_=np_)
    s = summary.read(run.path("lj.summary.json"))
    t = thermo.read(run.path("thermo.csv"))
    natoms = summary.get(s, "run/atoms")
    assert natoms == 500 == summary.get(s, "timing/atoms")
    # the deck's steps; the phases (Other is the loop's remainder) add up to the loop time
    loop = summary.get(s, "timing/loop_time_s")
    assert summary.get(s, "timing/steps") == 200
    assert loop > 0 and summary.get(s, "timing/atom_steps_per_s") == pytest.approx(500 * 200 / loop, rel=1e-14)
    phases = summary.get(s, "timing/phases")
    assert list(phases) == ["Pair", "Neigh", "Comm", "Output", "Search", "Other"]
    assert sum(v["avg_s"] for v in phases.values()) == pytest.approx(loop, rel=1e-12)
    for v in phases.values():
        assert v["max_s"] >= v["avg_s"] - 1e-15 * loop
        assert v["percent_loop"] == pytest.approx(100 * v["avg_s"] / loop, rel=1e-12, abs=1e-12)
    assert phases["Pair"]["avg_s"] > 0
    # an exact list on a liquid at T* = 1.44: rebuilt, but not at every step
    assert 2 <= summary.get(s, "neighbor/builds") < 200
    assert summary.get(s, "neighbor/list_pairs") > 0
    # the energy drift and momentum change: what the thermo CSV gives (same doubles, 17 digits)
    assert summary.get(s, "conservation/energy_drift_per_atom_time") == pytest.approx(
        thermo.energy_drift(t, natoms), rel=1e-12)
    assert summary.get(s, "conservation/momentum_change") == pytest.approx(thermo.momentum_change(t), rel=1e-6,
                                                                          abs=1e-15)
    assert summary.get(s, "run/simulated_time") == pytest.approx(t["time"][-1], rel=1e-15)
    # the last thermo sample: the CSV's last row (17 digits both)
    for k in ("step", "time", "temp", "pe", "ke", "etotal", "press"):
        assert summary.get(s, "thermo_last/" + k) == pytest.approx(t[k][-1], rel=1e-15, abs=1e-300)
    # the peak memory of every rank: at least the binary and its libraries, far below a GiB per rank here
    assert 1.0 * np_ < summary.get(s, "memory/peak_mib_all_ranks") < 1024.0 * np_
    # identity of the run
    assert summary.get(s, "deck/crc32") == "%08x" % zlib.crc32(open(run.path("lj.nml"), "rb").read())
    assert summary.get(s, "deck/path") == "lj.nml"
    assert summary.get(s, "machine/ranks") == np_
    assert summary.get(s, "units/style") == "lj" and summary.get(s, "units/time") == "tau"
    assert re.fullmatch(r"([0-9a-f]{40})?", summary.get(s, "terrace/git_commit"))
    assert summary.get(s, "terrace/version") in subprocess.run([run.terrace, "--version"], capture_output=True,
                                                               text=True).stdout.split()
    assert summary.get(s, "exit/reason") == "finished" and summary.get(s, "exit/status") == 0
    assert summary.get(s, "outputs") == {"thermo_file": "thermo.csv", "summary_file": "lj.summary.json"}
    # no temporary file is left
    assert not [f for f in os.listdir(run.cwd) if f.endswith(".terrace-partial")]


def test_energy_stepping_summary(run):
    from .conftest import REPO
    run("es", ES.format(repo=REPO), np_=2)
    s = summary.read(run.path("es.summary.json"))
    t = thermo.read(run.path("es.csv"))
    es = s["energy_stepping"]
    events = es["events"]
    # every event goes up, down or is reflected; the thermo CSV counts the same events and reflections
    assert events > 0 and es["ups"] + es["downs"] + es["reflections"] == events
    assert es["events"] == int(t["events"][-1]) and es["reflections"] == int(t["reflections"][-1])
    assert es["mean_event_interval"] == pytest.approx(t["time"][-1] / es["events"], rel=1e-14)
    # an event takes at least one ray evaluation and one force pass
    assert es["ray_evaluations_per_event"] >= 1.0 and es["force_passes_per_event"] >= 1.0
    assert es["terrace_height"] == t["terrace_height"][0]
    assert es["conserved_first"] == pytest.approx(t["e_terraced"][0], rel=1e-13)
    assert es["conserved_last"] == pytest.approx(t["e_terraced"][-1], rel=1e-13)
    assert summary.get(s, "timing/events") == events
    assert summary.get(s, "neighbor/prunes") >= 0
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
    # the step and time of the checkpoint file it names (its /state attributes)
    with h5py.File(run.path("ck.h5"), "r") as ck:
        assert summary.get(s, "checkpoint/step") == int(ck["state"].attrs["step"]) > 0
        assert summary.get(s, "checkpoint/time") == float(ck["state"].attrs["time"])
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
    # the phase table: every phase's average and slowest rank, to the 4 decimals it prints
    table = subprocess.run([python, "-m", "terrace_tools.summary", "phases", path], capture_output=True, text=True,
                           env=env)
    assert table.returncode == 0, table.stderr
    lines = table.stdout.splitlines()
    phases = json.load(open(path))["timing"]["phases"]
    rows = {ln.split()[0]: [float(x) for x in ln.split()[1:]] for ln in lines[2:-1]}
    assert list(rows) == list(phases)
    for name, (avg, mx, pct) in rows.items():
        assert (avg, mx) == (round(phases[name]["avg_s"], 4), round(phases[name]["max_s"], 4))
    assert lines[-1] == "list builds: %d" % json.load(open(path))["neighbor"]["builds"]


def test_default_name():
    assert summary.default_name("input/run.nml") == "run.summary.json"
    assert summary.default_name("deck") == "deck.summary.json"
    assert summary.default_name("a.b.NML") == "a.b.summary.json"
