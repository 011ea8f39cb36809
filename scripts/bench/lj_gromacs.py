#!/usr/bin/env python3
"""The anchors' LJ scene for GROMACS (scripts/bench/anchors.sh, verlet_buffer.sh): LAMMPS's bench
lattice (fcc, 4-atom basis, 20^3 cells at rho* 0.8442) in argon units (sigma 0.3405 nm, eps/k_B
119.8 K, m 39.948 u), written into the current directory as lj.gro and lj.top, with lj.mdp (rc 2.5
sigma, rlist 2.8 sigma fixed, nstlist 20, dt 0.005 tau, velocities at T* 1.44) and lj_tol.mdp (the
same with GROMACS's default verlet-buffer-tolerance, 0.005 kJ/mol/ps, in place of the fixed rlist).

usage: lj_gromacs.py NSTEPS
"""
import sys
nsteps = int(sys.argv[1])
sigma, eps_k, mass, kb = 0.3405, 119.8, 39.948, 0.00831446261815324   # nm, K, u, kJ/mol/K
eps = eps_k * kb
a = sigma * (4.0 / 0.8442) ** (1.0 / 3.0)
n = 20
tau = sigma * (mass / eps) ** 0.5                       # ps
basis = [(0, 0, 0), (0.5, 0.5, 0), (0.5, 0, 0.5), (0, 0.5, 0.5)]
with open('lj.gro', 'w') as g:
    g.write('fcc LJ, rho* 0.8442, 20^3 cells (argon units)\n%d\n' % (4 * n ** 3))
    k = 0
    for i in range(n):
        for j in range(n):
            for l in range(n):
                for b in basis:
                    k += 1
                    g.write('%5d%-5s%5s%5d%8.3f%8.3f%8.3f\n' % (k % 100000, 'AR', 'AR', k % 100000,
                            (i + b[0]) * a, (j + b[1]) * a, (l + b[2]) * a))
    g.write('%10.5f%10.5f%10.5f\n' % (n * a, n * a, n * a))
with open('lj.top', 'w') as t:
    t.write('[ defaults ]\n; nbfunc comb-rule gen-pairs\n1 2 no\n\n[ atomtypes ]\n'
            '; name mass charge ptype sigma epsilon\nAR %.3f 0.0 A %.6f %.8f\n\n'
            '[ moleculetype ]\nAR 1\n\n[ atoms ]\n1 AR 1 AR AR 1 0.0 %.3f\n\n'
            '[ system ]\nLJ bench\n\n[ molecules ]\nAR %d\n' % (mass, sigma, eps, mass, 4 * n ** 3))
rc, rl = 2.5 * sigma, 2.8 * sigma
mdp = dict(integrator='md', dt='%.7f' % (0.005 * tau), nsteps=nsteps, **{
    'cutoff-scheme': 'Verlet', 'nstlist': 20, 'verlet-buffer-tolerance': -1, 'rlist': '%.6f' % rl,
    'pbc': 'xyz', 'coulombtype': 'Cut-off', 'rcoulomb': '%.6f' % rc, 'vdwtype': 'Cut-off',
    'vdw-modifier': 'Potential-shift', 'rvdw': '%.6f' % rc, 'DispCorr': 'no', 'tcoupl': 'no',
    'pcoupl': 'no', 'comm-mode': 'None', 'constraints': 'none', 'gen-vel': 'yes',
    'gen-temp': '%.3f' % (1.44 * eps_k), 'gen-seed': 87287, 'nstcalcenergy': 100, 'nstenergy': 100,
    'nstlog': 100, 'nstxout': 0, 'nstvout': 0, 'nstfout': 0, 'nstxout-compressed': 0})
with open('lj.mdp', 'w') as m:
    for k, v in mdp.items():
        m.write('%-24s = %s\n' % (k, v))
mdp['verlet-buffer-tolerance'] = 0.005        # GROMACS's default: its own buffer for nstlist 20
del mdp['rlist']
with open('lj_tol.mdp', 'w') as m:
    for k, v in mdp.items():
        m.write('%-24s = %s\n' % (k, v))
