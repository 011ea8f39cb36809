"""Shared machinery of the benchmark study: environment description, running Terrace and LAMMPS,
reading their outputs (logs, thermo CSV, H5MD, LAMMPS dumps, atoms files)."""
import datetime
import os
import re
import shutil
import subprocess
import time

import numpy as np

REPO = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..'))
KB_METAL = 8.617343e-5          # eV/K (Terrace and LAMMPS metal units)
MPI_ENV = {'OMPI_ALLOW_RUN_AS_ROOT': '1', 'OMPI_ALLOW_RUN_AS_ROOT_CONFIRM': '1',
           'OMPI_MCA_rmaps_base_oversubscribe': '1'}


def sh(cmd, cwd=None):
    try:
        p = subprocess.run(cmd, capture_output=True, text=True, cwd=cwd, timeout=60)
        return (p.stdout + p.stderr).strip()
    except (OSError, subprocess.TimeoutExpired):
        return ''


# ------------------------------------------------------------------------------------ environment
def environment(build):
    """Machine, compiler, flags, LAMMPS, MPI, date and commit (printed and written to the report)."""
    env = {}
    model = '?'
    try:
        for line in open('/proc/cpuinfo'):
            if line.startswith('model name'):
                model = line.split(':', 1)[1].strip()
                break
    except OSError:
        pass
    env['cpu'] = model
    env['nproc'] = sh(['nproc']) or str(os.cpu_count())
    osrel = ''
    try:
        for line in open('/etc/os-release'):
            if line.startswith('PRETTY_NAME='):
                osrel = line.split('=', 1)[1].strip().strip('"')
    except OSError:
        pass
    env['os'] = osrel
    cache = {}
    try:
        for line in open(os.path.join(build, 'CMakeCache.txt')):
            m = re.match(r'^([A-Za-z_]+):[A-Z]+=(.*)$', line.strip())
            if m:
                cache[m.group(1)] = m.group(2)
    except OSError:
        pass
    fc = cache.get('CMAKE_Fortran_COMPILER', 'gfortran')
    env['compiler'] = (sh([fc, '--version']).splitlines() or ['?'])[0]
    bt = cache.get('CMAKE_BUILD_TYPE', '')
    env['build_type'] = bt
    env['flags'] = ' '.join(x for x in [cache.get('CMAKE_Fortran_FLAGS', ''),
                                        cache.get('CMAKE_Fortran_FLAGS_' + bt.upper(), '') if bt else ''] if x)
    used = ''
    try:
        for line in open(os.path.join(build, 'CMakeFiles', 'terrace_core.dir', 'flags.make')):
            if line.startswith('Fortran_FLAGS ='):
                used = line.split('=', 1)[1].strip()
    except OSError:
        pass
    env['flags_used'] = used or env['flags']
    m = re.search(r'(\d+ \w+ \d{4}[^\n]*)', sh(['lmp', '-h']))
    env['lammps'] = ('LAMMPS ' + m.group(1).strip()) if m else 'not found'
    env['mpi'] = (sh(['mpirun', '--version']).splitlines() or ['?'])[0]
    env['date'] = datetime.datetime.now(datetime.timezone.utc).strftime('%Y-%m-%d %H:%M UTC')
    env['commit'] = sh(['git', '-C', REPO, 'rev-parse', '--short', 'HEAD'])
    env['dirty'] = bool(sh(['git', '-C', REPO, 'status', '--porcelain', '--untracked-files=no']))
    try:
        env['load'] = '%.2f %.2f %.2f' % os.getloadavg()
    except OSError:
        env['load'] = '?'
    return env


class Stopwatch:
    """Wall time of each part of the study, printed as it goes and listed at the end."""

    def __init__(self):
        self.parts = []
        self.t0 = time.time()

    def part(self, name):
        sw = self

        class _P:
            def __enter__(self):
                self.t = time.time()
                print('[%7.1f s] %s ...' % (time.time() - sw.t0, name), flush=True)

            def __exit__(self, *exc):
                dt = time.time() - self.t
                sw.parts.append((name, dt))
                print('[%7.1f s] %s done in %.1f s' % (time.time() - sw.t0, name, dt), flush=True)
        return _P()

    def total(self):
        return time.time() - self.t0


