#!/usr/bin/env python3
"""Cost of the neo-Hookean element kernel on the talk's cube against a brute estimate.

Scene: the talk's 8 x 8 x 8-cell cube (scripts/make_cube_mesh.py: 2,969 nodes, 12,288 tetrahedra),
the decks input/cube_spin_verlet.nml (dt 2.5e-5 s) and input/cube_spin_es.nml (h = 1e-3 J), one rank.

Measured, each run repeated --repeat times (median):
  * one velocity-Verlet step and one energy-stepping event in microseconds, two ways:
      wall: from the run summary (loop time over the steps/events; "Pair" = force passes, "Search" =
            ray passes), the difference of a long and a short run so that the start-up cancels;
      cpu:  the process's CPU time (user + system, wait4), long minus short run: on a shared, loaded machine
            the wall clock counts the time the process waited for a core, the CPU time does not;
    (the fastest repeat's CPU time is printed too: on a loaded machine it varies less);
  * with --callgrind (valgrind): instructions per element in one force pass and in one ray pass
    (inclusive Ir of nh_forces / nh_ray over their calls, repeatable on a loaded machine).
Brute estimate of the element arithmetic: floating-point operations counted by hand per element
(FORCE_FLOPS, RAY_FLOPS below; an FMA counts 2; divisions and logarithms apart), timed with this
machine's attainable rates from a tiny calibration program (same compiler and flags as the build:
a vectorised and a scalar chain of 8 multiply-adds per element of an L1-resident array, a loop
of divisions and one of logarithms; the best of 5 CPU-timed trials). Estimate per step =
nelem (flops / vector rate + divisions x division time + logs x log time); per event the same with
the log's force passes and ray evaluations per event. Printed: measured / estimate.

Usage:  PYTHONPATH=scripts /usr/bin/python3 scripts/bench/mesh_cost.py [--terrace build/terrace] [--repeat 3]
        [--steps 200] [--events 100] [--callgrind] [--label TEXT]
Run time on the 2-vCPU AMD EPYC (shared): ~1-2 min, plus ~1-2 min with --callgrind.
"""
import argparse
import os
import platform
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

from terrace_tools import summary

REPO = os.path.abspath(os.path.join(os.path.dirname(os.path.abspath(__file__)), '..', '..'))

# Floating-point operations per element (add, sub, mul; an FMA = 2), from src/potentials/neohookean.f90.
FORCE_FLOPS = {
    'edge vectors Ds (gather)': 9,
    'F = Ds Dm^-1': 45,
    'cofactors of F': 27,
    'J = det F': 5,
    '(lambda ln J - mu) / J': 3,
    'P = mu F + w cof F': 27,
    'H = -V0 P Dm^-T': 54,
    'node 1 = -(sum of 3)': 6,
    '|F|^2': 17,
    'energy W V0': 12,
    'virial': 7,
    'scatter (12 adds)': 12,
}
FORCE_DIV, FORCE_LOG = 1, 1
RAY_FLOPS = {
    'edge vectors Ds, Dv (gather)': 18,
    'F0, G': 90,
    'cofactors of F0': 27,
    'J0': 5,
    'A = adj(F0) G / J0': 54,
    'c1, c2, c3': 30,
    'p, p\', p\'\'': 14,
    'ln J, L\', L\'\'': 4,
    '|F0|^2, F0:G, |G|^2': 51,
    'tr F^T F (s)': 5,
    'W, W\', W\'\'': 22,
    'weights and virial': 10,
}
RAY_DIV, RAY_LOG = 3, 2

