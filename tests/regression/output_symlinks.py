#!/usr/bin/env python3
"""Outputs named through symbolic links are written to the links' targets and the links stay.

usage: output_symlinks.py TERRACE OUTDIR NPROCS

A small LJ deck names every output through a link: thermo_file, forces_file and final_atoms_file
(written under a temporary name and renamed into place), trajectory_file (HDF5, overwrite); it runs
twice so, then twice with checkpoint_file too (written as <target>.tmp and renamed; the small
outputs of a checkpointed run are written in place). The links point into another directory:
relative, absolute, through a chain of two links, and dangling (a target not there yet, which the
run creates). Every target already holds old content. After the run: each link is still a link to
the same target; each target holds the new output (the thermo header, the forces of every atom, an
HDF5 trajectory and checkpoint that h5py opens with the run's frame count); no temporary file is
left in either directory; and the run's outputs equal, byte for byte (the text outputs), those of
the same deck written to plain file names. A second run on the same links replaces the targets
again (the links still stay). Then --check on the deck with a link to a missing directory must
fail naming thermo_file.
"""
import os
import shutil
import subprocess
import sys

import h5py

DECK = """&run units='lj', dimension=3, n_steps=20, seed=7 /
&system lattice='fcc', density=0.8442, cells=3,3,3, mass=1.0, temperature=1.0 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&output thermo_every=5, thermo_file='{thermo}', forces_file='{forces}', final_atoms_file='{final}',
        trajectory_file='{traj}', trajectory_every=5, overwrite=.true.{ckpt_keys} /
"""
CKPT_KEYS = ", checkpoint_file='{ckpt}', checkpoint_every=10"
NAMES = dict(thermo='thermo.csv', forces='forces.txt', final='final.atoms', traj='traj.h5', ckpt='ck.h5')


def fail(msg):
    print('FAIL ' + msg)
    sys.exit(1)


def run(terrace, np_, cwd, deck, expect=0, check=False):
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT='1', OMPI_ALLOW_RUN_AS_ROOT_CONFIRM='1')
    cmd = ([terrace] if np_ == 1 else ['mpirun', '--oversubscribe', '-np', str(np_), terrace]) + \
        (['--check'] if check else []) + [deck]
    p = subprocess.run(cmd, cwd=cwd, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                       timeout=300)
    if p.returncode != expect:
        fail('%s in %s: exit %d, expected %d:\n%s' % (' '.join(cmd), cwd, p.returncode, expect, p.stdout[-2000:]))
    return p.stdout


def deck(names, ckpt):
    keys = CKPT_KEYS.format(ckpt=names['ckpt']) if ckpt else ''
    return DECK.format(ckpt_keys=keys, **names)


