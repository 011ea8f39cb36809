#!/usr/bin/env python3
"""Cost of event-driven dynamics: events per second and cost per event against N.

Hard spheres (sigma = m = kT = 1) at packing fraction --eta from an fcc lattice (N = 4 m^3 for
m = 6, 14, 29, 63: about 1e3 to 1e6 atoms), run for --collisions collisions per atom, one rank.
The run log's loop time covers the event loop only (set-up and outputs apart from one sample at
the start and the end). Prints one table row per N:
  N, events (pair crossings + cell crossings + stale predictions), pair crossings, loop seconds,
  events/s, microseconds per event, pair crossings (collisions) per second, peak memory.
Usage: scripts/bench/edmd_cost.py [--terrace build/terrace] [--eta 0.45] [--collisions 10]
       [--cells 6,14,29,63] [--out /tmp/edmd_cost]
"""
import argparse
import math
import os
import re
import subprocess


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    ap = argparse.ArgumentParser()
    ap.add_argument('--terrace', default=os.path.join(here, '..', '..', 'build', 'terrace'))
    ap.add_argument('--eta', type=float, default=0.45)
    ap.add_argument('--collisions', type=float, default=10.0)
    ap.add_argument('--cells', default='6,14,29,63')
    ap.add_argument('--out', default='/tmp/edmd_cost')
    a = ap.parse_args()
    terrace = os.path.abspath(a.terrace)
    n = 6*a.eta/math.pi
    g = (1 - a.eta/2)/(1 - a.eta)**3
    rate = 4*n*g*math.sqrt(math.pi)
    t_run = a.collisions/rate
    print('hard spheres, eta = %g (n = %.4f), %g collisions per atom (t = %.4g), one rank' %
          (a.eta, n, a.collisions, t_run))
    print('%9s %11s %11s %9s %11s %9s %11s %10s' % ('N', 'events', 'collisions', 'loop s', 'events/s', 'us/event',
                                                  'coll/s', 'memory'))
    for m in (int(c) for c in a.cells.split(',')):
        d = os.path.join(a.out, 'm%d' % m)
        os.makedirs(d, exist_ok=True)
        with open(os.path.join(d, 'run.nml'), 'w') as f:
            f.write(f"""&run units='lj', dimension=3, run_time={t_run:.17g}, seed=4 /
&system lattice='fcc', density={n:.17g}, cells={m},{m},{m}, mass=1.0, temperature=1.0 /
&potential style='hard_sphere', diameter=1.0 /
&integrator style='event_driven' /
&output thermo_interval={t_run:.17g} /
""")
        p = subprocess.run([terrace, 'run.nml'], cwd=d, capture_output=True, text=True)
        log = p.stdout + p.stderr
        open(os.path.join(d, 'terrace.log'), 'w').write(log)
        if p.returncode != 0:
            print('m = %d: terrace failed:\n%s' % (m, log[-1500:]))
            continue
        loop = float(re.search(r'Loop time: ([0-9.eE+-]+) s', log).group(1))
        ev = re.search(r'Events: (\d+) \((\d+) pair crossings', log)
        mem = re.search(r'Peak memory: ([0-9.]+ \w+)', log)
        events, pairs = int(ev.group(1)), int(ev.group(2))
        print('%9d %11d %11d %9.3f %11.4e %9.3f %11.4e %10s' % (4*m**3, events, pairs, loop, events/loop,
                                                              1e6*loop/events, pairs/loop,
                                                              mem.group(1) if mem else '?'))


if __name__ == '__main__':
    main()
