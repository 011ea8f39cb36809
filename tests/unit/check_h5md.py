#!/usr/bin/env python3
"""Checks of the H5MD files written by the terrace_h5md tests (h5py).

  check_h5md.py layout DIR
      DIR holds h5md_np{1,2,4}.h5 and h5md_2d_np{1,2,4}.h5 written by test_h5md: H5MD 1.1 layout,
      attributes, shapes, atoms in id order, values, step/time, observables; the files written on
      1, 2 and 4 ranks have identical content; `h5dump -H` reads them (its output is printed).
  check_h5md.py killed MPIEXEC NPFLAG DRIVER FILE [PREFLAGS...]
      runs DRIVER on 2 ranks; it writes 2 frames and calls MPI_Abort without closing the file:
      the file must still be readable, with the 2 frames.
Exit status 0 when every check passes.
"""
import os
import shutil
import subprocess
import sys

import h5py
import numpy as np

N = 10
MASSES = np.array([1.5, 4.0, 39.948])
failures = []


def check(cond, what):
    if not cond:
        failures.append(what)
        print('FAIL:', what)


def text(a):
    """An attribute string (fixed-length bytes or variable-length str) as str."""
    if isinstance(a, np.ndarray):
        return [text(x) for x in a]
    return a.decode() if isinstance(a, (bytes, np.bytes_)) else str(a)


def expected(k, dim=3):
    """Frame k values by id (rows id-1): position, velocity, force, image."""
    ids = np.arange(1, N + 1, dtype=float)[:, None]
    d = np.arange(1, dim + 1, dtype=float)[None, :]
    return (10.0 * ids + d + 0.25 * k, -(ids + 0.5 * d) - k, 0.125 * ids * d + k,
            (ids * d - 3 * k).astype(np.int32))


def check_main(path):
    with h5py.File(path, 'r') as f:
        h = f['h5md']
        check(list(h.attrs['version']) == [1, 1], f'{path}: h5md/version')
        check(text(h['author'].attrs['name']) == 'Terrace tests', f'{path}: author/name')
        check(text(h['creator'].attrs['name']) == 'Terrace', f'{path}: creator/name')
        check(text(h['creator'].attrs['version']) == '0.1.0-test', f'{path}: creator/version')
        u = h['modules/units']
        check(list(u.attrs['version']) == [1, 0] and text(u.attrs['system']) == 'SI', f'{path}: units module')
        p = f['particles/all']
        box = p['box']
        check(int(box.attrs['dimension']) == 3 and box.attrs['dimension'].shape == (), f'{path}: box/dimension')
        check(text(box.attrs['boundary']) == ['periodic', 'periodic', 'none'], f'{path}: box/boundary')
        e = box['edges']
        check(isinstance(e, h5py.Group) and e['value'].shape == (3, 3) and e['value'].maxshape == (None, 3),
              f'{path}: box/edges is not a time-dependent element of shape (frames, 3)')
        check(np.array_equal(e['value'][()], [[110.0, 41.0, 7.5]] * 3), f'{path}: box/edges/value')
        check(e['value'].dtype == np.float64 and text(e['value'].attrs['unit']) == 'Ang', f'{path}: edges unit')
        check(list(e['step'][()]) == [0, 100, 200] and list(e['time'][()]) == [0.0, 0.5, 1.0]
              and text(e['time'].attrs['unit']) == 'ps', f'{path}: box/edges/step, time')
        units = {'position': 'Ang', 'velocity': 'Ang ps-1', 'force': 'eV Ang-1', 'image': None}
        for j, name in enumerate(['position', 'velocity', 'force', 'image']):
            g = p[name]
            v = g['value']
            check(v.shape == (3, N, 3), f'{path}: {name}/value shape {v.shape}')
            check(v.maxshape == (None, N, 3) and v.chunks is not None, f'{path}: {name}/value not extendible')
            check(v.dtype == (np.int32 if name == 'image' else np.float64), f'{path}: {name} dtype {v.dtype}')
            check(text(v.attrs.get('unit')) == str(units[name]) if units[name] else 'unit' not in v.attrs,
                  f'{path}: {name} unit')
            check(g['step'].dtype == np.int64 and list(g['step'][()]) == [0, 100, 200], f'{path}: {name}/step')
            check(g['time'].dtype == np.float64 and list(g['time'][()]) == [0.0, 0.5, 1.0], f'{path}: {name}/time')
            check(g['step'] == p['box/edges/step'] and g['time'] == p['box/edges/time'],
                  f'{path}: {name}/step,time are not hard links to box/edges/')
            for k in range(3):
                check(np.array_equal(v[k], expected(k)[j]), f'{path}: {name} frame {k} values')
        check(text(p['position/time'].attrs['unit']) == 'ps', f'{path}: time unit')
        check(p['id'].dtype == np.int64 and np.array_equal(p['id'][()], np.arange(1, N + 1)), f'{path}: id')
        species = 1 + np.arange(1, N + 1) % 3
        check(p['species'].dtype == np.int32 and np.array_equal(p['species'][()], species), f'{path}: species')
        check(np.array_equal(p['mass'][()], MASSES[species - 1]) and text(p['mass'].attrs['unit']) == 'u',
              f'{path}: mass')
        o = f['observables']
        pe = o['potential_energy']
        check(list(pe['step'][()]) == [0, 100, 200] and list(pe['time'][()]) == [0.0, 0.5, 1.0]
              and list(pe['value'][()]) == [0.0, -1.5, -3.0], f'{path}: observables/potential_energy')
        check(text(pe['value'].attrs['unit']) == 'eV' and text(pe['time'].attrs['unit']) == 'ps',
              f'{path}: potential_energy units')
        t = o['temperature']
        check(list(t['step'][()]) == [0, 200] and list(t['value'][()]) == [300.0, 302.0],
              f'{path}: observables/temperature')


