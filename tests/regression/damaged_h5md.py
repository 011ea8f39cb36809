#!/usr/bin/env python3
"""Damaged H5MD files: non-finite numbers, and one damaged byte that
makes HDF5 spin.

usage: damaged_h5md.py TERRACE TERRACE_ANALYZE OUTDIR

Terrace writes a small trajectory (metal units: its unit attributes are variable-length strings,
kept in HDF5's global heap). First, copies with one NaN or Inf in position/value or velocity/value
(first, middle and last frame) are given to terrace-analyze (rdf / vdos) and to the engine
(&system read_h5md, the frame holding the bad value), 1 and 3 ranks: non-zero exit, exactly one
'terrace: error' line naming the file, the dataset and 'NaN or infinite', and nothing blaming the
time step. Then The test flips single bytes of the global heap collection (after its
'GCOL' signature), one at a time, and opens each copy with h5py in a subprocess with a 3 s limit
until one hangs (the size field of a heap object does, with HDF5 1.10). With that file:
  - terrace-analyze on 1 and 3 ranks, and the engine with &system read_h5md on 1 and 3 ranks,
    must exit non-zero within 20 s (TERRACE_IO_WATCHDOG_S=5), with exactly one 'terrace: error:'
    line naming the file and saying HDF5 is stuck, and no crash text.
Where no flip makes h5py hang (another HDF5), the test says so and exits 77 (skipped).
"""
import os
import shutil
import subprocess
import sys
import time

DECK = """&run units='metal', n_steps=20, seed=3 /
&system lattice='fcc', lattice_constant=5.26, cells=4,4,4, mass=39.948, temperature=80.0 /
&potential style='lj', epsilon=0.0104, sigma=3.4, cutoff=8.5 /
&integrator style='velocity_verlet', dt=0.002 /
&output thermo_every=10, trajectory_file='t.h5', trajectory_every=2, trajectory_fields='position velocity' /
"""
READ = """&run units='metal', n_steps=5, seed=3 /
&system read_h5md='bad.h5', mass=39.948 /
&potential style='lj', epsilon=0.0104, sigma=3.4, cutoff=8.5 /
&integrator style='velocity_verlet', dt=0.002 /
"""
PROBE = """import h5py, sys
f = h5py.File(sys.argv[1], 'r')
def visit(name, obj):
    for k, v in obj.attrs.items():
        pass
f.visititems(visit)
"""
CRASH = ("backtrace", "sigsegv", "segmentation", "program received", "core dumped")


def main():
    terrace, analyze, out = (os.path.abspath(a) for a in sys.argv[1:4])
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1", TERRACE_IO_WATCHDOG_S="5")
    open(os.path.join(out, "deck.nml"), "w").write(DECK)
    p = subprocess.run([terrace, "deck.nml"], cwd=out, env=env, capture_output=True, text=True)
    if p.returncode != 0:
        sys.exit("FAIL the run that writes the trajectory: " + p.stderr)
    fails = 0

    def expect(what, np_, cmd, must):
        full = cmd if np_ == 1 else ["mpirun", "--oversubscribe", "-np", str(np_)] + cmd
        t0 = time.time()
        try:
            p = subprocess.run(full, cwd=out, env=env, capture_output=True, text=True, timeout=20)
            rc, text = p.returncode, p.stdout + p.stderr
        except subprocess.TimeoutExpired:
            rc, text = 124, "timed out"
        dt = time.time() - t0
        errs = [l for l in text.splitlines() if l.startswith("terrace: error")]
        why = ""
        if rc in (0, 124, 137):
            why = "exit %d" % rc
        elif any(c in text.lower() for c in CRASH):
            why = "crash text"
        elif len(errs) != 1:
            why = "%d error lines" % len(errs)
        elif any(m not in errs[0] for m in must) or "time step" in errs[0]:
            why = "message: " + errs[0]
        if why:
            print("FAIL  %s np=%d: %s\n%s" % (what, np_, why, text[-800:]))
            return 1
        print("ok    %s np=%d: exit %d after %.1f s: %s" % (what, np_, rc, dt, errs[0]))
        return 0

    import h5py
    import numpy as np
    with h5py.File(os.path.join(out, "t.h5"), "r") as f:
        nframes = f["particles/all/position/value"].shape[0]
    for field, frame, atom, bad in (("position", 0, 0, np.nan), ("position", nframes // 2, 100, np.inf),
                                    ("velocity", nframes - 1, 255, np.nan)):
        shutil.copy(os.path.join(out, "t.h5"), os.path.join(out, "nan.h5"))
        with h5py.File(os.path.join(out, "nan.h5"), "r+") as f:
            d = f["particles/all/%s/value" % field]
            a = d[...]
            a[frame, atom, 1] = bad
            d[...] = a
        open(os.path.join(out, "nan.nml"), "w").write(
            READ.replace("read_h5md='bad.h5'", "read_h5md='nan.h5', h5md_frame=%d" % (frame + 1)))
        must = ["nan.h5", "/particles/all/%s/value" % field, "NaN or infinite"]
        tag = "%s %s frame %d" % (field, "NaN" if np.isnan(bad) else "Inf", frame + 1)
        for np_ in (1, 3):
            compute = "rdf" if field == "position" else "vdos"
            fails += expect("terrace-analyze --compute=%s, %s" % (compute, tag), np_,
                            [analyze, "--trajectory_file=nan.h5", "--compute=" + compute], must)
            fails += expect("terrace read_h5md, %s" % tag, np_, [terrace, "nan.nml"], must)

    data = open(os.path.join(out, "t.h5"), "rb").read()
    open(os.path.join(out, "probe.py"), "w").write(PROBE)
    gcol = data.find(b"GCOL")
    found = None
    for off in range(gcol + 16, gcol + 200):   # the heap objects (after the 16-byte header)
        b = bytearray(data)
        b[off] ^= 0xFF
        open(os.path.join(out, "bad.h5"), "wb").write(b)
        try:
            subprocess.run(["/usr/bin/python3", "probe.py", "bad.h5"], cwd=out, capture_output=True, timeout=3)
        except subprocess.TimeoutExpired:
            found = off
            break
    if found is None:
        print("SKIP: no single-byte flip of the global heap makes h5py hang with this HDF5 (the "
              "non-finite cases above: %d failures)" % fails)
        sys.exit(1 if fails else 77)
    print("h5py hangs on t.h5 with byte %d flipped (global heap at %d)" % (found, gcol))
    open(os.path.join(out, "read.nml"), "w").write(READ)
    for what, cmd in (("terrace-analyze", [analyze, "--trajectory_file=bad.h5", "--compute=rdf"]),
                      ("terrace read_h5md", [terrace, "read.nml"])):
        for np_ in (1, 3):
            fails += expect(what + ", a byte of the global heap flipped", np_, cmd, ["bad.h5", "stuck"])
    sys.exit(1 if fails else 0)


if __name__ == "__main__":
    main()
