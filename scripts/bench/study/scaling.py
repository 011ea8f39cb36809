"""Parallel scaling of both integrators on the LJ benchmark scene (shifted LJ, melted start):
strong (fixed size) and weak (atoms per rank fixed: cells = c0 * P^(1/3), rounded), one run per
rank count; the phase table (Pair, Neigh, Comm, Search, Output, Other; the max over ranks) is kept
so that the event-search time (Search: the ray evaluations and the global MIN over the ranks that
picks the event) and the halo traffic (Comm) show separately.

Only meaningful on a machine with at least as many free cores as the largest rank count."""
import csv
import os

from .common import run_terrace

PHASES = ['pair', 'neigh', 'comm', 'search', 'output', 'other']
FIELDS = ['kind', 'ranks', 'cells', 'natoms', 'method', 'n', 'loop'] + PHASES + [p + '_max' for p in PHASES]

LJ = "&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.true. /"


def _prep(ctx, d, cells, np_):
    """Melt an fcc start (300 Verlet steps from T* = 1.44) and write start.atoms in D."""
    os.makedirs(d, exist_ok=True)
    deck = ("&run units='lj', dimension=3, n_steps=300, seed=87287 /\n"
            "&system lattice='fcc', density=0.8442, cells=%d,%d,%d, periodic=.true.,.true.,.true., mass=1.0, "
            "temperature=1.44 /\n%s\n&integrator style='velocity_verlet', dt=0.005 /\n&neighbor skin=0.3 /\n"
            "&output thermo_every=100, thermo_file='', final_atoms_file='start.atoms' /\n" % (cells, cells, cells, LJ))
    r = run_terrace(ctx.terrace, d, 'prep', deck, np_=np_, timeout=ctx.timeout)
    if r['rc'] != 0:
        raise RuntimeError('scaling preparation failed: ' + r['error'])


def _deck(cells, integ, n):
    L = cells * (4.0 / 0.8442) ** (1.0 / 3.0)
    return ("&run units='lj', dimension=3, n_steps=%d, seed=1 /\n"
            "&system atoms_file='start.atoms', box_lo=0,0,0, box_hi=%r,%r,%r, periodic=.true.,.true.,.true., "
            "mass=1.0 /\n%s\n%s\n&neighbor skin=0.3 /\n&output thermo_every=%d, thermo_file='' /\n"
            % (n, L, L, L, LJ, integ, n))


def run(ctx, ranks):
    quick = ctx.mode == 'quick'
    c0 = 10 if quick else 20
    n_vv, n_es = (100, 100) if quick else (1000, 500)
    rows = []
    for kind in ('strong', 'weak'):
        for p in ranks:
            cells = c0 if kind == 'strong' else max(2, int(round(c0 * p ** (1.0 / 3.0))))
            d = os.path.join(ctx.work, 'scaling', '%s_c%d' % (kind, cells))
            if not os.path.exists(os.path.join(d, 'start.atoms')):
                _prep(ctx, d, cells, min(p, 4))
            for method, integ, n in (('terrace-vv', "&integrator style='velocity_verlet', dt=0.005 /", n_vv),
                                     ('terrace-es', "&integrator style='energy_stepping', terrace_height=0.3 /", n_es)):
                name = '%s_np%d' % (method, p)
                r = run_terrace(ctx.terrace, d, name, _deck(cells, integ, n), np_=p, timeout=ctx.timeout)
                if r['rc'] != 0:
                    print('    scaling %s %s np %d failed: %s' % (kind, method, p, r['error']), flush=True)
                    continue
                row = dict(kind=kind, ranks=p, cells=cells, natoms=4 * cells ** 3, method=method, n=r['n'],
                           loop=r['loop'])
                for ph in PHASES:
                    row[ph] = r.get(ph, 0.0)
                    row[ph + '_max'] = r.get(ph + '_max', 0.0)
                rows.append(row)
                print('    scaling %-6s %-10s ranks %2d  atoms %7d  loop %8.3f s  (search %.3f, comm %.3f)'
                      % (kind, method, p, row['natoms'], r['loop'], row['search_max'], row['comm_max']), flush=True)
    with open(os.path.join(ctx.data, 'scaling_%s.csv' % ctx.mode), 'w', newline='') as f:
        w = csv.writer(f)
        w.writerow(FIELDS)
        for r in rows:
            w.writerow([r.get(k, '') for k in FIELDS])
    return rows