CALIB = r"""
program calib
    implicit none
    integer, parameter :: dp = kind(1.0d0), n = 512
    real(dp) :: x(n), y(n), a, b, t0, t1, best(4), s
    integer :: i, r, trial, nrep
    a = 0.999999_dp; b = 1.0e-7_dp
    do i = 1, n
        x(i) = 1 + i*1.0e-3_dp
    end do
    best = huge(1.0_dp)
    s = 0
    nrep = 20000
    do trial = 1, 5
        y = x
        call cpu_time(t0)
        do r = 1, nrep
            call chain_vec(y, a, b)
        end do
        call cpu_time(t1)
        s = s + sum(y)
        best(1) = min(best(1), t1 - t0)
        y = x
        call cpu_time(t0)
        do r = 1, nrep
            call chain_scalar(y, a, b)
        end do
        call cpu_time(t1)
        s = s + sum(y)
        best(2) = min(best(2), t1 - t0)
        call cpu_time(t0)
        do r = 1, nrep/4
            call divs(x, y)
        end do
        call cpu_time(t1)
        s = s + sum(y)
        best(3) = min(best(3), t1 - t0)
        call cpu_time(t0)
        do r = 1, nrep/8
            call logs(x, y)
            s = s + y(mod(r - 1, n) + 1)
        end do
        call cpu_time(t1)
        best(4) = min(best(4), t1 - t0)
    end do
    ! flop/s of 8 FMAs (16 flops) per element; seconds per division and per logarithm
    print '(a,4es14.6,es12.3)', 'CALIB', 16.0_dp*n*nrep/best(1), 16.0_dp*n*nrep/best(2), &
        best(3)/(real(n, dp)*(nrep/4)), best(4)/(real(n, dp)*(nrep/8)), s + sum(y)
contains
    subroutine chain_vec(y, a, b)
        real(dp), intent(inout) :: y(n)
        real(dp), intent(in) :: a, b
        integer :: i
        do i = 1, n
            y(i) = ((((((((y(i)*a + b)*a + b)*a + b)*a + b)*a + b)*a + b)*a + b)*a + b)
        end do
    end subroutine chain_vec
    subroutine chain_scalar(y, a, b)
        real(dp), intent(inout) :: y(n)
        real(dp), intent(in) :: a, b
        integer :: i
        !GCC$ novector
        do i = 1, n
            y(i) = ((((((((y(i)*a + b)*a + b)*a + b)*a + b)*a + b)*a + b)*a + b)*a + b)
        end do
    end subroutine chain_scalar
    subroutine divs(x, y)
        real(dp), intent(in) :: x(n)
        real(dp), intent(inout) :: y(n)
        integer :: i
        do i = 1, n
            y(i) = 1/(y(i) + x(i))
        end do
    end subroutine divs
    subroutine logs(x, y)
        real(dp), intent(in) :: x(n)
        real(dp), intent(inout) :: y(n)
        integer :: i
        do i = 1, n
            y(i) = log(y(i) + x(i))
        end do
    end subroutine logs
end program calib
"""


def run_cpu(cmd, cwd):
    """Run cmd; return (log text, user + system CPU seconds of the child, from wait4)."""
    with open(os.path.join(cwd, 'run.log'), 'w') as f:
        p = subprocess.Popen(cmd, cwd=cwd, stdout=f, stderr=subprocess.STDOUT)
        _, status, ru = os.wait4(p.pid, 0)
        p.returncode = os.waitstatus_to_exitcode(status)
    text = open(os.path.join(cwd, 'run.log')).read()
    if p.returncode != 0:
        sys.exit(f'mesh_cost: {" ".join(cmd)} failed (exit {p.returncode}):\n{text[-2000:]}')
    return text, ru.ru_utime + ru.ru_stime


def log_values(path):
    """Loop time, the Pair and Search phases and energy stepping's rays and force passes per event,
    from a run summary."""
    f = summary.run_figures(path)
    v = {'loop': f['loop'], 'pair': f['pair'], 'search': f['search']}
    if f.get('evals') is not None:
        v['rays'], v['passes'] = f['evals'], f['passes']
    return v


def deck(src, dst, count, sample):
    text = open(os.path.join(REPO, 'input', src)).read()
    text = text.replace('run_time=0.1', f'n_steps={count}')
    text = re.sub(r'thermo_interval=[0-9.e-]+', f'thermo_every={sample}', text)
    open(dst, 'w').write(text)


