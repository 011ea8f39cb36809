#!/usr/bin/env python3
"""Table (and a figure) from a run of scripts/bench/argon_weak.sh.

Usage: python3 scripts/bench/argon_weak_report.py CSV_OR_DIR [CSV_OR_DIR...] [--no-base] [--figure PNG]

Several runs join into one table: each run's rounds stay its own (round r of the i-th run is i.r),
so that efficiencies still pair a run's one-rank and P-rank times. --no-base leaves out the
NAME-base decks of a BASELINE run.

With a BASELINE run (decks NAME-base), also the baseline's loop time over the binary's, round by round.

Per deck and rank count: the median loop time over the rounds, the weak-scaling efficiency (the
same round's one-rank loop time over the P-rank one: median and range over the rounds), microseconds
per step, and the slowest rank's Comm, Pair and Neigh seconds (medians). The figure: efficiency
(median, bars from the smallest to the largest round) and microseconds per step against ranks.
"""
import argparse
import csv
import os
import statistics

ORDER = ['default', 'mixed', 'lammps']
LABEL = {'default': 'Terrace, the job\'s deck (double, exact list)',
         'mixed': 'Terrace, mixed, buffer_tolerance',
         'lammps': 'LAMMPS (Berendsen, skin 1 A)'}


def load(source):
    path = os.path.join(source, 'argon_weak.csv') if os.path.isdir(source) else source
    with open(path) as f:
        return list(csv.DictReader(f))


def summary(rows):
    """{deck: [(ranks, atoms, loop median, (eff median, min, max), us/step, comm, pair, neigh)]}"""
    out = {}
    decks = sorted({r['deck'] for r in rows}, key=lambda d: ORDER.index(d) if d in ORDER else 9)
    for d in decks:
        one = {r['round']: float(r['loop_s']) for r in rows if r['deck'] == d and r['ranks'] == '1'}
        out[d] = []
        for p in sorted({int(r['ranks']) for r in rows if r['deck'] == d}):
            rs = [r for r in rows if r['deck'] == d and int(r['ranks']) == p]
            eff = [one[r['round']] / float(r['loop_s']) for r in rs if r['round'] in one]
            med = lambda k: statistics.median(float(r[k]) for r in rs)
            e = (statistics.median(eff), min(eff), max(eff)) if eff else None
            out[d].append((p, rs[0]['atoms'], med('loop_s'), e, med('comm_max_s'), med('pair_max_s'),
                           med('neigh_max_s')))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('source', nargs='+')
    ap.add_argument('--no-base', action='store_true', help="leave out a BASELINE run's NAME-base decks")
    ap.add_argument('--steps', type=int, default=0,
                    help='steps per run, for microseconds per step (default: read from the run directories)')
    ap.add_argument('--figure')
    a = ap.parse_args()
    rows = []
    for i, src in enumerate(a.source):
        for r in load(src):
            if len(a.source) > 1:
                r['round'] = f"{i + 1}.{r['round']}"
            rows.append(r)
    if a.no_base:
        rows = [r for r in rows if not r['deck'].endswith('-base')]
    steps = a.steps
    if not steps and len(a.source) == 1:   # the deck's run_time in ps at 10 fs, from any run directory's job.nml
        base = a.source[0] if os.path.isdir(a.source[0]) else os.path.dirname(a.source[0])
        for r in rows:
            nml = os.path.join(base, f"{r['deck']}_np{r['ranks']}_r{r['round']}", 'job.nml')
            if os.path.exists(nml):
                for line in open(nml):
                    if 'run_time=' in line:
                        steps = round(float(line.split('run_time=')[1].split(',')[0]) * 100)
                break
    res = summary(rows)
    print("deck     ranks   atoms  loop s (median)  us/step  efficiency median [min, max]   "
          "slowest rank: Comm  Pair  Neigh (median s)")
    for d, lines in res.items():
        for p, atoms, loop, e, comm, pair, neigh in lines:
            es = "%.3f [%.3f, %.3f]" % e if e else "-"
            us = "%8.1f" % (1e6 * loop / steps) if steps else "       -"
            print("%-8s %5d %7s %14.3f   %s   %-28s %12.3f %6.3f %6.3f" % (d, p, atoms, loop, us, es, comm, pair, neigh))
    paired = sorted({r['deck'][:-5] for r in rows if r['deck'].endswith('-base')})
    if paired:   # argon_weak.sh BASELINE=...: the baseline's loop time over the binary's, run by run
        print("\nNAME-base / NAME, loop time, the same round: median [min, max]")
        for d in paired:
            for p in sorted({int(r['ranks']) for r in rows if r['deck'] == d}):
                t = {(r['deck'], r['round']): float(r['loop_s']) for r in rows if int(r['ranks']) == p}
                q = [t[(d + '-base', k)] / t[(d, k)] for (dd, k) in t if dd == d and (d + '-base', k) in t]
                if q:
                    print("%-8s %5d   %.3f [%.3f, %.3f]  (%d rounds)" % (d, p, statistics.median(q), min(q), max(q),
                                                                      len(q)))
    if a.figure:
        from terrace_tools.plotting import plt, save
        fig, axes = plt.subplots(1, 2, figsize=(10, 4.2))
        style = {'default': ('C0', 'o'), 'mixed': ('C1', 's'), 'lammps': ('C2', '^')}
        ps = sorted({int(r['ranks']) for r in rows})
        for d, lines in res.items():
            col, mk = style.get(d, ('C3', 'x'))
            pe = [(p, e) for p, _, _, e, *_ in lines if e]
            axes[0].errorbar([p for p, _ in pe], [e[0] for _, e in pe],
                             yerr=[[e[0] - e[1] for _, e in pe], [e[2] - e[0] for _, e in pe]],
                             color=col, marker=mk, capsize=3, label=LABEL.get(d, d))
            if steps:
                axes[1].plot([l[0] for l in lines], [1e6 * l[2] / steps for l in lines], color=col, marker=mk,
                             label=LABEL.get(d, d))
        axes[0].axhline(1.0, ls=':', color='grey')
        axes[0].axhline(0.9, ls='--', color='grey', lw=0.8)
        axes[0].set_ylim(0, 1.1)
        axes[0].set_ylabel('efficiency T(1) / T(P), same round')
        axes[0].set_title('argon job, 864 atoms per rank: weak scaling')
        axes[1].set_yscale('log')
        axes[1].set_ylabel('microseconds per step (median)')
        axes[1].set_title('time per step')
        for ax in axes:
            ax.set_xscale('log', base=2)
            ax.set_xticks(ps)
            ax.set_xticklabels([str(p) for p in ps])
            ax.set_xlabel('MPI ranks (one per core)')
            ax.grid(alpha=0.3, which='both')
        axes[0].legend(fontsize=8, loc='lower left')
        save(fig, a.figure, dpi=110)
        print(f"figure: {a.figure}")


if __name__ == '__main__':
    main()
