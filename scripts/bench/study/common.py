"""Shared machinery of the benchmark study: environment description, running Terrace and LAMMPS,
reading their outputs (logs, thermo CSV, H5MD, LAMMPS dumps, atoms files)."""
import datetime
import math
import os
import re
import shutil
import subprocess
import time

import numpy as np

from terrace_tools import atoms, h5md, lammps, summary, thermo

REPO = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..', '..'))
KB_METAL = 8.617343e-5          # eV/K (Terrace and LAMMPS metal units)
TRAPPED_SHARE = 0.9             # energy stepping: 'trapped' above this share of reflections among events
TRAPPED_MIN_EVENTS = 100        # ... of at least this many events (the engine's own threshold for warning)
MPI_ENV = {'OMPI_ALLOW_RUN_AS_ROOT': '1', 'OMPI_ALLOW_RUN_AS_ROOT_CONFIRM': '1',
           'OMPI_MCA_rmaps_base_oversubscribe': '1'}


def exact_dt(t_end, dt):
    """The Verlet step that ends a run exactly at T_END: t_end / N with N = ceil(t_end / dt), so the
    step is never larger than the requested DT (the engine takes nint(run_time / dt) steps: with a dt
    that does not divide run_time the run would end up to dt/2 away from t_end)."""
    n = max(1, int(math.ceil(t_end / dt * (1.0 - 1e-12))))
    return t_end / n


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
def parse_terrace_summary(path):
    """The closing run log's figures from the run summary (terrace_tools.summary.run_figures); for a
    run that wrote none (it failed): loop and n None, phases and builds 0."""
    if not os.path.exists(path):
        r = {'loop': None, 'n': None, 'builds': 0}
        for ph in ('pair', 'neigh', 'comm', 'output', 'search', 'other'):
            r[ph] = r[ph + '_max'] = 0.0
        return r
    return summary.run_figures(path)


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
    summary_path = os.path.join(work, summary.default_name(name + '.nml'))
    if os.path.exists(summary_path):
        os.remove(summary_path)
    t = time.time()
    try:
        p = subprocess.run(cmd, cwd=work, capture_output=True, text=True, timeout=timeout, env=env)
        rc, out, err = p.returncode, p.stdout, p.stderr
    except subprocess.TimeoutExpired as e:
        rc, out, err = 124, (e.stdout or b'').decode() if isinstance(e.stdout, bytes) else (e.stdout or ''), 'timeout'
    wall = time.time() - t
    with open(os.path.join(work, name + '.log'), 'w') as f:
        f.write(out + '\n--- stderr ---\n' + err)
    r = parse_terrace_summary(summary_path)
    # trapped: more than 90 % of the events were reflections (the run summary's measured share; the
    # run log warns above one half, and says 'trapped' above 90 %)
    share = r.get('refl_share')
    r['trapped'] = share is not None and (r.get('events') or 0) >= TRAPPED_MIN_EVENTS and share > TRAPPED_SHARE
    r.update(rc=rc, wall=wall, log=out, err=err, name=name)
    m = re.search(r'^terrace: error: (.*)$', err + '\n' + out, re.M)
    r['error'] = m.group(1).strip() if m else ('' if rc == 0 else 'exit status %d: %s' % (rc, err.strip()[-300:]))
    r['warnings'] = re.findall(r'^terrace: warning: (.*)$', err + '\n' + out, re.M)
    return r


read_thermo = thermo.read
read_atoms_file = atoms.read
write_atoms_file = atoms.write


def read_h5md(path):
    """Frames of a Terrace H5MD trajectory: time (F,), unwrapped positions (F,N,d), velocities or None,
    box edges (d,)."""
    fr = h5md.read(path)
    return fr['time'], fr['x'], fr['v'], fr['edges']


# ------------------------------------------------------------------------------------ LAMMPS
def have_lammps():
    return shutil.which('lmp') is not None


def write_lammps_data(path, types, x, v, lo, hi, masses, dim):
    lammps.write_data(path, types, x, v, lo, hi, masses, title='terrace study start state')


parse_lammps_log = lammps.parse_log


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
    times, c = lammps.read_dump(path, dt)
    if not c:
        return times, np.array([]), np.array([])
    return times, np.stack([c['xu'], c['yu'], c['zu']], axis=-1), np.stack([c['vx'], c['vy'], c['vz']], axis=-1)


def splice_section(path, lines, name, after):
    """Put a study section (lines, from '<!-- NAME:begin -->' to '<!-- NAME:end -->') into the page at
    path: in place of the section's old text, else after the section AFTER's end marker, else at the end."""
    if not lines:
        return
    text = open(path).read() if os.path.exists(path) else ''
    block = '\n'.join(lines)
    b, e, a = '<!-- %s:begin -->' % name, '<!-- %s:end -->' % name, '<!-- %s:end -->' % after
    if b in text and e in text:
        text = text[:text.index(b)] + block + text[text.index(e) + len(e):]
    elif a in text:
        i = text.index(a) + len(a)
        text = text[:i] + '\n\n' + block + text[i:]
    else:
        text = text.rstrip('\n') + '\n\n' + block + '\n'
    with open(path, 'w') as f:
        f.write(text)
