#!/usr/bin/env python3
"""Summary of scripts/bench/ab_ranks.sh's output (its screen, or the ab_ranks.txt it leaves).

Usage: python3 scripts/bench/ab_ranks_report.py FILE

Per deck, rank count and binary: the lowest and median loop time over the rounds; OLD over NEW in each
round (a pair ran back to back) and the median of those ratios; each binary's speed-up from one rank
(median loop time at one rank over the median at P ranks), where one rank was run.
"""
import collections
import re
import statistics
import sys

LINE = re.compile(r'r(\d+) np\s*(\d+) (\S+)\s+(old|new) loop\s+([0-9.]+) s')


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    runs = collections.defaultdict(dict)          # (deck, np, binary) -> {round: loop seconds}
    with open(sys.argv[1]) as f:
        for line in f:
            m = LINE.match(line)
            if m:
                runs[(m[3], int(m[2]), m[4])][int(m[1])] = float(m[5])
    if not runs:
        sys.exit(f"ab_ranks_report.py: no run lines in {sys.argv[1]}")
    decks = sorted({k[0] for k in runs})
    print(f"{'deck':<16} {'ranks':>5} | {'old low':>8} {'old med':>8} | {'new low':>8} {'new med':>8} | "
          f"{'old/new paired: median [per round]':<40} | {'speed-up old':>12} {'new':>6}")
    for deck in decks:
        for np_ in sorted({k[1] for k in runs if k[0] == deck}, reverse=True):
            o, n = runs.get((deck, np_, 'old'), {}), runs.get((deck, np_, 'new'), {})

            def cols(d):
                return (f"{min(d.values()):8.3f} {statistics.median(d.values()):8.3f}" if d
                        else f"{'-':>8} {'-':>8}")

            pairs = [o[r] / n[r] for r in sorted(o) if r in n and n[r] > 0]
            paired = (f"{statistics.median(pairs):5.2f} [{', '.join(f'{x:.2f}' for x in pairs)}]" if pairs
                      else '-')

            def speedup(b, d):
                one = runs.get((deck, 1, b), {})
                return (f"{statistics.median(one.values()) / statistics.median(d.values()):.2f}"
                        if one and d else '-')
            print(f"{deck:<16} {np_:5d} | {cols(o)} | {cols(n)} | {paired:<40} | "
                  f"{speedup('old', o):>12} {speedup('new', n):>6}")
    print("Loop seconds; lowest and median over the rounds. Paired: OLD/NEW of the two runs of one round"
          " (above 1: NEW faster).")


if __name__ == '__main__':
    main()
