#!/usr/bin/env python3
"""Counters inside energy stepping's event search, for scripts/bench/es_search_probe.sh.

  search_probe.py patch SRC_DIR     add the counters to a copy of the sources (never the repository's)
  search_probe.py report FILE       print the tables of the counts the patched build wrote to FILE

The patched build counts, over a run:
  1. ray evaluations per search, whether the root was evaluated or returned unevaluated (checked by
     the force pass at the kick), and what the kick before the search was (climb, reflection, fall;
     'none': the first search, a window's end, a verification miss);
  2. at the first evaluation of a search (s1, aimed by the Taylor quadratic from s = 0), how far f(s1)
     lies from the nearer level, in units of the terrace (upper - lower), by decade; apart for the
     searches whose curvature at s = 0 was measured and those that aimed with the last event's
     curvature (after a kick);
  3. where the solver considers returning the next Taylor root unevaluated (the root less than a
     quarter step away), its predicted error (f''' from the two ends) against the error found when
     that root is evaluated after all, both in units of the tolerance, by decade.
ES_PROBE_ACCEPT (default 0.1) replaces the fraction of the tolerance below which that root is
returned unevaluated.
"""
import sys

SOLVER = 'src/integrators/event_solver.f90'
STEPPING = 'src/integrators/energy_stepping.f90'

# (file, text that must occur once, replacement)
EDITS = [
    (SOLVER, "    public :: taylor_step, hermite_value\n",
     "    public :: taylor_step, hermite_value\n"
     "    integer(8), public :: probe_first(-20:2, 0:1) = 0, probe_next(-20:10, -20:10) = 0\n"
     "    real(8), public :: probe_accept = 0.1d0\n"),
    (SOLVER, "        integer :: status\n        logical :: c0_unknown\n        s0 = 0\n",
     "        integer :: status\n        logical :: c0_unknown, pend\n        real(dp) :: pred, plev\n"
     "        pend = .false.\n        s0 = 0\n"),
    (SOLVER, "            call ray%eval(s1, p1)\n            if (c0_unknown) then\n",
     "            call ray%eval(s1, p1)\n"
     "            if (pend) probe_next(bucket(pred, 10), bucket(abs(p1(1) - plev)/self%tol, 10)) = &\n"
     "                probe_next(bucket(pred, 10), bucket(abs(p1(1) - plev)/self%tol, 10)) + 1\n"
     "            pend = .false.\n"
     "            if (s0 == 0) probe_first(bucket(min(abs(p1(1) - upper), abs(p1(1) - lower))/(upper - lower), 2), &\n"
     "                merge(1, 0, c0_unknown)) = probe_first(bucket(min(abs(p1(1) - upper), abs(p1(1) - lower))/&\n"
     "                (upper - lower), 2), merge(1, 0, c0_unknown)) + 1\n"
     "            if (c0_unknown) then\n"),
    (SOLVER, "            if (step < 0.25_dp*(s1 - s0) .and. s1 + step <= s_max) then\n"
             "                if (abs(p1(3) - p0(3))/(s1 - s0)*step**3/6 < 0.1_dp*self%tol) then\n",
     "            if (step < 0.25_dp*(s1 - s0) .and. s1 + step <= s_max) then\n"
     "                pend = .true.; pred = abs(p1(3) - p0(3))/(s1 - s0)*step**3/6/self%tol\n"
     "                plev = merge(upper, lower, su <= sl)\n"
     "                if (abs(p1(3) - p0(3))/(s1 - s0)*step**3/6 < probe_accept*self%tol) then\n"),
    (SOLVER, "\nend module terrace_event_solver",
     "\n    pure integer function bucket(x, top)\n"
     "        real(dp), intent(in) :: x\n        integer, intent(in) :: top\n"
     "        bucket = max(-20, min(top, floor(log10(x + 1.0e-30_dp))))\n"
     "    end function bucket\n\nend module terrace_event_solver"),
    (STEPPING, "    use terrace_event_solver, only: ",
     "    use terrace_event_solver, only: probe_first, probe_next, probe_accept, "),
    (STEPPING, "\ncontains\n",
     "\n    integer(8) :: probe_evals(0:9, 0:1, 0:3) = 0\n    integer :: probe_kind = 3\ncontains\n"),
    (STEPPING, "            r%stats%ray_evals = r%stats%ray_evals + r%ray%evals\n",
     "            r%stats%ray_evals = r%stats%ray_evals + r%ray%evals\n"
     "            probe_evals(min(r%ray%evals, 9), merge(1, 0, res%evaluated), probe_kind) = &\n"
     "                probe_evals(min(r%ray%evals, 9), merge(1, 0, res%evaluated), probe_kind) + 1\n"
     "            probe_kind = 3\n"),
    (STEPPING, "            select case (outcome)\n            case (jump_climb)\n",
     "            probe_kind = outcome + 1\n            select case (outcome)\n            case (jump_climb)\n"),
    (STEPPING, "            stats = r%stats\n        end associate\n    end subroutine run_energy_stepping\n",
     "            stats = r%stats\n        end associate\n        call probe_write()\n"
     "    contains\n        subroutine probe_write()\n            integer :: u, i, j, k\n"
     "            character(len=256) :: path\n"
     "            call get_environment_variable('ES_PROBE_OUT', path)\n"
     "            if (len_trim(path) == 0) return\n"
     "            open (newunit=u, file=trim(path), status='replace', action='write')\n"
     "            write (u, '(a,es12.4)') 'accept ', probe_accept\n"
     "            do k = 0, 3; do j = 0, 1; do i = 0, 9\n"
     "                if (probe_evals(i, j, k) > 0) write (u, '(a,3i4,i12)') 'evals ', i, j, k, probe_evals(i, j, k)\n"
     "            end do; end do; end do\n"
     "            do j = 0, 1; do i = -20, 2\n"
     "                if (probe_first(i, j) > 0) write (u, '(a,2i4,i12)') 'first ', i, j, probe_first(i, j)\n"
     "            end do; end do\n"
     "            do j = -20, 10; do i = -20, 10\n"
     "                if (probe_next(i, j) > 0) write (u, '(a,2i4,i12)') 'next ', i, j, probe_next(i, j)\n"
     "            end do; end do\n"
     "            close (u)\n        end subroutine probe_write\n    end subroutine run_energy_stepping\n"),
    (STEPPING, "        real(dp) :: window\n        associate (st => r%st)\n",
     "        real(dp) :: window\n        character(len=32) :: acc\n        integer :: la\n"
     "        call get_environment_variable('ES_PROBE_ACCEPT', acc, la)\n"
     "        if (la > 0) read (acc, *) probe_accept\n        associate (st => r%st)\n"),
]