# ------------------------------------------------------------------------------------ Terrace
def parse_terrace_log(out):
    def g(pat, conv=float, default=None):
        m = re.search(pat, out, re.M)
        return conv(m.group(1)) if m else default
    r = {'loop': g(r'^Loop time:\s*([0-9.eE+-]+)\s*s'), 'n': g(r'^Loop time: .* for (\d+) ', int)}
    for ph in ('Pair', 'Neigh', 'Comm', 'Output', 'Search', 'Other'):
        r[ph.lower()] = g(r'^%s\s+([0-9.eE+-]+)' % ph, float, 0.0)
        r[ph.lower() + '_max'] = g(r'^%s\s+[0-9.eE+-]+\s+([0-9.eE+-]+)' % ph, float, 0.0)
    r['builds'] = g(r'^Neighbour list builds:\s*(\d+)', int, 0)
    if 'Events:' in out:
        m = re.search(r'^Events:\s*(\d+)\s*\((\d+) up, (\d+) down, (\d+) reflections\)', out, re.M)
        if m:
            r['events'], r['up'], r['down'], r['refl'] = (int(x) for x in m.groups())
        r['mean_dt'] = g(r'^Mean event interval:\s*([0-9.eE+-]+)')
        r['evals'] = g(r'ray evaluations per event:\s*([0-9.eE+-]+)')
        r['passes'] = g(r'force passes per event:\s*([0-9.eE+-]+)')
    r['trapped_warning'] = 'reflections' in out and 'trapped' in out
    return r


def run_terrace(terrace, work, name, deck, np_=1, timeout=3600):
    """Write NAME.nml in WORK and run it there. Returns a dict: rc, wall, log, err, error (the
    one-line engine error or ''), and the parsed run log."""
    with open(os.path.join(work, name + '.nml'), 'w') as f:
        f.write(deck)
    cmd = [terrace, name + '.nml']
    env = dict(os.environ)
    if np_ > 1:
        cmd = ['mpirun', '--oversubscribe', '-np', str(np_)] + cmd
        env.update(MPI_ENV)
    t = time.time()
    try:
        p = subprocess.run(cmd, cwd=work, capture_output=True, text=True, timeout=timeout, env=env)
        rc, out, err = p.returncode, p.stdout, p.stderr
    except subprocess.TimeoutExpired as e:
        rc, out, err = 124, (e.stdout or b'').decode() if isinstance(e.stdout, bytes) else (e.stdout or ''), 'timeout'
    wall = time.time() - t
    with open(os.path.join(work, name + '.log'), 'w') as f:
        f.write(out + '\n--- stderr ---\n' + err)
    r = parse_terrace_log(out)
    r.update(rc=rc, wall=wall, log=out, err=err, name=name)
    m = re.search(r'^terrace: error: (.*)$', err + '\n' + out, re.M)
    r['error'] = m.group(1).strip() if m else ('' if rc == 0 else 'exit status %d: %s' % (rc, err.strip()[-300:]))
    r['warnings'] = re.findall(r'^terrace: warning: (.*)$', err + '\n' + out, re.M)
    return r


def read_thermo(path):
    """Terrace thermo CSV as a dict of float arrays (empty dict if missing)."""
    if not os.path.exists(path) or os.path.getsize(path) == 0:
        return {}
    with open(path) as f:
        head = f.readline().strip().split(',')
    try:
        a = np.loadtxt(path, delimiter=',', skiprows=1, ndmin=2)
    except ValueError:
        a = np.genfromtxt(path, delimiter=',', skip_header=1, ndmin=2)
    if a.size == 0:
        return {}
    return {k.strip(): a[:, i] for i, k in enumerate(head)}


def read_atoms_file(path):
    """Terrace atoms file: (types, x (N,3), v (N,3) or None)."""
    a = np.loadtxt(path, comments='#', ndmin=2)
    types = a[:, 0].astype(int)
    x = a[:, 1:4]
    v = a[:, 4:7] if a.shape[1] >= 7 else None
    return types, x, v


def write_atoms_file(path, types, x, v, comment=''):
    with open(path, 'w') as f:
        f.write('# %s\n# type x y z vx vy vz\n' % comment)
        for t, xi, vi in zip(types, x, v):
            f.write('%d %.17g %.17g %.17g %.17g %.17g %.17g\n' % (t, *xi, *vi))


def read_h5md(path):
    """Frames of a Terrace H5MD trajectory: time (F,), unwrapped positions (F,N,d), velocities or None,
    box edges (d,)."""
    import h5py
    with h5py.File(path, 'r') as f:
        p = f['particles/all']
        t = p['position/time'][:]
        x = p['position/value'][:]
        e = p['box/edges']
        if isinstance(e, h5py.Group):       # time-dependent box (value[frames][D]): the first frame's
            e = e['value'][0]               # (Terrace's NVE runs keep the box fixed)
        else:
            e = e[()]
        edges = np.array(e, dtype=float).reshape(-1)
        bnd = [b.decode() if isinstance(b, bytes) else str(b) for b in p['box'].attrs.get('boundary', [])]
        if 'image' in p:
            img = p['image/value'][:]
            per = np.array([b.startswith('periodic') for b in bnd] + [False] * 3)[:x.shape[2]]
            x = x + img * (edges[:x.shape[2]] * per)[None, None, :]
        v = p['velocity/value'][:] if 'velocity' in p else None
    return np.asarray(t, float), np.asarray(x, float), (None if v is None else np.asarray(v, float)), edges


# ------------------------------------------------------------------------------------ LAMMPS
def have_lammps():
    return shutil.which('lmp') is not None


