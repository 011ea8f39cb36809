"""Tables of scripts/bench/comm_volume.sh: point-to-point messages and bytes per step and rank,
and collective operations per step, from Open MPI's monitoring files (PREFIX.<rank>.prof), for
Terrace (figures from its run summary) and LAMMPS (neighbour builds from its log).

Usage: comm_volume_report.py RUNS.tsv   (lines: scene code mode ranks nsteps directory)

Monitoring file lines used (Open MPI 4.1, pml_monitoring_enable 2 = user and internal traffic
apart): 'E src dst B bytes M msgs sent' the application's point-to-point messages (MPI_Sendrecv
counts one message sent); 'I ...' point-to-point messages that collectives made inside MPI;
'D COMM' then 'O2A/A2O/A2A rank B bytes M msgs sent' the collective operations on that
communicator: all-to-all kinds (allreduce, barrier, allgather, alltoall) counted on every member,
rooted ones (bcast, scatter: O2A; reduce, gather: A2O) on the root only.
"""
import glob
import os
import sys

from terrace_tools import summary


def read_prof(path):
    """(p2p msgs, p2p bytes, internal msgs, internal bytes, {comm: [a2a, rooted]}) sent by one rank."""
    msgs = nbytes = imsgs = ibytes = 0
    comms = {}
    comm = None
    with open(path) as f:
        for line in f:
            w = line.rstrip("\n").split("\t")
            if w[0] in ("E", "I") and len(w) >= 5:
                b = int(w[3].split()[0]); m = int(w[4].split()[0])
                if w[0] == "E":
                    msgs += m; nbytes += b
                else:
                    imsgs += m; ibytes += b
            elif w[0] == "D" and len(w) >= 2:
                comm = w[1]
                comms.setdefault(comm, [0, 0])
            elif w[0] in ("O2A", "A2O", "A2A") and comm is not None and len(w) >= 4:
                m = int(w[3].split()[0])
                comms[comm][0 if w[0] == "A2A" else 1] += m
    return msgs, nbytes, imsgs, ibytes, comms


def read_run(directory):
    files = sorted(glob.glob(os.path.join(directory, "mon.*.prof")),
                   key=lambda p: int(p.rsplit(".", 2)[-2]))
    if not files:
        raise SystemExit(f"comm_volume_report.py: no monitoring files in {directory}")
    ranks = [read_prof(p) for p in files]
    colls = 0
    names = set().union(*(r[4].keys() for r in ranks))
    for c in names:   # all-to-all kinds: once (every member counts it); rooted: the roots' sum
        colls += max(r[4].get(c, [0, 0])[0] for r in ranks) + sum(r[4].get(c, [0, 0])[1] for r in ranks)
    return {"msgs": [r[0] for r in ranks], "bytes": [r[1] for r in ranks],
            "imsgs": [r[2] for r in ranks], "ibytes": [r[3] for r in ranks], "colls": colls}


def builds(code, directory):
    if code == "terrace":
        return int(summary.get(os.path.join(directory, "run.summary.json"), "neighbor/builds"))
    with open(os.path.join(directory, "log.lammps")) as f:
        for line in f:
            w = line.split()
            if w[:4] == ["Neighbor", "list", "builds", "="]:
                return int(w[4])
    raise SystemExit(f"comm_volume_report.py: no 'Neighbor list builds' line in {directory}/log.lammps")


def diff(a, b, nsteps):
    """Per-rank per-step differences b - a (lists) and the collective count difference."""
    per = {k: [(y - x) / nsteps for x, y in zip(a[k], b[k])] for k in ("msgs", "bytes", "imsgs", "ibytes")}
    per["colls"] = (b["colls"] - a["colls"]) / nsteps
    per["colls_total"] = b["colls"] - a["colls"]
    return per


def mean(v):
    return sum(v) / len(v)


