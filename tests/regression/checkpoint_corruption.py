#!/usr/bin/env python3
"""Damaged checkpoints are refused on restart.

usage: checkpoint_corruption.py TERRACE OUTDIR NPROCS [--dataset-flips 1|3] [--attribute-stride J]
                                [--names] [--metadata-stride K]

A 108-atom LJ run writes a checkpoint on NPROCS ranks. Then single bytes of a copy are flipped
(XOR 0xff) and the run is restarted from it on NPROCS ranks:
  - every /atoms dataset: its first byte, and (--dataset-flips 3, the default) its last byte and one
    in the middle of its stored data (file offsets from h5py's get_offset; they are contiguous);
  - every J-th attribute of / and of /state (default 1: all): one byte of its value (found in the
    file after its name), and with --names one byte of its name;
  - every K-th byte of the rest of the file (HDF5's superblock, object headers, heaps, B-trees;
    default 1024, 0: none).
A flip in a dataset or an attribute must be detected: non-zero exit within the time limit, exactly
one 'terrace: error:' line naming the checkpoint, &system read_checkpoint and the damage, no crash
text. A flip elsewhere must be detected in the same way or be harmless: a byte HDF5 does not use,
where the restart ends with the final state of the undamaged restart byte for byte. Anything else
(a silent different result, a crash, a hang) fails the test.
"""
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

DECK = """&run units='lj', n_steps=20, seed=7 /
&system {restart}lattice='fcc', density=0.8442, cells=3,3,3, mass=1.0, temperature=1.0 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&integrator style='velocity_verlet', dt=0.005 /
&output thermo_every=5, thermo_file='thermo.csv', final_atoms_file='final.txt', checkpoint_file='ck.h5',
        checkpoint_every=10 /
"""
CRASH = ("Backtrace", "SIGSEGV", "Segmentation", "Program received", "HDF5-DIAG", "mpirun noticed",
         "Fortran runtime error", "free():", "malloc")


def run(terrace, np_, cwd, deck):
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT="1", OMPI_ALLOW_RUN_AS_ROOT_CONFIRM="1",
               OMPI_MCA_rmaps_base_oversubscribe="1")
    cmd = [terrace, deck] if np_ == 1 else ["mpirun", "--oversubscribe", "-np", str(np_), terrace, deck]
    try:
        p = subprocess.run(cmd, cwd=cwd, env=env, capture_output=True, text=True, timeout=60)
        return p.returncode, p.stdout + p.stderr
    except subprocess.TimeoutExpired:
        return 124, "timed out"


