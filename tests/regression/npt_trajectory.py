#!/usr/bin/env python3
"""A trajectory of a run whose box changes (a barostat): H5MD's box/edges is a time series, one row
per frame, and every reader uses each frame's box.

A 500-atom LJ liquid compressed by C-rescale from P* = -0.4 towards P* = 20 (the box edge falls by
about 10 %) on 2 ranks, a frame and a thermo row every 20 steps. Asserts:
  1. box/edges/value[f] equals the thermo row's box_lx, box_ly, box_lz at the frame's step (1e-12);
     the edges change by more than 5 % over the run;
  2. terrace_tools.h5md.read gives each frame's box (frame_edges) and unwraps each frame with it
     (x + image * edges[f]; the first frame's box would be off by more than 0.5 sigma here);
  3. terrace-analyze's g(r) equals an independent numpy g(r) with each frame's box (minimum image,
     <V h(r)> normalisation) to 1e-9, and its MSD equals numpy's over every origin from positions
     unwrapped with each frame's box to 1e-9;
  4. a run started from the last frame (&system read_h5md) starts in that frame's box.

usage: npt_trajectory.py TERRACE TERRACE_ANALYZE OUTDIR   (scripts/ on PYTHONPATH, as CTest sets it)
"""
import csv
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

from terrace_tools import h5md

ENV = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
           OMPI_MCA_rmaps_base_oversubscribe="1")
DECK = """&run units='lj', dimension=3, n_steps=400, seed=4242 /
&system {system} /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.true. /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&thermostat style='csvr', temperature=1.2, damping=0.5 /
&barostat style='c_rescale', pressure=20.0, damping=0.2, compressibility=0.2 /
&output thermo_every=20, thermo_file='{stem}.csv', trajectory_file='{stem}.h5', trajectory_every=20,
        trajectory_fields='position velocity image' /
"""
FAILS = []


def check(ok, what):
    print(("ok   " if ok else "FAIL ") + what)
    if not ok:
        FAILS.append(what)


def run(cmd, cwd):
    p = subprocess.run(cmd, cwd=cwd, env=ENV, capture_output=True, text=True, timeout=600)
    if p.returncode != 0:
        print(p.stdout[-3000:], p.stderr[-3000:])
        sys.exit(f"FAIL: {' '.join(cmd)} exited {p.returncode}")
    return p.stdout


def rows(path):
    return list(csv.DictReader(open(path)))


def main():
    terrace, analyze, out = (os.path.abspath(a) for a in sys.argv[1:4])
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    system = ("lattice='fcc', density=0.8442, cells=5,5,5, periodic=.true.,.true.,.true., mass=1.0, "
              "temperature=1.44")
    with open(os.path.join(out, "npt.nml"), "w") as f:
        f.write(DECK.format(system=system, stem="npt"))
    run(["mpirun", "--oversubscribe", "-np", "2", terrace, "npt.nml"], out)

    # 1. the box of every frame
    th = {int(r["step"]): r for r in rows(os.path.join(out, "npt.csv"))}
    with h5py.File(os.path.join(out, "npt.h5"), "r") as h:
        edges = h["particles/all/box/edges/value"][()]
        steps = h["particles/all/box/edges/step"][()]
    want = np.array([[float(th[int(s)][k]) for k in ("box_lx", "box_ly", "box_lz")] for s in steps])
    err = np.abs(edges - want).max() / want.max()
    change = 1 - edges[:, 0].min() / edges[0, 0]
    check(len(steps) == 21 and err < 1e-12 and change > 0.05,
          f"box/edges/value: {len(steps)} frames, each the thermo's box to {err:.1e}; the edge changes by {change:.1%}")

    # 2. unwrapping with each frame's box
    fr = h5md.read(os.path.join(out, "npt.h5"))
    wrapped = h5md.read(os.path.join(out, "npt.h5"), unwrap=False)
    with h5py.File(os.path.join(out, "npt.h5"), "r") as h:
        img = h["particles/all/image/value"][()]
    uerr = np.abs(fr["x"] - (wrapped["x"] + img * edges[:, None, :])).max()
    stale = np.abs(fr["x"] - (wrapped["x"] + img * edges[0][None, None, :])).max()
    check(np.allclose(fr["frame_edges"], edges, rtol=0, atol=0) and uerr < 1e-12 and stale > 0.5,
          f"terrace_tools.h5md.read: each frame unwrapped with its own box (to {uerr:.1e}; the first frame's "
          f"box would be off by {stale:.2f} sigma)")

    # 3. terrace-analyze g(r) and MSD against numpy with each frame's box
    run([analyze, "--trajectory_file=npt.h5", "--compute=rdf,msd", "--output_prefix=npt", "--rdf_bins=100",
         "--msd_blocks=2", "--msd_max_time=0.5", "--msd_fit_start=0.1", "--msd_fit_end=0.5"], out)
    r_tab = np.loadtxt(os.path.join(out, "npt_rdf.csv"), delimiter=",", skiprows=1, ndmin=2)
    x = wrapped["x"]
    nf, n, _ = x.shape
    r_max = 0.5 * edges.min()
    nb = 100
    hv = np.zeros(nb)
    iu = np.triu_indices(n, 1)
    for f in range(nf):
        d = x[f][:, None, :] - x[f][None, :, :]
        d -= edges[f] * np.round(d / edges[f])
        r = np.sqrt((d ** 2).sum(-1))[iu]
        h_, _ = np.histogram(r[r < r_max], bins=nb, range=(0, r_max))
        hv += np.prod(edges[f]) * h_
    rb = np.linspace(0, r_max, nb + 1)
    g = hv / (nf * 0.5 * n * (n - 1) * 4 * np.pi / 3 * (rb[1:] ** 3 - rb[:-1] ** 3))
    gerr = np.abs(r_tab[:, 1] - g).max()
    check(gerr < 1e-9 and g.max() > 1.5, f"terrace-analyze g(r) = numpy's with each frame's box to {gerr:.1e} "
          f"(peak {g.max():.3f})")
    m_tab = np.loadtxt(os.path.join(out, "npt_msd.csv"), delimiter=",", skiprows=1, ndmin=2)
    u = fr["x"]
    lags = np.rint(m_tab[:, 0] / (fr["time"][1] - fr["time"][0])).astype(int)
    msd = np.array([((u[m:] - u[:nf - m]) ** 2).sum(-1).mean() for m in lags])
    merr = np.abs(m_tab[:, 1] - msd).max() / msd.max()
    check(merr < 1e-9 and len(lags) > 3, f"terrace-analyze MSD = numpy's over {len(lags)} lags to {merr:.1e} relative")

    # 4. a run from the last frame starts in its box
    with open(os.path.join(out, "from_frame.nml"), "w") as f:
        f.write(DECK.format(system="read_h5md='npt.h5', h5md_frame=-1, mass=1.0", stem="from_frame")
                .replace("n_steps=400", "n_steps=20"))
    run([terrace, "from_frame.nml"], out)
    r0 = rows(os.path.join(out, "from_frame.csv"))[0]
    b0 = np.array([float(r0[k]) for k in ("box_lx", "box_ly", "box_lz")])
    check(np.abs(b0 - edges[-1]).max() < 1e-12 * edges.max(),
          f"a run from the last frame starts in its box ({b0[0]:.6f}, the frame's {edges[-1][0]:.6f})")
    print("PASS" if not FAILS else f"FAIL ({len(FAILS)})")
    return 1 if FAILS else 0


if __name__ == "__main__":
    sys.exit(main())
