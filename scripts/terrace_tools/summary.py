"""The run summary Terrace writes at the end of a run (&output summary_file, JSON; doc/input.md,
"Run summary"): read it, get a value by its '/'-separated key, check the deck's CRC-32.

Command line:
    python3 -m terrace_tools.summary get FILE KEY     # print one value ('timing/loop_time_s')
    python3 -m terrace_tools.summary show FILE [PREFIX ...]   # key = value, one a line (keys
                                                      # under the prefixes, or all)
    python3 -m terrace_tools.summary phases FILE      # the loop time, the phase table (average and
                                                      # slowest rank) and the list builds
    python3 -m terrace_tools.summary check-deck FILE  # the deck's CRC-32 equals deck/crc32?
Exit status 1 when the key is missing or the deck differs.
"""
import json
import os
import sys
import zlib

_MISSING = object()


def default_name(deck):
    """The summary a deck writes by default: its file name without '.nml', plus '.summary.json',
    in the working directory (run.nml -> run.summary.json)."""
    name = os.path.basename(deck)
    if len(name) > 4 and name[-4:].lower() == ".nml":
        name = name[:-4]
    return name + ".summary.json"


def read(path):
    """The summary as nested dicts."""
    with open(path) as f:
        return json.load(f)


def get(summary, key, default=_MISSING):
    """The value under a '/'-separated key ('timing/phases/Pair/avg_s'); summary may be a path.
    KeyError when missing and no default is given."""
    if isinstance(summary, (str, os.PathLike)):
        summary = read(summary)
    node = summary
    for part in key.split("/"):
        if not isinstance(node, dict) or part not in node:
            if default is _MISSING:
                raise KeyError(key)
            return default
        node = node[part]
    return node


def flatten(summary, prefix=""):
    """{'a/b': value, ...} for every leaf, in file order."""
    out = {}
    for k, v in summary.items():
        if isinstance(v, dict):
            out.update(flatten(v, prefix + k + "/"))
        else:
            out[prefix + k] = v
    return out


def crc32(path):
    """CRC-32 of a file's bytes as 8 lower-case hex digits (the summary's deck/crc32)."""
    with open(path, "rb") as f:
        return "%08x" % zlib.crc32(f.read())


def run_figures(summary):
    """The closing run log's figures under short names (loop, n, pair, pair_max, ..., builds;
    energy stepping: events, up, down, refl, mean_dt, evals, passes), for the benchmark scripts."""
    if isinstance(summary, (str, os.PathLike)):
        summary = read(summary)
    t = summary.get("timing", {})
    r = {"loop": t.get("loop_time_s"), "n": t.get("steps", t.get("events"))}
    for ph, v in t.get("phases", {}).items():
        r[ph.lower()] = v.get("avg_s", 0.0)
        r[ph.lower() + "_max"] = v.get("max_s", 0.0)
    r["builds"] = get(summary, "neighbor/builds", 0)
    es = summary.get("energy_stepping")
    if es:
        r.update(events=es.get("events"), up=es.get("ups"), down=es.get("downs"), refl=es.get("reflections"),
                 mean_dt=es.get("mean_event_interval"), evals=es.get("ray_evaluations_per_event"),
                 passes=es.get("force_passes_per_event"))
        share = es.get("reflection_share")
        if share is None and es.get("events"):
            share = (es.get("reflections") or 0) / es["events"]
        r["refl_share"] = share
    c = summary.get("conservation", {})
    r.update(drift=c.get("energy_drift_per_atom_time"), dp=c.get("momentum_change"))
    return r


def phase_table(summary):
    """The loop time, the time of each phase (average and slowest rank, share of the loop) and the
    neighbour-list builds, as lines of text (the closing run log's figures, from the summary)."""
    if isinstance(summary, (str, os.PathLike)):
        summary = read(summary)
    t = summary.get("timing", {})
    count = "%s steps" % t["steps"] if "steps" in t else "%s events" % t.get("events")
    lines = ["loop time %.4f s for %s (%s rank(s), %s atoms)" % (t.get("loop_time_s", float("nan")), count,
             get(summary, "machine/ranks", "?"), t.get("atoms", "?")),
             "%-8s %13s %14s %7s" % ("phase", "avg time (s)", "max time (s)", "%loop")]
    for name, v in t.get("phases", {}).items():
        lines.append("%-8s %13.4f %14.4f %7.1f" % (name, v.get("avg_s", 0.0), v.get("max_s", 0.0),
                                                   v.get("percent_loop", 0.0)))
    lines.append("list builds: %s" % get(summary, "neighbor/builds", "?"))
    return lines


def _format(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, float):
        return repr(v)
    if v is None:
        return "null"
    return str(v)


def main(argv=None):
    argv = list(sys.argv[1:] if argv is None else argv)
    usage = ("usage: python3 -m terrace_tools.summary get FILE KEY | show FILE [PREFIX ...] | phases FILE"
             " | check-deck FILE")
    if not argv:
        print(usage, file=sys.stderr)
        return 2
    cmd = argv[0]
    if cmd == "get" and len(argv) == 3:
        try:
            v = get(read(argv[1]), argv[2])
        except KeyError:
            print(f"{argv[1]}: no key {argv[2]}", file=sys.stderr)
            return 1
        print(json.dumps(v) if isinstance(v, dict) else _format(v))
        return 0
    if cmd == "show" and len(argv) >= 2:
        prefixes = argv[2:]
        for k, v in flatten(read(argv[1])).items():
            if not prefixes or any(k == p or k.startswith(p.rstrip("/") + "/") for p in prefixes):
                print(f"{k} = {_format(v)}")
        return 0
    if cmd == "phases" and len(argv) == 2:
        print("\n".join(phase_table(argv[1])))
        return 0
    if cmd == "check-deck" and len(argv) == 2:
        s = read(argv[1])
        deck = get(s, "deck/path")
        have = crc32(deck)
        want = get(s, "deck/crc32")
        print(f"{deck}: crc32 {have} ({'the same as' if have == want else 'differs from'} the summary's {want})")
        return 0 if have == want else 1
    print(usage, file=sys.stderr)
    return 2


if __name__ == "__main__":
    sys.exit(main())