def patch(src):
    for rel, old, new in EDITS:
        path = src + '/' + rel
        text = open(path).read()
        if text.count(old) != 1:
            sys.exit('search_probe: %s: the text to patch occurs %d times (the code changed: update EDITS)\n  %r'
                     % (rel, text.count(old), old[:80]))
        open(path, 'w').write(text.replace(old, new))


def report(path):
    evals, first, nxt = {}, {}, {}
    for line in open(path):
        w = line.split()
        if w[0] == 'accept':
            print('unevaluated roots accepted below %g of the tolerance' % float(w[1]))
        elif w[0] == 'evals':
            evals[tuple(map(int, w[1:4]))] = int(w[4])
        elif w[0] == 'first':
            first[tuple(map(int, w[1:3]))] = int(w[3])
        elif w[0] == 'next':
            nxt[tuple(map(int, w[1:3]))] = int(w[3])
    kinds = ['after a fall', 'after a reflection', 'after a climb', 'none (start, window end, miss)']
    total = sum(evals.values())
    print('\n1. ray evaluations per search (%d searches, %.3f evaluations per search)'
          % (total, sum(k[0]*v for k, v in evals.items())/max(total, 1)))
    print('%-32s %-12s' % ('last kick', 'root') + ''.join('%9s' % (str(n) if n < 9 else '9+') for n in range(10)))
    for k in range(4):
        for e in (0, 1):
            row = [evals.get((n, e, k), 0) for n in range(10)]
            if sum(row):
                print('%-32s %-12s' % (kinds[k], 'evaluated' if e else 'unevaluated') + ''.join('%9d' % c for c in row))
    print('\n2. first evaluation: |f(s1) - nearer level| / (upper - lower), searches per decade')
    print('%-10s %14s %14s' % ('decade', 'c0 measured', 'c0 guessed'))
    for d in range(-20, 3):
        a, b = first.get((d, 0), 0), first.get((d, 1), 0)
        if a or b:
            print('%-10s %14d %14d' % ('1e%d' % d, a, b))
    print('\n3. the next Taylor root: predicted error (rows) against the error found at it (columns), '
          'in units of the tolerance, by decade')
    cols = sorted({j for _, j in nxt})
    print('%-8s' % 'pred' + ''.join('%9s' % ('1e%d' % j) for j in cols) + '   within 10x')
    for i in sorted({i for i, _ in nxt}):
        row = [nxt.get((i, j), 0) for j in cols]
        near = sum(nxt.get((i, j), 0) for j in (i - 1, i, i + 1))
        print('%-8s' % ('1e%d' % i) + ''.join('%9d' % c for c in row) + '   %.3f' % (near/max(sum(row), 1)))


if __name__ == '__main__':
    if len(sys.argv) != 3 or sys.argv[1] not in ('patch', 'report'):
        sys.exit(__doc__)
    (patch if sys.argv[1] == 'patch' else report)(sys.argv[2])
