#!/usr/bin/env python3
"""A restart whose trajectory cannot be continued (&system restart_outputs).

usage: restart_new_outputs.py TERRACE DECK OUTDIR NPROCS

DECK writes a thermo CSV (thermo.csv), an H5MD trajectory (traj.h5), a final state (final.txt) and
checkpoints (restart.h5). The test:
  1. runs it uninterrupted (the reference);
  2. runs it with &run walltime_limit = 1e-6: it stops at its first safe point with a checkpoint
     (exit status 3) at step S;
  3. damages traj.h5 as a SIGKILL inside HDF5's flush does (the file is shorter than its superblock
     says: h5py refuses it) and restarts: exit status 1, an error that names restart_outputs, and
     thermo.csv and traj.h5 left byte for byte as they were;
  4. restarts with restart_outputs = 'new' and walltime_limit = 1e-6: exit status 3, a new
     checkpoint, the run writing thermo.part2.csv and traj.part2.h5;
  5. gives traj.part2.h5's position one frame more than its velocity (a kill between the two
     elements' writes of a frame) and restarts from that checkpoint without restart_outputs: it
     appends to the part-2 files (output_part in the checkpoint) and finishes.
Then final.txt must equal the reference byte for byte, thermo.part2.csv must be the reference's
header and its lines after step S, every time series of traj.part2.h5 (step, time, value) the
reference's frames after step S exactly, and the damaged files must be untouched.
"""
import os
import re
import shutil
import sys

import h5py
import numpy as np

from checkpoint_restart import fail, make_deck, run as run_deck  # (the same deck edits and runs)
from terrace_tools import summary


def deck(src, dst, walltime=False, restart=False, outputs=None):
    make_deck(src, dst, walltime="1e-6" if walltime else None, restart="restart.h5" if restart else None)
    if outputs:
        text = open(dst).read()
        open(dst, "w").write(re.sub(r"&system\s", f"&system restart_outputs='{outputs}', ", text, count=1))


def run(terrace, np_, name, cwd, expect):
    """Run NAME.nml in cwd (log NAME.log), expecting that exit status; return the log."""
    run_deck(terrace, np_, name + ".nml", cwd, name + ".log", expect)
    return open(os.path.join(cwd, name + ".log")).read()


def series(f):
    """Every time series of an H5MD file: path of its value -> (step, time, value)."""
    out = {}

    def visit(name, obj):
        if isinstance(obj, h5py.Group) and "value" in obj and "step" in obj:
            out[name] = (obj["step"][()], obj["time"][()], obj["value"][()])
    f.visititems(visit)
    return out


