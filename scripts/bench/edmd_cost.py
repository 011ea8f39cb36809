#!/usr/bin/env python3
"""Cost of event-driven dynamics: events per second and cost per event against N.

Hard spheres (sigma = m = kT = 1) at packing fraction --eta from an fcc lattice (N = 4 m^3 for
m = 6, 14, 29, 63: about 1e3 to 1e6 atoms), one rank, each N run twice: for --collisions and for
three times as many collisions per atom. The cost per event is the difference of the two runs'
CPU times (user + system of the terrace process) over the difference of their events, so that the
set-up (scene, neighbour list, the loop's first prediction of every atom) drops out and a machine
shared with other jobs does not count their time. Prints one row per N: N, events of the longer
run (pair crossings + cell crossings + stale predictions), its pair crossings, its loop wall time,
CPU microseconds per event, events per CPU second, pair crossings (collisions) per CPU second,
peak memory.
Usage: scripts/bench/edmd_cost.py [--terrace build/terrace] [--eta 0.45] [--collisions 5]
       [--cells 6,14,29,63] [--out /tmp/edmd_cost]
"""
import argparse
import math
import os
import resource
import subprocess

from terrace_tools import summary


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser()
    ap.add_argument('--terrace', default=os.path.join(here, '..', '..', 'build', 'terrace'))
    ap.add_argument('--eta', type=float, default=0.45)
    ap.add_argument('--collisions', type=float, default=5.0)
    ap.add_argument('--cells', default='6,14,29,63')
    ap.add_argument('--out', default='/tmp/edmd_cost')
    a = ap.parse_args()
    terrace = os.path.abspath(a.terrace)
    n = 6*a.eta/math.pi
    g = (1 - a.eta/2)/(1 - a.eta)**3
    rate = 4*n*g*math.sqrt(math.pi)
    print('hard spheres, eta = %g (n = %.4f), %g and %g collisions per atom, one rank' %
          (a.eta, n, a.collisions, 3*a.collisions))
    print('%9s %11s %11s %9s %9s %11s %11s %10s' % ('N', 'events', 'collisions', 'loop s', 'us/event',
                                                  'events/s', 'coll/s', 'memory'))
    for m in (int(c) for c in a.cells.split(',')):
        runs = []
        for k, coll in enumerate((a.collisions, 3*a.collisions)):
            runs.append(run_one(terrace, os.path.join(a.out, 'm%d_%d' % (m, k)), m, n, coll/rate))
            if runs[-1] is None:
                break
        if None in runs:
            continue
        (c0, e0, p0, l0, mem0), (c1, e1, p1, l1, mem1) = runs
        cost = (c1 - c0)/(e1 - e0)
        print('%9d %11d %11d %9.2f %9.3f %11.4e %11.4e %10s' % (4*m**3, e1, p1, l1, 1e6*cost, 1/cost,
                                                              (p1 - p0)/(c1 - c0), mem1))


def run_one(terrace, d, m, n, t_run):
    """CPU seconds, events, pair crossings, loop wall seconds and peak memory of one run."""
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, 'run.nml'), 'w') as f:
        f.write(f"""&run units='lj', dimension=3, run_time={t_run:.17g}, seed=4 /
&system lattice='fcc', density={n:.17g}, cells={m},{m},{m}, mass=1.0, temperature=1.0 /
&potential style='hard_sphere', diameter=1.0 /
&integrator style='event_driven' /
&output thermo_interval={t_run:.17g} /
""")
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run([terrace, 'run.nml'], cwd=d, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    log = p.stdout + p.stderr
    open(os.path.join(d, 'terrace.log'), 'w').write(log)
    if p.returncode != 0:
        print('m = %d: terrace failed:\n%s' % (m, log[-1500:]))
        return None
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    s = summary.read(os.path.join(d, 'run.summary.json'))
    mem = summary.get(s, 'memory/peak_mib_all_ranks', None)
    return (cpu, summary.get(s, 'event_driven/events'), summary.get(s, 'event_driven/pair_crossings'),
            summary.get(s, 'timing/loop_time_s'), '?' if mem is None else '%.1f MiB' % mem)


if __name__ == '__main__':
    main()
