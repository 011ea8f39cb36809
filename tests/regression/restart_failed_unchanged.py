#!/usr/bin/env python3
"""A restart that fails changes nothing: trajectory, thermo CSV, checkpoint and final state stay
byte for byte as they were.

usage: restart_failed_unchanged.py TERRACE DECK OUTDIR NPROCS

DECK (tests/regression/decks/ckpt_lj.nml) runs 190 steps here, so that its last checkpoint (step
160) lies before its end: the trajectory then holds more frames than the checkpoint recorded, and
an appending restart cuts it back to them. For each damage of the thermo CSV (deleted; shortened
to fewer lines than the checkpoint recorded; emptied) the test copies the complete run's files,
damages thermo.csv, restarts from the checkpoint and requires: exit status 1, one error line that
names &output thermo_file and the checkpoint, and every file in the directory byte-identical
(none added, none removed). Then a restart of an undamaged copy must succeed, cut the trajectory to
the checkpoint's frames and append up to the end: its thermo CSV and trajectory equal the
uninterrupted run's, which shows that the failed restarts did have something to cut.
"""
import os
import re
import shutil
import sys

import h5py
import numpy as np

from checkpoint_restart import fail, make_deck, run   # (beside this script: on sys.path as its folder)


def snapshot(d):
    return {n: open(os.path.join(d, n), 'rb').read() for n in sorted(os.listdir(d))
            if os.path.isfile(os.path.join(d, n)) and not n.endswith('.log') and not n.endswith('.nml')}


def main():
    if len(sys.argv) != 5:
        fail(__doc__)
    terrace, src, out, np_ = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2]), sys.argv[3], int(sys.argv[4])
    shutil.rmtree(out, ignore_errors=True)
    full = os.path.join(out, 'full')
    os.makedirs(full)
    make_deck(src, os.path.join(full, 'run.nml'), length='n_steps=190')
    run(terrace, np_, 'run.nml', full, 'run.log', 0)
    with h5py.File(os.path.join(full, 'restart.h5'), 'r') as f:
        kept_frames = int(f['state'].attrs['trajectory_frames'])
        kept_lines = int(f['state'].attrs['thermo_lines'])
    with h5py.File(os.path.join(full, 'traj.h5'), 'r') as f:
        frames = f['particles/all/position/value'].shape[0]
    if not frames > kept_frames:
        fail('the trajectory holds %d frames, the checkpoint %d: a restart would cut nothing' % (frames, kept_frames))

    def damaged(name, damage):
        d = os.path.join(out, name)
        shutil.copytree(full, d)
        damage(os.path.join(d, 'thermo.csv'))
        make_deck(src, os.path.join(d, 'restart.nml'), length='n_steps=190', restart='restart.h5')
        before = snapshot(d)
        run(terrace, np_, 'restart.nml', d, 'restart.log', 1)
        log = open(os.path.join(d, 'restart.log')).read()
        errors = [l for l in log.splitlines() if l.startswith('terrace: error')]
        if len(errors) != 1 or 'thermo_file' not in errors[0] or 'checkpoint' not in errors[0]:
            fail('%s: expected one error line naming thermo_file and the checkpoint, got:\n%s' % (name, log[-1500:]))
        after = snapshot(d)
        if sorted(after) != sorted(before):
            fail('%s: the failed restart added or removed files: %s' % (name, sorted(set(after) ^ set(before))))
        changed = [n for n in before if before[n] != after[n]]
        if changed:
            fail('%s: the failed restart changed %s' % (name, ', '.join(changed)))
        return errors[0]

    lines = open(os.path.join(full, 'thermo.csv')).read().splitlines(keepends=True)
    shown = []
    shown.append(damaged('deleted', os.remove))
    shown.append(damaged('shortened', lambda p: open(p, 'w').write(''.join(lines[:kept_lines - 2]))))
    shown.append(damaged('emptied', lambda p: open(p, 'w').close()))

    # the control: an undamaged restart cuts the trajectory back and ends as the uninterrupted run
    d = os.path.join(out, 'intact')
    shutil.copytree(full, d)
    make_deck(src, os.path.join(d, 'restart.nml'), length='n_steps=190', restart='restart.h5')
    run(terrace, np_, 'restart.nml', d, 'restart.log', 0)
    if open(os.path.join(d, 'thermo.csv'), 'rb').read() != open(os.path.join(full, 'thermo.csv'), 'rb').read():
        fail('the undamaged restart ended with another thermo.csv than the uninterrupted run')
    with h5py.File(os.path.join(d, 'traj.h5'), 'r') as a, h5py.File(os.path.join(full, 'traj.h5'), 'r') as b:
        for k in ('position', 'velocity'):
            if not np.array_equal(a['particles/all/%s/value' % k][()], b['particles/all/%s/value' % k][()]):
                fail('the undamaged restart ended with another trajectory (%s) than the uninterrupted run' % k)
    print('PASS restart_failed_unchanged on %d rank(s): thermo.csv deleted, shortened below the checkpoint\'s %d '
          'lines, emptied: each restart stopped with one line and left traj.h5 (%d frames, %d at the checkpoint), '
          'thermo.csv, restart.h5 and final.txt byte for byte; an undamaged restart cut and continued them to the '
          'uninterrupted run\'s end.\n  e.g. %s' % (np_, kept_lines, frames, kept_frames, shown[1][:300]))


if __name__ == '__main__':
    main()
