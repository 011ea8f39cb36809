#!/usr/bin/env python3
"""Tables (and a figure) from a run of scripts/bench/scaling.sh.

Usage: python3 scripts/bench/scaling_report.py DIR_OR_TGZ [--phases] [--figure PNG]

DIR_OR_TGZ is scaling.sh's OUTDIR (scaling.csv and one folder per point), or a .tgz of it.
  default    one table per scene and kind: loop seconds of Terrace Verlet, Terrace energy stepping
             and LAMMPS, speed-up (strong) or efficiency (weak) against one rank, the LAMMPS/Terrace
             Verlet ratio, Terrace's Comm and Search (slowest rank) and ray evaluations per event.
  --phases   per step / per event milliseconds of each phase (Terrace's run summaries, LAMMPS's log; average and slowest
             rank): Terrace Verlet and LAMMPS Pair, Neigh, Comm; energy stepping's force pass (Pair),
             ray passes (Search, also per ray evaluation) and Comm. Energy stepping's ray evaluations
             per event depend on the state, so its weak scaling is read per pass here.
  --figure   speed-up (strong) and efficiency (weak) against ranks, both scenes, all three codes.
A run with BASELINE (codes terrace-vv-base, terrace-es-base) adds the baseline's loop time over the
binary's at each point.
"""
import argparse
import csv
import io
import json
import os
import sys
import tarfile

from terrace_tools import lammps
from terrace_tools import summary as run_summary

CODES = ['terrace-vv', 'terrace-es', 'lammps']
LABEL = {'terrace-vv': 'Terrace Verlet', 'terrace-es': 'Terrace energy stepping', 'lammps': 'LAMMPS Verlet'}


class Source:
    """Files of a scaling.sh OUTDIR, from the folder or from a .tgz of it."""

    def __init__(self, path):
        self.dir, self.tar = None, None
        if os.path.isdir(path):
            self.dir = path
        else:
            self.tar = tarfile.open(path)
            self.names = {os.path.normpath(m.name): m for m in self.tar.getmembers() if m.isfile()}

    def read(self, rel):
        if self.dir is not None:
            p = os.path.join(self.dir, rel)
            return open(p).read() if os.path.exists(p) else None
        m = self.names.get(os.path.normpath(rel))
        return self.tar.extractfile(m).read().decode() if m is not None else None


def load(src):
    text = src.read('scaling.csv')
    if text is None:
        sys.exit('scaling_report.py: no scaling.csv in the given folder or archive')
    rows = list(csv.DictReader(io.StringIO(text)))
    for r in rows:
        r['ranks'], r['n'] = int(r['ranks']), int(r['n'])
        r['loop_s'] = float(r['loop_s'])
    return rows


def groups(rows):
    for scene in ('lj', 'eam'):
        for kind in ('strong', 'weak'):
            sel = [r for r in rows if r['scene'] == scene and r['kind'] == kind]
            if sel:
                yield scene, kind, sel


def pick(sel, p, code):
    return next((r for r in sel if r['ranks'] == p and r['code'] == code), None)


def ratio_to_one(sel, r):
    """T(1 rank) / T(P ranks): speed-up (strong) or efficiency (weak)."""
    b = pick(sel, 1, r['code'])
    return None if b is None else b['loop_s'] / r['loop_s']


