#!/usr/bin/env python3
"""What Open MPI's mpirun does with the signals a batch system sends (doc/checkpoints.md).

usage: scripts/signals_mpirun.py TERRACE [NPROCS] [REPEATS]

Runs a 4-rank LJ liquid deck (checkpoint_file set, long enough not to finish) several times and,
once its first checkpoint exists, sends one of: SIGUSR1 to mpirun, SIGTERM to mpirun, SIGTERM to
every rank directly (as SLURM does at the time limit), SIGTERM to one rank only. Prints for each:
mpirun's exit status, seconds from signal to exit, and whether the ranks stopped with a new
checkpoint ("stopped early" in the log).
"""
import os
import signal
import subprocess
import sys
import tempfile
import time

here = os.path.dirname(os.path.abspath(__file__))
deck_src = os.path.join(here, "..", "tests", "regression", "decks", "ckpt_lj.nml")


def children(pid):
    kids = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                stat = open(f"/proc/{d}/stat").read()
            except OSError:
                continue
            name = stat[stat.index("(") + 1:stat.rindex(")")]
            if int(stat[stat.rindex(")") + 2:].split()[1]) == pid and name.startswith("terrace"):
                kids.append(int(d))
    return kids


def trial(terrace, np_, how):
    work = tempfile.mkdtemp(prefix="terrace_sig_")
    text = open(deck_src).read().replace("n_steps=300", "n_steps=100000")
    open(os.path.join(work, "run.nml"), "w").write(text)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1")
    log = open(os.path.join(work, "log"), "w")
    p = subprocess.Popen(["mpirun", "--oversubscribe", "-np", str(np_), terrace, "run.nml"], cwd=work, env=env,
                         stdout=log, stderr=subprocess.STDOUT)
    while not os.path.exists(os.path.join(work, "restart.h5")):
        time.sleep(0.02)
    t0 = time.time()
    if how == "SIGUSR1 to mpirun":
        p.send_signal(signal.SIGUSR1)
    elif how == "SIGTERM to mpirun":
        p.send_signal(signal.SIGTERM)
    elif how == "SIGTERM to every rank":
        for k in children(p.pid):
            os.kill(k, signal.SIGTERM)
    elif how == "SIGTERM to one rank":
        os.kill(sorted(children(p.pid))[-1], signal.SIGTERM)
    rc = p.wait(timeout=120)
    dt = time.time() - t0
    text = open(os.path.join(work, "log")).read()
    stopped = "stopped early" in text
    subprocess.run(["rm", "-rf", work])
    return rc, dt, stopped


def main():
    terrace = os.path.realpath(sys.argv[1])
    np_ = int(sys.argv[2]) if len(sys.argv) > 2 else 4
    repeats = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    print(f"{'signal':24s} {'mpirun exit':>11s} {'seconds':>8s}  checkpoint + 'stopped early'")
    for how in ("SIGUSR1 to mpirun", "SIGTERM to mpirun", "SIGTERM to every rank", "SIGTERM to one rank"):
        for _ in range(repeats):
            rc, dt, stopped = trial(terrace, np_, how)
            print(f"{how:24s} {rc:11d} {dt:8.2f}  {'yes' if stopped else 'no'}")


if __name__ == "__main__":
    main()