def write_lammps_data(path, types, x, v, lo, hi, masses, dim):
    n = len(types)
    with open(path, 'w') as f:
        f.write('terrace study start state\n\n%d atoms\n%d atom types\n\n' % (n, max(types)))
        for d, ax in enumerate('xyz'):
            f.write('%.17g %.17g %slo %shi\n' % (lo[d], hi[d], ax, ax))
        f.write('\nMasses\n\n')
        for t, m in enumerate(masses, 1):
            f.write('%d %.17g\n' % (t, m))
        f.write('\nAtoms # atomic\n\n')
        for i in range(n):
            f.write('%d %d %.17g %.17g %.17g\n' % (i + 1, types[i], *x[i]))
        f.write('\nVelocities\n\n')
        for i in range(n):
            f.write('%d %.17g %.17g %.17g\n' % (i + 1, *v[i]))


def parse_lammps_log(text):
    """Thermo rows (dict of arrays from the last run), loop time, the Output row of the timing
    breakdown, and the first ERROR line."""
    r = {'loop': None, 'output': 0.0, 'error': '', 'thermo': {}}
    m = re.search(r'^Loop time of ([0-9.eE+-]+) on (\d+) procs for (\d+) steps', text, re.M)
    if m:
        r['loop'] = float(m.group(1))
        r['n'] = int(m.group(3))
    m = re.search(r'^Output\s*\|\s*[0-9.eE+-]+\s*\|\s*([0-9.eE+-]+)', text, re.M)
    if m:
        r['output'] = float(m.group(1))
    for ph, key in (('Pair', 'pair'), ('Neigh', 'neigh'), ('Comm', 'comm'), ('Other', 'other')):
        m = re.search(r'^%s\s*\|\s*[0-9.eE+-]+\s*\|\s*([0-9.eE+-]+)' % ph, text, re.M)
        r[key] = float(m.group(1)) if m else 0.0
    m = re.search(r'^(ERROR.*)$', text, re.M)
    if m:
        r['error'] = m.group(1).strip()
    lines = text.splitlines()
    start = None
    for i, line in enumerate(lines):
        if line.split()[:2] == ['Step', 'Time']:
            start = i
    if start is not None:
        head = lines[start].split()
        rows = []
        for line in lines[start + 1:]:
            w = line.split()
            if len(w) != len(head):
                break
            try:
                rows.append([float(x) for x in w])
            except ValueError:
                break
        if rows:
            a = np.array(rows)
            names = {'Step': 'step', 'Time': 'time', 'Temp': 'temp', 'PotEng': 'pe', 'KinEng': 'ke',
                     'TotEng': 'etotal', 'Press': 'press', 'v_px': 'px', 'v_py': 'py', 'v_pz': 'pz',
                     'v_lx': 'lx', 'v_ly': 'ly', 'v_lz': 'lz'}
            r['thermo'] = {names.get(h, h): a[:, i] for i, h in enumerate(head)}
    return r


def run_lammps(work, name, text, np_=1, timeout=3600):
    path = os.path.join(work, name + '.in')
    with open(path, 'w') as f:
        f.write(text)
    cmd = ['lmp', '-screen', 'none', '-log', name + '.lmplog', '-in', name + '.in']
    env = dict(os.environ)
    if np_ > 1:
        cmd = ['mpirun', '--oversubscribe', '-np', str(np_)] + cmd
        env.update(MPI_ENV)
    t = time.time()
    try:
        p = subprocess.run(cmd, cwd=work, capture_output=True, text=True, timeout=timeout, env=env)
        rc = p.returncode
        extra = p.stdout + p.stderr
    except subprocess.TimeoutExpired:
        rc, extra = 124, 'timeout'
    wall = time.time() - t
    try:
        text = open(os.path.join(work, name + '.lmplog')).read()
    except OSError:
        text = ''
    r = parse_lammps_log(text + '\n' + extra)
    r.update(rc=rc, wall=wall, name=name)
    if rc != 0 and not r['error']:
        r['error'] = 'exit status %d: %s' % (rc, extra.strip()[-300:])
    return r


def read_lammps_dump(path, dt):
    """Custom text dump 'id xu yu zu vx vy vz' sorted by id: times (F,), x (F,N,3), v (F,N,3)."""
    times, xs, vs = [], [], []
    with open(path) as f:
        lines = f.read().splitlines()
    i = 0
    while i < len(lines):
        if lines[i].startswith('ITEM: TIMESTEP'):
            step = int(lines[i + 1])
            n = int(lines[i + 3])
            j = i + 4
            while not lines[j].startswith('ITEM: ATOMS'):
                j += 1
            a = np.array([[float(w) for w in lines[k].split()] for k in range(j + 1, j + 1 + n)])
            a = a[np.argsort(a[:, 0])]
            times.append(step * dt)
            xs.append(a[:, 1:4])
            vs.append(a[:, 4:7])
            i = j + 1 + n
        else:
            i += 1
    return np.array(times), np.array(xs), np.array(vs)
