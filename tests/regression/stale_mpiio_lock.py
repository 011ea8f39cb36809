#!/usr/bin/env python3
"""A run is not held up by MPI-IO state a killed job left on the node.

Open MPI's MPI-IO (ompio) by default guards a shared file pointer with a POSIX semaphore named
after the file's base name only (/dev/shm/sem.OMPIO_<name>); a job killed while it held it leaves
it locked, and every later open of a file of that name waits forever. Terrace removes that name
before each collective open (platform/file_ops.c, terrace_mpiio_clear_semaphore). Checked: with a
locked semaphore planted for the checkpoint's and the trajectory's temporary names, a run that
writes both finishes (exit 0) on NPROCS ranks, and its thermo file equals that of a run in a
clean directory. The planted semaphores are removed afterwards.
usage: stale_mpiio_lock.py TERRACE WORKDIR NPROCS
"""
import ctypes
import os
import shutil
import subprocess
import sys

terrace, work, nprocs = sys.argv[1], sys.argv[2], sys.argv[3]
shutil.rmtree(work, ignore_errors=True)
os.makedirs(work)
os.chdir(work)
tag = 'stale%d' % os.getpid()
deck = f"""&run units='lj', dimension=3, n_steps=100, seed=7 /
&system lattice='fcc', density=0.8442, cells=4,4,4, mass=1.0, temperature=1.0 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&integrator style='velocity_verlet', dt=0.005 /
&output thermo_every=20, thermo_file='thermo.csv', trajectory_file='{tag}.h5', trajectory_every=50,
        checkpoint_file='{tag}_ckpt.h5', checkpoint_every=50 /
"""
libc = ctypes.CDLL(None, use_errno=True)
libc.sem_open.restype = ctypes.c_void_p
libc.sem_open.argtypes = [ctypes.c_char_p, ctypes.c_int, ctypes.c_uint, ctypes.c_uint]
names = [('/OMPIO_%s' % n).encode() for n in (tag + '.h5', tag + '_ckpt.h5.tmp', tag + '_ckpt.h5')]
for n in names:                       # O_CREAT, value 0: held, as a killed job leaves it
    if not libc.sem_open(n, os.O_CREAT, 0o644, 0):
        sys.exit('cannot create the semaphore %s (errno %d)' % (n, ctypes.get_errno()))
rc = 1
try:
    for d in ('clean', 'planted'):
        os.makedirs(d)
        with open(os.path.join(d, 'run.nml'), 'w') as f:
            f.write(deck)
    env = dict(os.environ, TERRACE_IO_WATCHDOG_S='20')
    out = {}
    for d in ('planted', 'clean'):
        if d == 'clean':
            for n in names:
                libc.sem_unlink(n)
        p = subprocess.run(['mpirun', '--oversubscribe', '-np', nprocs, terrace, 'run.nml'], cwd=d, env=env,
                           capture_output=True, text=True, timeout=300)
        out[d] = p
        print('%s semaphores: exit %d' % (d, p.returncode))
    a = open('planted/thermo.csv').read() if os.path.exists('planted/thermo.csv') else None
    b = open('clean/thermo.csv').read() if os.path.exists('clean/thermo.csv') else None
    if out['planted'].returncode != 0:
        print(out['planted'].stdout[-2000:], out['planted'].stderr[-2000:])
        print('stale_mpiio_lock: FAIL (the run with locked semaphores did not finish)')
    elif a is None or a != b:
        print('stale_mpiio_lock: FAIL (thermo differs from the clean run, or is missing)')
    else:
        print('thermo identical to the clean run (%d lines)' % a.count('\n'))
        print('stale_mpiio_lock: PASS')
        rc = 0
finally:
    for n in names:
        libc.sem_unlink(n)
sys.exit(rc)
