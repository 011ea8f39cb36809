#!/usr/bin/env python3
"""Event-driven checkpoints across rank counts: a run stopped on 4 ranks (&run walltime_limit, exit
status 3, checkpoint at its first safe point) and continued on 1 rank with &system read_checkpoint
ends with the thermo CSV and final atoms of the uninterrupted 1-rank run, byte for byte; and the
reverse (stopped on 1 rank, continued on 4). Every rank runs all events, and a restart builds the
event state from the checkpoint's atoms alone, as the uninterrupted run does at its safe points.
Usage: edmd_restart_ranks.py TERRACE DECK OUTDIR
"""
import os
import re
import shutil
import subprocess
import sys


def run(terrace, np_, deck, cwd, expect):
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT='1', OMPI_ALLOW_RUN_AS_ROOT_CONFIRM='1')
    cmd = [terrace, deck] if np_ == 1 else ['mpirun', '--oversubscribe', '-np', str(np_), terrace, deck]
    p = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, timeout=600, env=env)
    open(os.path.join(cwd, deck + '.log'), 'w').write(p.stdout + p.stderr)
    if p.returncode != expect:
        print(p.stdout[-2000:], p.stderr[-2000:])
        raise SystemExit('FAIL: %s on %d rank(s) in %s: exit status %d, expected %d' % (deck, np_, cwd, p.returncode,
                                                                                         expect))


def main():
    if len(sys.argv) != 4:
        raise SystemExit(__doc__)
    terrace, deck, out = os.path.abspath(sys.argv[1]), sys.argv[2], sys.argv[3]
    shutil.rmtree(out, ignore_errors=True)
    text = open(deck).read()
    ref = os.path.join(out, 'uninterrupted')
    os.makedirs(ref)
    open(os.path.join(ref, 'run.nml'), 'w').write(text)
    run(terrace, 1, 'run.nml', ref, 0)
    ok = True
    for first, second in ((4, 1), (1, 4)):
        d = os.path.join(out, 'np%d_then_np%d' % (first, second))
        os.makedirs(d)
        open(os.path.join(d, 'run.nml'), 'w').write(re.sub(r'&run\s', '&run walltime_limit=1e-6, ', text, count=1))
        open(os.path.join(d, 'restart.nml'), 'w').write(
            re.sub(r'&system\s', "&system read_checkpoint='restart.h5', ", text, count=1))
        run(terrace, first, 'run.nml', d, 3)
        run(terrace, second, 'restart.nml', d, 0)
        for f in ('thermo.csv', 'final.txt'):
            same = open(os.path.join(ref, f), 'rb').read() == open(os.path.join(d, f), 'rb').read()
            ok &= same
            print('stopped on %d rank(s), continued on %d: %s %s' % (first, second, f,
                                                                    'identical' if same else 'DIFFERS: FAIL'))
    print('edmd_restart_ranks: ' + ('PASS' if ok else 'FAIL'))
    sys.exit(0 if ok else 1)


if __name__ == '__main__':
    main()
