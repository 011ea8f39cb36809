#!/usr/bin/env python3
"""terrace-analyze on bad input: every case must exit with the expected status (1: bad input or
file, 2: bad command line), print exactly one 'terrace: error' line holding every listed substring
(file, group/dataset or key, what is wrong), write no output file, and not hang (60 s). Cases run on
1 rank; those marked np2 also on 2 ranks.

usage: bad_inputs.py TERRACE_ANALYZE WORKDIR
"""
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

from common import MPI_ENV, Checks, write_h5md  # noqa: E402

exe, work = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
files = os.path.join(work, "files")
os.makedirs(files)
c = Checks()

# ---------------------------------------------------------------- the input files
nf, n = 40, 16
t = np.arange(nf) * 0.01
rng = np.random.default_rng(1)
x = rng.uniform(0, 10, size=(nf, n, 3))
v = rng.normal(size=(nf, n, 3))
img = np.zeros((nf, n, 3), np.int32)
F = lambda name: os.path.join(files, name)  # noqa: E731
write_h5md(F("good.h5"), 3, positions=x, velocities=v, images=img, times=t, edges=[10, 10, 10])
write_h5md(F("no_velocity.h5"), 3, positions=x, times=t, edges=[10, 10, 10])
write_h5md(F("velocity_shape.h5"), 3, positions=x, velocities=v[:, :-1], times=t, edges=[10, 10, 10])
write_h5md(F("image_frames.h5"), 3, positions=x, images=img[:-1], times=t, edges=[10, 10, 10])
write_h5md(F("uneven_time.h5"), 3, positions=x, velocities=v, times=t ** 1.5, edges=[10, 10, 10])
t_nan = t.copy(); t_nan[7] = float("nan")
write_h5md(F("nan_time.h5"), 3, positions=x, velocities=v, times=t_nan, edges=[10, 10, 10])
t_back = t.copy(); t_back[7] = t[3]
write_h5md(F("backward_time.h5"), 3, positions=x, velocities=v, times=t_back, edges=[10, 10, 10])
write_h5md(F("free.h5"), 3, positions=x, velocities=v, times=t, boundary=["none"] * 3)
write_h5md(F("no_time.h5"), 3, positions=x, images=img, edges=[10, 10, 10])
write_h5md(F("box_frames.h5"), 3, positions=x[:10], times=t[:10], edges=[10, 10, 10], edges_series=True)
with h5py.File(F("box_frames.h5"), "a") as f:
    e = f["particles/all/box/edges/value"][:]
    del f["particles/all/box/edges/value"]
    f["particles/all/box/edges/value"] = e[:7]
write_h5md(F("time_length.h5"), 3, positions=x, times=t, edges=[10, 10, 10])
with h5py.File(F("time_length.h5"), "a") as f:
    del f["particles/all/position/time"]
    f["particles/all/position/time"] = t[:-3]
with h5py.File(F("position_rank2.h5"), "w") as f:
    f["particles/all/position/value"] = x[0]
with open(F("not_hdf5.h5"), "w") as f:
    f.write("this is not an HDF5 file\n")
with open(F("unknown_key.nml"), "w") as f:
    f.write("&analysis trajectory_file='good.h5', compute='rdf',\n  rdf_binz=100 /\n")
with open(F("two_groups.nml"), "w") as f:
    f.write("&analysis trajectory_file='good.h5', compute='rdf' /\n&output x=1 /\n")