def main():
    if len(sys.argv) != 5:
        fail(__doc__)
    terrace, src, outdir, np_ = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2]), sys.argv[3], int(sys.argv[4])
    shutil.rmtree(outdir, ignore_errors=True)
    ref, wd = os.path.join(outdir, "ref"), os.path.join(outdir, "int")
    os.makedirs(ref)
    os.makedirs(wd)
    deck(src, os.path.join(ref, "run.nml"))
    run(terrace, np_, "run", ref, 0)

    deck(src, os.path.join(wd, "stop.nml"), walltime=True)
    run(terrace, np_, "stop", wd, 3)
    s = summary.get(os.path.join(wd, "stop.summary.json"), "checkpoint/step", None)
    if s is None or summary.get(os.path.join(wd, "stop.summary.json"), "exit/reason") != "walltime_limit":
        fail("the stopped run's summary names no checkpoint, or another exit reason than walltime_limit")

    # a kill inside HDF5's flush: the superblock's end of file lies beyond the file's end
    traj = os.path.join(wd, "traj.h5")
    os.truncate(traj, os.path.getsize(traj) - 12000)
    try:
        h5py.File(traj, "r").close()
        fail("the shortened trajectory still opens: the test does not damage it")
    except OSError:
        pass
    before = {n: open(os.path.join(wd, n), "rb").read() for n in ("thermo.csv", "traj.h5")}

    deck(src, os.path.join(wd, "append.nml"), restart=True)
    log = run(terrace, np_, "append", wd, 1)
    if "restart_outputs = 'new'" not in log:
        fail("the failed restart does not name &system restart_outputs = 'new':\n" + log[-2000:])
    for n, b in before.items():
        if open(os.path.join(wd, n), "rb").read() != b:
            fail(f"the failed restart changed {n}")
    if os.path.exists(os.path.join(wd, "thermo.part2.csv")) or os.path.exists(os.path.join(wd, "traj.part2.h5")):
        fail("the failed restart wrote part files")

    deck(src, os.path.join(wd, "new.nml"), walltime=True, restart=True, outputs="new")
    log = run(terrace, np_, "new", wd, 3)
    if "the run goes on in thermo.part2.csv and traj.part2.h5" not in log:
        fail("restart_outputs = 'new' did not say where the run goes on:\n" + log[-2000:])
    # its run summary is a part file too, and names the part files it wrote
    s2 = summary.get(os.path.join(wd, "new.summary.part2.json"), "checkpoint/step")
    if summary.get(os.path.join(wd, "new.summary.part2.json"), "outputs") != {
            "thermo_file": "thermo.part2.csv", "trajectory_file": "traj.part2.h5",
            "topology_file": "traj.part2.topology.data", "checkpoint_file": "restart.h5",
            "summary_file": "new.summary.part2.json"}:
        fail("the run summary of restart_outputs = 'new' does not list its part files: "
             + str(summary.get(os.path.join(wd, "new.summary.part2.json"), "outputs")))
    if s2 < s:
        fail(f"the second checkpoint (step {s2}) lies before the first (step {s})")
    # a kill between two elements' writes of a frame past the checkpoint: position holds one frame
    # more than velocity; the appending restart cuts both back to the checkpoint's frames
    with h5py.File(os.path.join(wd, "traj.part2.h5"), "r+") as f:
        pos = f["particles/all/position/value"]
        nf = pos.shape[0]
        if f["particles/all/velocity/value"].shape[0] != nf:
            fail("traj.part2.h5: position and velocity already hold different numbers of frames")
        pos.resize(nf + 1, axis=0)
        pos[nf] = np.full(pos.shape[1:], 1.0e30)
    run(terrace, np_, "append", wd, 0)       # appends to the part-2 files (the checkpoint's output_part)

    for n, b in before.items():
        if open(os.path.join(wd, n), "rb").read() != b:
            fail(f"the restarts changed {n}")
    if open(os.path.join(wd, "final.txt"), "rb").read() != open(os.path.join(ref, "final.txt"), "rb").read():
        fail("final.txt differs from the uninterrupted run's")
    ref_lines = open(os.path.join(ref, "thermo.csv")).read().splitlines()
    want = [ref_lines[0]] + [l for l in ref_lines[1:] if int(l.split(",")[0]) > s]
    got = open(os.path.join(wd, "thermo.part2.csv")).read().splitlines()
    if got != want:
        fail(f"thermo.part2.csv: {len(got)} lines, expected the reference's header and its {len(want) - 1} lines "
             f"after step {s}")
    a, b = series(h5py.File(os.path.join(ref, "traj.h5"), "r")), series(h5py.File(os.path.join(wd, "traj.part2.h5"), "r"))
    if sorted(a) != sorted(b):
        fail(f"traj.part2.h5 holds other time series: {sorted(set(a) ^ set(b))}")
    frames = 0
    for name, (step, t, value) in a.items():
        keep = step > s
        bs, bt, bv = b[name]
        if not (np.array_equal(step[keep], bs) and np.array_equal(t[keep], bt) and np.array_equal(value[keep], bv)):
            fail(f"traj.part2.h5 {name}: not the reference's frames after step {s}")
        frames = max(frames, int(keep.sum()))
    if frames == 0:
        fail(f"the reference has no frame after step {s}: nothing was compared")
    print(f"PASS restart_outputs on {np_} rank(s): checkpoints at steps {s} and {s2}; the damaged traj.h5 "
          f"stopped the appending restart with a pointer to restart_outputs; 'new' then went on in "
          f"thermo.part2.csv and traj.part2.h5, continued by a second restart (over a frame that only one element "
          f"held): {len(want) - 1} thermo lines and "
          f"{frames} frames equal to the uninterrupted run's after step {s}, final state byte for byte")


if __name__ == "__main__":
    main()