def main():
    if len(sys.argv) != 4:
        fail(__doc__)
    terrace, out, np_ = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2]), int(sys.argv[3])
    shutil.rmtree(out, ignore_errors=True)
    plain, work, real = os.path.join(out, 'plain'), os.path.join(out, 'work'), os.path.join(out, 'real')
    for d in (plain, work, real):
        os.makedirs(d)
    for ckpt in (False, True):
        os.makedirs(os.path.join(plain, str(ckpt)))
        with open(os.path.join(plain, str(ckpt), 'run.nml'), 'w') as f:
            f.write(deck(NAMES, ckpt))
        run(terrace, np_, os.path.join(plain, str(ckpt)), 'run.nml')

    # the links: relative, absolute, a chain of two, dangling (target created by the run)
    links = dict(thermo='thermo_link.csv', forces='forces_link.txt', final='final_link.atoms', traj='traj_link.h5',
                 ckpt='ck_link.h5')
    targets = {k: os.path.join(real, NAMES[k]) for k in NAMES}
    os.symlink('../real/thermo.csv', os.path.join(work, links['thermo']))
    os.symlink(targets['forces'], os.path.join(work, links['forces']))
    os.symlink('../real/middle.atoms', os.path.join(work, links['final']))
    os.symlink('final.atoms', os.path.join(real, 'middle.atoms'))
    os.symlink('../real/traj.h5', os.path.join(work, links['traj']))
    os.symlink('../real/ck.h5', os.path.join(work, links['ckpt']))
    for k in ('thermo', 'forces', 'traj', 'ckpt'):        # final.atoms: dangling, created by the run
        with open(targets[k], 'w') as f:
            f.write('old content\n')
    link_text = {k: os.readlink(os.path.join(work, links[k])) for k in links}

    for attempt, ckpt in ((1, False), (2, False), (3, True), (4, True)):
        with open(os.path.join(work, 'run.nml'), 'w') as f:
            f.write(deck(links, ckpt))
        run(terrace, np_, work, 'run.nml')
        for k, name in links.items():
            p = os.path.join(work, name)
            if not os.path.islink(p):
                fail('run %d: %s is no longer a symbolic link (the output replaced the link)' % (attempt, name))
            if os.readlink(p) != link_text[k]:
                fail('run %d: %s now points at %s, not %s' % (attempt, name, os.readlink(p), link_text[k]))
            if not os.path.isfile(targets[k]) or os.path.islink(targets[k]):
                fail('run %d: the target %s is not a regular file' % (attempt, targets[k]))
        if not os.path.islink(os.path.join(real, 'middle.atoms')):
            fail('run %d: the middle link of the chain was replaced' % attempt)
        for k in ('thermo', 'forces', 'final'):
            got = open(targets[k], 'rb').read()
            want = open(os.path.join(plain, str(ckpt), NAMES[k]), 'rb').read()
            if got != want:
                fail('run %d: %s (through %s) differs from the plain run\'s %s (%d bytes, expected %d)'
                     % (attempt, targets[k], links[k], NAMES[k], len(got), len(want)))
        with h5py.File(targets['traj'], 'r') as f:
            nf = f['particles/all/position/value'].shape[0]
        if nf != 5:
            fail('run %d: the trajectory target holds %d frames, expected 5' % (attempt, nf))
        if ckpt:
            with h5py.File(targets['ckpt'], 'r') as f:
                if 'atoms' not in f:
                    fail('run %d: the checkpoint target is not a checkpoint' % attempt)
        elif open(targets['ckpt'], 'rb').read() != b'old content\n':
            fail('run %d: the checkpoint target changed in a run without checkpoints' % attempt)
        for d in (work, real):
            stray = [n for n in os.listdir(d) if 'terrace-' in n or n.endswith('.tmp')]
            if stray:
                fail('run %d: temporary or lock files left in %s: %s' % (attempt, d, stray))
        # (the run summary, named after the deck, and the trajectory's topology companion, named after
        # the trajectory as the deck gives it, belong beside the deck)
        extra = sorted(set(os.listdir(work)) - set(links.values())
                       - {'run.nml', 'run.summary.json', os.path.splitext(links['traj'])[0] + '.topology.data'})
        if extra:
            fail('run %d: files written beside the links instead of through them: %s' % (attempt, extra))

    # a link to a directory that does not exist: refused before the run, naming the key
    os.symlink('../nowhere/thermo.csv', os.path.join(work, 'bad_link.csv'))
    with open(os.path.join(work, 'bad.nml'), 'w') as f:
        f.write(deck(dict(links, thermo='bad_link.csv'), False))
    msg = run(terrace, np_, work, 'bad.nml', expect=1, check=True)
    if 'thermo_file' not in msg or 'does not exist' not in msg:
        fail('a link into a missing directory: the error does not name thermo_file and the missing directory:\n'
             + msg[-1000:])
    print('PASS output_symlinks on %d rank(s): thermo, forces, final atoms (through a chain of two links, '
          'dangling at first) and trajectory written to the links\' targets in two runs, then with the checkpoint '
          'in two more; the links stayed, '
          'the text outputs equal the plain run\'s byte for byte, nothing left behind' % np_)


if __name__ == '__main__':
    main()