# name | exit | arguments | substrings | np2
cases = [
    ("missing_file", 1, "--trajectory_file=nope.h5 --compute=rdf", ["nope.h5", "trajectory_file", "cannot open"], True),
    ("not_hdf5", 1, "--trajectory_file=not_hdf5.h5 --compute=rdf", ["not_hdf5.h5", "not an HDF5"], False),
    ("no_velocity_for_vdos", 1, "--trajectory_file=no_velocity.h5 --compute=vdos",
     ["no_velocity.h5", "/particles/all/velocity/value", "missing", "VDOS needs velocities"], True),
    ("no_particles_group", 1, "--trajectory_file=good.h5 --compute=rdf --particles_group=atoms",
     ["good.h5", "/particles/atoms", "missing"], False),
    ("velocity_wrong_shape", 1, "--trajectory_file=velocity_shape.h5 --compute=vdos",
     ["velocity_shape.h5", "velocity/value", "wrong shape"], True),
    ("image_wrong_frames", 1, "--trajectory_file=image_frames.h5 --compute=msd",
     ["image_frames.h5", "image/value", "wrong shape", "39 frames"], False),
    ("position_rank2", 1, "--trajectory_file=position_rank2.h5 --compute=rdf",
     ["position_rank2.h5", "position/value", "wrong shape"], False),
    ("too_few_frames_vacf", 1, "--trajectory_file=good.h5 --compute=vdos --correlation_time=0.3",
     ["&analysis", "correlation_time", "too few frames", "good.h5", "40 frames"], True),
    ("too_few_frames_msd", 1, "--trajectory_file=good.h5 --compute=msd --msd_max_time=0.2",
     ["&analysis", "msd_max_time", "too few frames", "good.h5"], False),
    ("uneven_time", 1, "--trajectory_file=uneven_time.h5 --compute=vdos",
     ["uneven_time.h5", "velocity/time", "not equally spaced"], False),
    ("nan_time", 1, "--trajectory_file=nan_time.h5 --compute=vdos",
     ["nan_time.h5", "velocity/time", "do not increase", "not finite"], False),
    ("backward_time", 1, "--trajectory_file=backward_time.h5 --compute=msd",
     ["backward_time.h5", "position/time", "do not increase"], False),
    ("no_time_for_msd", 1, "--trajectory_file=no_time.h5 --compute=msd",
     ["no_time.h5", "position/time", "missing"], False),
    ("time_wrong_length", 1, "--trajectory_file=time_length.h5 --compute=rdf",
     ["time_length.h5", "position/time", "wrong shape"], False),
    ("box_series_wrong_frames", 1, "--trajectory_file=box_frames.h5 --compute=rdf",
     ["box_frames.h5", "box/edges/value", "wrong shape"], False),
    ("rdf_r_max_beyond_half_box", 1, "--trajectory_file=good.h5 --compute=rdf --rdf_r_max=6",
     ["&analysis", "rdf_r_max", "larger than half"], False),
    ("sq_free_box", 1, "--trajectory_file=free.h5 --compute=sq",
     ["free.h5", "/particles/all/box", "periodic box"], False),
    ("last_frame_beyond", 1, "--trajectory_file=good.h5 --compute=rdf --last_frame=41",
     ["last_frame", "beyond the last frame", "40 frames"], False),
    ("unknown_compute", 1, "--trajectory_file=good.h5 --compute=rdf,gofr", ["compute", "unknown analysis", "gofr"], False),
    ("missing_trajectory_file", 1, "--compute=rdf", ["&analysis", "trajectory_file", "missing"], False),
    ("missing_compute", 1, "--trajectory_file=good.h5", ["&analysis", "compute", "missing"], False),
    ("wrong_type", 1, "--trajectory_file=good.h5 --compute=rdf --rdf_bins=many",
     ["&analysis", "rdf_bins", "expected an integer"], False),
    ("rdf_bins_huge", 1, "--trajectory_file=good.h5 --compute=rdf --rdf_bins=2000000000",
     ["&analysis", "rdf_bins", "between 1 and 10000000"], False),
    ("window_unknown", 1, "--trajectory_file=good.h5 --compute=vdos --window=hamming",
     ["&analysis", "window", "hamming", "allowed"], False),
    ("unknown_key_in_file", 1, "unknown_key.nml", ["unknown_key.nml:2", "&analysis", "rdf_binz", "unknown key"], True),
    ("unknown_group_in_file", 1, "two_groups.nml", ["two_groups.nml:2", "&output", "unknown namelist group"], False),
    ("missing_namelist_file", 1, "nothere.nml", ["nothere.nml", "cannot open"], False),
    ("unknown_flag", 2, "--trajectory_file=good.h5 --compute=rdf --bins=3", ["--bins", "unknown option"], False),
]

for name, want, args, subs, np2 in cases:
    for nprocs in ([1, 2] if np2 else [1]):
        wd = os.path.join(work, f"{name}.np{nprocs}")
        shutil.copytree(files, wd)
        before = set(os.listdir(wd))
        cmd = [exe] + args.split()
        if nprocs > 1:
            cmd = ["mpirun", "--oversubscribe", "-np", str(nprocs)] + cmd
        try:
            p = subprocess.run(cmd, cwd=wd, env=MPI_ENV, capture_output=True, text=True, timeout=60)
        except subprocess.TimeoutExpired:
            c.check(False, f"np={nprocs} {name}: hang (killed after 60 s)")
            continue
        lines = [ln for ln in p.stderr.splitlines() if ln.startswith("terrace: error")]
        new = sorted(set(os.listdir(wd)) - before)
        why = []
        if p.returncode != want:
            why.append(f"exit {p.returncode}, expected {want}")
        if len(lines) != 1:
            why.append(f"{len(lines)} 'terrace: error' lines")
        missing = [s for s in subs if not lines or s not in lines[0]]
        if missing:
            why.append(f"message lacks {missing}")
        if new:
            why.append(f"files written: {new}")
        c.check(not why, f"np={nprocs} {name}" + (": " + "; ".join(why) if why else "") +
                (f" | {lines[0]}" if lines else ""))

# control: the good file runs and writes its outputs
wd = os.path.join(work, "control")
shutil.copytree(files, wd)
p = subprocess.run([exe, "--trajectory_file=good.h5", "--compute=vdos,rdf,msd,sq"], cwd=wd, env=MPI_ENV,
                   capture_output=True, text=True, timeout=60)
outs = sorted(f for f in os.listdir(wd) if f.startswith("analysis_"))
c.check(p.returncode == 0 and len(outs) == 6, f"control: the good file runs (exit {p.returncode}) and writes {outs}")
c.finish()