def main(argv):
    rows = [line.rstrip("\n").split("\t") for line in open(argv[1]) if line.strip()]
    runs = {}
    for scene, code, mode, np_, n, d in rows:
        runs[(scene, code, mode, int(np_), int(n))] = (read_run(d), builds(code, d))
    keys = sorted({(s, c, int(p), m) for s, c, m, p, _, _ in rows if m != "frozen"},
                  key=lambda k: ({"lj": 0, "eam": 1}.get(k[0], 2), k[0], k[2], k[1] != "terrace", k[3] != "deck", k[3]))
    steps = sorted({int(r[4]) for r in rows})
    s1, s2 = steps[0], steps[-1]
    span = s2 - s1
    for scene, code, mode, np_, n, d in rows:
        if code == "terrace":
            sha = summary.get(os.path.join(d, "run.summary.json"), "terrace/git_commit", "unknown")
            dirty = summary.get(os.path.join(d, "run.summary.json"), "terrace/git_modified", False)
            print(f"Terrace binary built from commit {sha[:7]}{' (with local changes)' if dirty else ''}")
            break
    print(f"Per step and rank: point-to-point messages and kB sent by the application (mean / max over ranks);")
    print(f"collective operations per step (all ranks together; over the {span} steps between the {s1}- and "
          f"{s2}-step runs).")
    print("mean step: the deck's list schedule (code:every20: Terrace with LAMMPS's every 20, check no);")
    print("ordinary step: a list never rebuilt; per build: the difference (mean - ordinary) x steps / builds.")
    scene_now = None
    for scene, code, np_, mode in keys:
        label = code if mode == "deck" else f"{code}:{mode}"
        if scene != scene_now:
            scene_now = scene
            print()
            print(f"== {scene.upper()} ==")
            print(f"{'code':16} {'ranks':>5} | {'mean step: msgs':>15} {'kB':>15} {'colls':>6} | "
                  f"{'ordinary: msgs':>14} {'kB':>15} {'colls':>6} | {'builds':>6} | "
                  f"{'per build: msgs':>15} {'kB':>7} {'colls':>5}")
        dk = diff(runs[(scene, code, mode, np_, s1)][0], runs[(scene, code, mode, np_, s2)][0], span)
        fr = diff(runs[(scene, code, "frozen", np_, s1)][0], runs[(scene, code, "frozen", np_, s2)][0], span)
        nb = runs[(scene, code, mode, np_, s2)][1] - runs[(scene, code, mode, np_, s1)][1]
        fb = runs[(scene, code, "frozen", np_, s2)][1] - runs[(scene, code, "frozen", np_, s1)][1]
        if fb != 0:
            print(f"warning: {scene} {code} {np_} ranks: the frozen list was rebuilt ({fb} builds)")
        if nb > 0:
            pm = (mean(dk["msgs"]) - mean(fr["msgs"])) * span / nb
            pk = (mean(dk["bytes"]) - mean(fr["bytes"])) * span / nb / 1e3
            pc = (dk["colls_total"] - fr["colls_total"]) / nb
            per_build = f"{pm:15.1f} {pk:7.1f} {pc:5.1f}"
        else:
            per_build = f"{'-':>15} {'-':>7} {'-':>5}"
        print(f"{label:16} {np_:5d} | {mean(dk['msgs']):7.2f} / {max(dk['msgs']):5.2f} "
              f"{mean(dk['bytes']) / 1e3:7.1f} / {max(dk['bytes']) / 1e3:5.1f} {dk['colls']:6.3f} | "
              f"{mean(fr['msgs']):6.2f} / {max(fr['msgs']):5.2f} "
              f"{mean(fr['bytes']) / 1e3:7.1f} / {max(fr['bytes']) / 1e3:5.1f} {fr['colls']:6.3f} | "
              f"{nb:6d} | {per_build}")
    print()
    print("Collective operations in the span, as counts (the row's schedule / list never rebuilt):")
    for scene, code, np_, mode in keys:
        label = code if mode == "deck" else f"{code}:{mode}"
        dk = diff(runs[(scene, code, mode, np_, s1)][0], runs[(scene, code, mode, np_, s2)][0], span)
        fr = diff(runs[(scene, code, "frozen", np_, s1)][0], runs[(scene, code, "frozen", np_, s2)][0], span)
        im = mean(dk["imsgs"]) * span
        print(f"  {scene:3} {label:16} {np_:2d} ranks: {dk['colls_total']:4d} / {fr['colls_total']:4d} in {span} steps"
              f"   (their internal point-to-point messages, deck: {im:.0f} per rank)")


if __name__ == "__main__":
    main(sys.argv)