def summary(src, rows):
    for scene, kind, sel in groups(rows):
        what = 'speed-up' if kind == 'strong' else 'efficiency'
        size = '32,000 atoms' if kind == 'strong' else '32,000 atoms per rank'
        print(f"{scene.upper()} {kind} scaling ({size}): loop s ({what} against 1 rank); "
              "Terrace's Comm and Search: slowest rank, s")
        print(f"{'ranks':>5} {'atoms':>8} | {'Terrace VV':>18} | {'Terrace ES':>18} | {'LAMMPS':>18} | "
              f"{'VV/LAMMPS':>9} | {'VV comm':>8} {'ES comm':>8} {'ES search':>9} {'ES rays':>7} {'event/step':>10}")
        for p in sorted({r['ranks'] for r in sel}):
            cells = []
            for c in CODES:
                r = pick(sel, p, c)
                if r is None:
                    cells.append(f"{'failed':>18}")
                    continue
                s = ratio_to_one(sel, r)
                cells.append(f"{r['loop_s']:9.3f} ({s:6.2f})" if s is not None else f"{r['loop_s']:9.3f}         ")
            vv, lm, es = pick(sel, p, 'terrace-vv'), pick(sel, p, 'lammps'), pick(sel, p, 'terrace-es')
            ratio = f"{lm['loop_s'] / vv['loop_s']:9.2f}" if vv and lm else f"{'':>9}"
            cost = (f"{(es['loop_s'] / es['n']) / (vv['loop_s'] / vv['n']):10.2f}" if vv and es
                    else f"{'-':>10}")

            def g(r, k, fmt='.3f'):
                return format(float(r[k]), fmt) if r is not None and r.get(k) else '-'
            natoms = next(r['atoms'] for r in sel if r['ranks'] == p)
            print(f"{p:5d} {natoms:>8} | {cells[0]} | {cells[1]} | {cells[2]} | {ratio} | "
                  f"{g(vv, 'comm_max_s'):>8} {g(es, 'comm_max_s'):>8} {g(es, 'search_max_s'):>9} "
                  f"{'-' if es is None or rays_per_event(src, es) is None else format(rays_per_event(src, es), '.3f'):>7} {cost}")
        print()
    base = [r for r in rows if r['code'].endswith('-base')]
    if base:   # scaling.sh BASELINE=...
        print("Baseline (BASELINE's binary, run just before): its loop time over the binary's, same point")
        for r in base:
            b = pick([x for x in rows if x['scene'] == r['scene'] and x['kind'] == r['kind']], r['ranks'],
                     r['code'][:-5])
            if b is not None:
                print(f"  {r['scene']:4} {r['kind']:6} np {r['ranks']:2d}  {r['code'][:-5]:10}  "
                      f"{r['loop_s']:8.3f} / {b['loop_s']:8.3f} = {r['loop_s'] / b['loop_s']:.3f}")
        print()
    print("VV/LAMMPS: LAMMPS loop time over Terrace Verlet's (above 1: Terrace faster), same steps, same ranks.")
    print("ES rays: ray evaluations per event (one ray pass each; an event also costs one force pass).")
    print("event/step: energy stepping's loop time per event over Verlet's per step, same ranks.")


def summary_phases(src, d, code):
    """{phase: (avg, max)} seconds from the run summary d/CODE.summary.json (None if there is none)."""
    t = src.read(os.path.join(d, code + '.summary.json'))
    if not t:
        return None
    return {k: (v['avg_s'], v['max_s']) for k, v in json.loads(t)['timing']['phases'].items()}


def lammps_phases(text):
    """{phase: (avg, max)} seconds from a LAMMPS log's MPI task timing breakdown."""
    r = lammps.parse_log(text)
    return {k.capitalize(): (r[k], r.get(k + '_max', r[k])) for k in ('pair', 'neigh', 'comm', 'modify', 'output', 'other')}


def rays_per_event(src, r):
    """Ray evaluations per event: the CSV's column or the run summary's."""
    if r.get('rays_per_event'):
        return float(r['rays_per_event'])
    t = src.read(os.path.join(f"{r['scene']}_{r['kind']}_np{r['ranks']}", 'terrace-es.summary.json'))
    if t:
        return run_summary.get(json.loads(t), 'energy_stepping/ray_evaluations_per_event', None)
    return None


def phases(src, rows):
    def cell(ph, k, n, scale=1.0):
        if k not in ph:
            return f"{'-':>13}"
        return f"{1e3 * ph[k][0] / n / scale:6.3f}/{1e3 * ph[k][1] / n / scale:<6.3f}"
    for scene, kind, sel in groups(rows):
        print(f"{scene.upper()} {kind}: ms per step (Verlet) or per event (energy stepping), average/slowest rank")
        head = ''.join(f" {h:>13}" for h in ('pair', 'neigh', 'comm'))
        print(f"{'':5} | {'Terrace Verlet':^41} | {'LAMMPS Verlet':^41} | {'Terrace energy stepping':^62}")
        print(f"{'ranks':>5} |{head} |{head} |" + ''.join(f" {h:>13}" for h in ('force', 'rays', 'per ray', 'comm'))
              + f" {'rays':>6}")
        for p in sorted({r['ranks'] for r in sel}):
            d = f"{scene}_{kind}_np{p}"
            line = f"{p:5d} |"
            for code, keys in (('terrace-vv', ('Pair', 'Neigh', 'Comm')), ('lammps', ('Pair', 'Neigh', 'Comm'))):
                r = pick(sel, p, code)
                if code == 'lammps':
                    t = src.read(os.path.join(d, 'lammps.log'))
                    ph = lammps_phases(t) if t else None
                else:
                    ph = summary_phases(src, d, code)
                if ph and r:
                    line += ''.join(' ' + cell(ph, k, int(r['n'])) for k in keys)
                else:
                    line += f"{'':42}"
                line += ' |'
            ph, r = summary_phases(src, d, 'terrace-es'), pick(sel, p, 'terrace-es')
            if ph and r:
                n, rays = int(r['n']), rays_per_event(src, r)
                line += (' ' + cell(ph, 'Pair', n) + ' ' + cell(ph, 'Search', n) + ' '
                         + (cell(ph, 'Search', n, rays) if rays else f"{'-':>13}") + ' ' + cell(ph, 'Comm', n)
                         + (f" {rays:6.2f}" if rays else ''))
            print(line)
        print()
    print("Terrace energy stepping: force = the force pass at each event (Pair); rays = the ray passes of an")
    print("event (Search, with the global MIN that picks the event); per ray = Search per ray evaluation;")
    print("rays = ray evaluations per event. Comm includes the time a rank waits for slower ones at each")
    print("exchange, so the slowest rank's extra compute shows up as the others' Comm.")