def main():
    terrace, out, np_ = os.path.abspath(sys.argv[1]), sys.argv[2], int(sys.argv[3])
    def opt(name, default):
        return int(sys.argv[sys.argv.index(name) + 1]) if name in sys.argv else default
    stride, nflips, astride = opt("--metadata-stride", 1024), opt("--dataset-flips", 3), opt("--attribute-stride", 1)
    names = "--names" in sys.argv
    shutil.rmtree(out, ignore_errors=True)
    base = os.path.join(out, "base")
    os.makedirs(base)
    open(os.path.join(base, "deck.nml"), "w").write(DECK.format(restart=""))
    rc, text = run(terrace, np_, base, "deck.nml")
    if rc != 0:
        print(text)
        sys.exit("FAIL the run that writes the checkpoint: exit %d" % rc)
    # the checkpoint of step 20, the last one: a restart only writes the final state again (enough
    # to compare), as the deck may differ from the writer's in read_checkpoint only
    ck = open(os.path.join(base, "ck.h5"), "rb").read()
    thermo = open(os.path.join(base, "thermo.csv"), "rb").read()
    restart_deck = DECK.format(restart="read_checkpoint='damaged.h5', ")

    def trial(name, data):
        d = os.path.join(out, "trial")
        shutil.rmtree(d, ignore_errors=True)
        os.makedirs(d)
        open(os.path.join(d, "deck.nml"), "w").write(restart_deck)
        open(os.path.join(d, "thermo.csv"), "wb").write(thermo)
        open(os.path.join(d, "damaged.h5"), "wb").write(data)
        rc, text = run(terrace, np_, d, "deck.nml")
        final = open(os.path.join(d, "final.txt"), "rb").read() if os.path.exists(os.path.join(d, "final.txt")) else None
        return rc, text, final

    rc, text, clean_final = trial("clean", ck)
    if rc != 0 or clean_final is None:
        print(text)
        sys.exit("FAIL the restart from the undamaged checkpoint: exit %d" % rc)

    def flipped(off):
        b = bytearray(ck)
        b[off] ^= 0xFF
        return bytes(b)

    def detected(rc, text):
        errs = [l for l in text.splitlines() if l.startswith("terrace: error:")]
        if rc in (0, 124, 137) or len(errs) != 1 or any(c in text for c in CRASH):
            return None
        e = errs[0]
        if "damaged.h5" not in e or "read_checkpoint" not in e:
            return None
        return e

    fails = 0
    counts = {"dataset": 0, "attribute": 0, "meta_detected": 0, "meta_harmless": 0}
    used = np.zeros(len(ck), bool)
    with h5py.File(os.path.join(base, "ck.h5"), "r") as f:
        dsets = [(k, d.id.get_offset(), d.id.get_storage_size()) for k, d in f["atoms"].items()]
        attrs = [(n, v) for n, v in f.attrs.items()] + [(n, v) for n, v in f["state"].attrs.items()]
    for name, off, size in dsets:
        used[off:off + size] = True
        for o in sorted({off, off + size // 2 + 3, off + size - 1} if nflips > 1 else {off}):
            rc, text, _ = trial(name, flipped(o))
            e = detected(rc, text)
            counts["dataset"] += 1
            if e is None:
                fails += 1
                print("FAIL  /atoms/%s byte %d flipped: exit %d, %s" % (name, o, rc, text.strip()[-300:]))
            elif o == off:
                print("ok    /atoms/%-9s flip at %5d: exit %d: %s" % (name, o, rc, e))
    for name, value in attrs[::astride]:
        nb = name.encode()
        pos = ck.find(nb)
        vb = np.asarray(value).tobytes()
        vpos = ck.find(vb, pos + len(nb), pos + len(nb) + 200) if pos >= 0 else -1
        if pos < 0 or vpos < 0:
            fails += 1
            print("FAIL  attribute %s not found in the file" % name)
            continue
        for what, o in ((("name", pos + len(nb) // 2),) if names else ()) + (("value", vpos + len(vb) // 2),):
            used[o] = True
            rc, text, _ = trial(name, flipped(o))
            e = detected(rc, text)
            counts["attribute"] += 1
            if e is None:
                fails += 1
                print("FAIL  attribute %s: %s byte %d flipped: exit %d, %s" % (name, what, o, rc, text.strip()[-300:]))
        print("ok    attribute %-17s flips detected: %s" % (name, e))
    for o in range(0, len(ck), stride) if stride > 0 else ():
        if used[o]:
            continue
        rc, text, final = trial("meta", flipped(o))
        e = detected(rc, text)
        if e is not None:
            counts["meta_detected"] += 1
        elif rc == 0 and final == clean_final:
            counts["meta_harmless"] += 1
        else:
            fails += 1
            print("FAIL  metadata byte %d flipped: exit %d, %s" % (o, rc, text.strip()[-300:]))
    print("%d dataset flips, %d attribute flips: all detected; %d other bytes (every %dth): %d detected, "
          "%d unused by HDF5 (identical restart); %d failures; np=%d"
          % (counts["dataset"], counts["attribute"], counts["meta_detected"] + counts["meta_harmless"], stride,
             counts["meta_detected"], counts["meta_harmless"], fails, np_))
    sys.exit(1 if fails else 0)


if __name__ == "__main__":
    main()