def check_2d(path):
    with h5py.File(path, 'r') as f:
        check('modules' not in f['h5md'], f'{path}: units module without units')
        p = f['particles/all']
        check(int(p['box'].attrs['dimension']) == 2 and text(p['box'].attrs['boundary']) == ['periodic', 'none'],
              f'{path}: 2-D box')
        check(sorted(p.keys()) == ['box', 'id', 'mass', 'position', 'species', 'velocity'], f'{path}: groups')
        check(p['position/value'].shape == (2, N, 2) and 'unit' not in p['position/value'].attrs,
              f'{path}: 2-D position')
        check(list(p['velocity/step'][()]) == [7, 8], f'{path}: 2-D step')
        check(np.array_equal(p['box/edges/value'][()], [[20.0, 30.0], [20.0, 30.0]])
              and 'unit' not in p['box/edges/value'].attrs, f'{path}: 2-D box/edges/value')
        for k in range(2):
            x, v, _, _ = expected(k, dim=2)
            check(np.array_equal(p['position/value'][k], x) and np.array_equal(p['velocity/value'][k], v),
                  f'{path}: 2-D values frame {k}')


def content(path):
    """Every link path -> (attributes, dataset dtype/shape/values) for a content comparison."""
    out = {}

    def walk(g, prefix):
        out[prefix or '/'] = ('group', {k: np.asarray(g.attrs[k]).tolist() for k in sorted(g.attrs)})
        for name in sorted(g.keys()):
            obj = g[name]
            full = prefix + '/' + name
            if isinstance(obj, h5py.Group):
                walk(obj, full)
            else:
                out[full] = (str(obj.dtype), obj.shape, obj.maxshape, obj[()].tolist(),
                             {k: np.asarray(obj.attrs[k]).tolist() for k in sorted(obj.attrs)})
    with h5py.File(path, 'r') as f:
        walk(f, '')
    return out


def layout(directory):
    for stem, checker in (('h5md', check_main), ('h5md_2d', check_2d)):
        files = [os.path.join(directory, f'{stem}_np{p}.h5') for p in (1, 2, 4)]
        for path in files:
            if not os.path.exists(path):
                check(False, f'{path} is missing (run test_h5md first)')
                return
            checker(path)
        ref = content(files[0])
        for path in files[1:]:
            other = content(path)
            check(other == ref, f'{path} differs in content from {files[0]}: '
                  + ', '.join(sorted(k for k in set(ref) | set(other) if ref.get(k) != other.get(k))))
    h5dump = shutil.which('h5dump')
    if h5dump:
        r = subprocess.run([h5dump, '-H', os.path.join(directory, 'h5md_np4.h5')], capture_output=True, text=True)
        print(r.stdout)
        check(r.returncode == 0 and 'HDF5' in r.stdout, f'h5dump -H failed: {r.stderr}')
    else:
        print('h5dump not found: header dump skipped')


def killed(mpiexec, npflag, driver, path, preflags):
    if os.path.exists(path):
        os.remove(path)
    r = subprocess.run([mpiexec, *preflags, npflag, '2', driver, path], capture_output=True, text=True, timeout=120)
    check(r.returncode != 0, 'the driver was expected to abort')
    try:
        with h5py.File(path, 'r') as f:
            p = f['particles/all']
            check(p['position/value'].shape == (2, N, 3), f'killed run: shape {p["position/value"].shape}')
            check(list(p['position/step'][()]) == [0, 1], 'killed run: steps')
            for k in range(2):
                check(np.array_equal(p['position/value'][k], expected(k)[0]), f'killed run: frame {k}')
            check(np.array_equal(p['id'][()], np.arange(1, N + 1)), 'killed run: id')
    except (OSError, KeyError) as e:
        check(False, f'killed run: {path} unreadable: {e}\n{r.stdout}\n{r.stderr}')


if __name__ == '__main__':
    if len(sys.argv) == 3 and sys.argv[1] == 'layout':
        layout(sys.argv[2])
    elif len(sys.argv) >= 6 and sys.argv[1] == 'killed':
        killed(sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5], sys.argv[6:])
    else:
        print(__doc__)
        sys.exit(2)
    print('check_h5md:', 'FAILED' if failures else 'passed', f'({len(failures)} failures)')
    sys.exit(1 if failures else 0)