def figure(rows, path):
    import matplotlib
    from terrace_tools.plotting import plt, save
    kinds = [k for k in ('strong', 'weak') if any(r['kind'] == k for r in rows)]   # a panel per kind run
    fig, axes = plt.subplots(1, len(kinds) + 1, figsize=(5 * (len(kinds) + 1), 4.4))
    style = {'terrace-vv': ('C0', 'o'), 'terrace-es': ('C1', 's'), 'lammps': ('C2', '^')}
    for ax, kind in zip(axes, kinds):
        allp = set()
        for scene, ls in (('lj', '-'), ('eam', '--')):
            sel = [r for r in rows if r['scene'] == scene and r['kind'] == kind]
            for c in CODES:
                pts = sorted((r['ranks'], ratio_to_one(sel, r)) for r in sel if r['code'] == c)
                pts = [(p, s) for p, s in pts if s is not None]
                if not pts:
                    continue
                allp.update(p for p, _ in pts)
                col, mk = style[c]
                ax.plot([p for p, _ in pts], [s for _, s in pts], ls, color=col, marker=mk,
                        label=f"{scene.upper()} {LABEL[c]}")
        ps = sorted(allp)
        if kind == 'strong':
            ax.plot(ps, ps, ':', color='grey', label='ideal')
            ax.set_ylabel('speed-up T(1) / T(P)')
            ax.set_title('strong scaling, 32,000 atoms')
            ax.set_yscale('log', base=2)
        else:
            ax.axhline(1.0, ls=':', color='grey', label='ideal')
            ax.set_ylabel('efficiency T(1) / T(P)')
            ax.set_title('weak scaling, 32,000 atoms per rank')
            ax.set_ylim(0, 1.1)
        ax.set_xscale('log', base=2)
        ax.set_xticks(ps)
        ax.set_xticklabels([str(p) for p in ps])
        ax.set_xlabel('MPI ranks (one per core)')
        ax.grid(alpha=0.3)
    ax = axes[-1]    # what the speed-ups are of: ms per Verlet step (per event for energy stepping)
    for scene, ls in (('lj', '-'), ('eam', '--')):
        sel = [r for r in rows if r['scene'] == scene and r['kind'] == 'strong']
        for c in CODES:
            pts = sorted((r['ranks'], 1e3 * r['loop_s'] / int(r['n'])) for r in sel if r['code'] == c)
            if pts:
                col, mk = style[c]
                ax.plot([p for p, _ in pts], [t for _, t in pts], ls, color=col, marker=mk,
                        label=f"{scene.upper()} {LABEL[c]}")
    ax.set_xscale('log', base=2)
    ax.set_yscale('log')
    ps = sorted({r['ranks'] for r in rows})
    ax.set_xticks(ps)
    ax.set_xticklabels([str(p) for p in ps])
    ax.set_xlabel('MPI ranks (one per core)')
    ax.set_ylabel('ms per step (energy stepping: per event)')
    ax.set_title('strong scaling, 32,000 atoms: time')
    ax.grid(alpha=0.3, which='both')
    axes[0].legend(fontsize=7, loc='upper left')
    save(fig, path, dpi=110)
    print(f"figure: {path}")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('source')
    ap.add_argument('--phases', action='store_true')
    ap.add_argument('--figure')
    ap.add_argument('--no-es-weak', action='store_true',
                    help='leave energy stepping out of the weak-scaling panel of the figure')
    a = ap.parse_args()
    src = Source(a.source)
    rows = load(src)
    summary(src, rows)
    if a.phases:
        print()
        phases(src, rows)
    if a.figure:
        fr = [r for r in rows if not (a.no_es_weak and r['kind'] == 'weak' and r['code'] == 'terrace-es')]
        figure(fr, a.figure)


if __name__ == '__main__':
    main()