def callgrind_ir(terrace, nml, work, name):
    """Inclusive instructions of neohookean's procedure `name` and its number of calls, under callgrind."""
    out = os.path.join(work, 'cg.out')
    subprocess.run(['valgrind', '--tool=callgrind', f'--callgrind-out-file={out}', terrace, nml], cwd=work,
                   capture_output=True, text=True, check=True)
    ann = subprocess.run(['callgrind_annotate', '--inclusive=yes', out], capture_output=True, text=True,
                         check=True).stdout
    ir = 0
    for line in ann.splitlines():
        if re.search(rf'neohookean_MOD_{name}\b', line):
            ir = int(line.split()[0].replace(',', ''))
            break
    # calls: "cfn=(id) symbol" (the symbol only at its first use), then "calls=N ..."
    ids, calls, target = {}, 0, False
    for line in open(out):
        m = re.match(r'(c?fn)=\((\d+)\)\s*(\S*)', line)
        if m:
            if m.group(3):
                ids[m.group(2)] = m.group(3)
            target = m.group(1) == 'cfn' and ids.get(m.group(2), '').endswith(f'neohookean_MOD_{name}')
            continue
        if target and line.startswith('calls='):
            calls += int(line.split('=')[1].split()[0])
            target = False
    return ir, calls


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument('--terrace', default=os.path.join(REPO, 'build', 'terrace'))
    ap.add_argument('--repeat', type=int, default=3)
    ap.add_argument('--steps', type=int, default=200)
    ap.add_argument('--events', type=int, default=100)
    ap.add_argument('--callgrind', action='store_true')
    ap.add_argument('--label', default='')
    a = ap.parse_args()
    work = tempfile.mkdtemp(prefix='mesh_cost_')
    terrace = os.path.join(work, 'terrace')
    shutil.copy(os.path.abspath(a.terrace), terrace)
    subprocess.run([sys.executable, os.path.join(REPO, 'scripts', 'make_cube_mesh.py'), os.path.join(work, 'cube.msh'),
                    '--size', '0.1', '--center'], check=True, stdout=subprocess.DEVNULL)
    nelem = 12288
    cpu = 'unknown'
    if os.path.exists('/proc/cpuinfo'):
        m = re.search(r'model name\s*:\s*(.*)', open('/proc/cpuinfo').read())
        cpu = m.group(1) if m else cpu
    print(f'mesh_cost: the talk\'s cube, {nelem} tetrahedra, 1 rank; {a.label}')
    print(f'machine: {cpu}, {os.cpu_count()} vCPU (shared), {platform.system()} {platform.machine()}; '
          f'date {time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}')
    print(f'binary: {os.path.abspath(a.terrace)}')

    # calibration (same compiler flags as the Release build)
    src = os.path.join(work, 'calib.f90')
    open(src, 'w').write(CALIB)
    subprocess.run(['gfortran', '-O3', '-march=native', '-funroll-loops', src, '-o', os.path.join(work, 'calib')],
                   check=True)
    out = subprocess.run([os.path.join(work, 'calib')], capture_output=True, text=True, check=True).stdout
    f = out.split()
    vec, sca, tdiv, tlog = float(f[1]), float(f[2]), float(f[3]), float(f[4])
    print(f'calibration: vector multiply-add {vec / 1e9:.2f} Gflop/s, scalar {sca / 1e9:.2f} Gflop/s, '
          f'division {tdiv * 1e9:.2f} ns, logarithm {tlog * 1e9:.2f} ns (best of 5, CPU time)')
    ff, rf = sum(FORCE_FLOPS.values()), sum(RAY_FLOPS.values())
    t_force = nelem * (ff / vec + FORCE_DIV * tdiv + FORCE_LOG * tlog)
    t_ray = nelem * (rf / vec + RAY_DIV * tdiv + RAY_LOG * tlog)
    print(f'brute count per element: force pass {ff} flops + {FORCE_DIV} div + {FORCE_LOG} log; '
          f'ray pass {rf} flops + {RAY_DIV} div + {RAY_LOG} log')
    print(f'brute estimate: force pass {t_force * 1e6:.1f} us, ray pass {t_ray * 1e6:.1f} us '
          f'(12,288 elements at the vector rate)')

    results = {}
    for kind, src_deck, count in (('verlet', 'cube_spin_verlet.nml', a.steps), ('es', 'cube_spin_es.nml', a.events)):
        short = max(1, count // 10)
        deck(src_deck, os.path.join(work, f'{kind}_long.nml'), count, count)
        deck(src_deck, os.path.join(work, f'{kind}_short.nml'), short, short)
        per_wall, per_cpu, pair, search, rays, passes = [], [], [], [], [], []
        for _ in range(a.repeat):
            tl, cl = run_cpu([terrace, f'{kind}_long.nml'], work)
            ts, cs = run_cpu([terrace, f'{kind}_short.nml'], work)
            vl = log_values(os.path.join(work, f'{kind}_long.summary.json'))
            vs = log_values(os.path.join(work, f'{kind}_short.summary.json'))
            per_wall.append((vl['loop'] - vs['loop']) / (count - short))
            per_cpu.append((cl - cs) / (count - short))
            pair.append((vl['pair'] - vs['pair']) / (count - short))
            search.append((vl['search'] - vs['search']) / (count - short))
            if 'rays' in vl:
                rays.append(vl['rays']); passes.append(vl['passes'])
        results[kind] = dict(wall=statistics.median(per_wall), cpu=statistics.median(per_cpu), cpu_min=min(per_cpu),
                             pair=statistics.median(pair), search=statistics.median(search),
                             rays=statistics.median(rays) if rays else 0, passes=statistics.median(passes) if passes else 1)
    v, e = results['verlet'], results['es']
    est_v = t_force
    est_e = e['passes'] * t_force + e['rays'] * t_ray
    print(f'velocity Verlet, one step ({a.steps} - {a.steps // 10} steps, median of {a.repeat}):')
    print(f'  wall {v["wall"] * 1e6:9.1f} us (force pass "Pair" {v["pair"] * 1e6:.1f} us); cpu {v["cpu"] * 1e6:9.1f} us (fastest {v["cpu_min"] * 1e6:.1f}); '
          f'estimate {est_v * 1e6:.1f} us; ratio cpu/estimate {v["cpu"] / est_v:.2f}, wall/estimate {v["wall"] / est_v:.2f}')
    print(f'energy stepping, one event ({a.events} - {a.events // 10} events, median of {a.repeat}; '
          f'{e["passes"]:.3f} force passes + {e["rays"]:.3f} ray passes per event):')
    print(f'  wall {e["wall"] * 1e6:9.1f} us (force "Pair" {e["pair"] * 1e6:.1f} us, ray "Search" {e["search"] * 1e6:.1f} us); '
          f'cpu {e["cpu"] * 1e6:9.1f} us (fastest {e["cpu_min"] * 1e6:.1f}); estimate {est_e * 1e6:.1f} us; ratio cpu/estimate {e["cpu"] / est_e:.2f}, '
          f'wall/estimate {e["wall"] / est_e:.2f}')
    print(f'  event / Verlet step: cpu {e["cpu"] / v["cpu"]:.2f}, wall {e["wall"] / v["wall"]:.2f}')

    if a.callgrind:
        if not shutil.which('valgrind') or not shutil.which('callgrind_annotate'):
            print('callgrind: SKIPPED (valgrind not installed)')
            return
        n = 10
        deck('cube_spin_verlet.nml', os.path.join(work, 'cg_v.nml'), n, n)
        deck('cube_spin_es.nml', os.path.join(work, 'cg_e.nml'), n, n)
        irf, nf = callgrind_ir(terrace, 'cg_v.nml', work, 'nh_forces')
        irr, nr = callgrind_ir(terrace, 'cg_e.nml', work, 'nh_ray')
        ir_f = irf / max(nf, 1) / nelem
        ir_r = irr / max(nr, 1) / nelem
        print(f'callgrind (instructions, repeatable): force pass {ir_f:.0f} Ir per element over {nf} passes '
              f'({ir_f / (ff + FORCE_DIV + FORCE_LOG):.2f} per counted operation); ray pass {ir_r:.0f} Ir per '
              f'element over {nr} passes ({ir_r / (rf + RAY_DIV + RAY_LOG):.2f} per counted operation)')
    shutil.rmtree(work, ignore_errors=True)


if __name__ == '__main__':
    main()
