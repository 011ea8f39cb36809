#!/usr/bin/env python3
"""The 864-atom argon slice of scripts/bench/anchors.sh (PARTS=argon) for GROMACS and LAMMPS.

Reads Terrace's atoms file (the liquid that input/argon_nvt.nml leaves, argon_nvt_eq.atoms: metal
units, A and A/ps, a cubic box from 0 to L) and writes into the current directory the same state
and physics as input/argon_nvt_100ns.nml for the two other codes:
  argon.gro, argon.top, argon.mdp  GROMACS: LJ eps 0.0103408116 eV, sigma 0.34 nm, rc 0.85 nm with
                                   the potential shifted at rc, leap-frog at 10 fs, v-rescale (the
                                   CSVR thermostat) at T K with tau_t TAU ps, the Verlet buffer at
                                   GROMACS's default tolerance (0.005 kJ/mol/ps per atom, nstlist 10
                                   before mdrun's own increase), energies to the log and edr every
                                   EVERY steps, positions and velocities to the trr every EVERY steps;
  argon.data, argon.in             LAMMPS: the same state (velocities included), lj/cut 8.5 A with
                                   pair_modify shift yes, skin 1 A checked every step, velocity
                                   Verlet with fix temp/berendsen (this LAMMPS has no temp/csvr) at T
                                   with damping TAU ps, thermo and a dump of x and v every EVERY
                                   steps, a restart file at the end.
Positions and velocities go to the .gro at ten decimals (GROMACS reads the precision from the
column spacing), so all three codes start from the same state to 1e-10 nm.

usage: argon_anchors.py ATOMS_FILE BOX_A NSTEPS EVERY TEMPERATURE TAU
"""
import sys

atoms_file, box, nsteps, every, temp, tau = (sys.argv[1], float(sys.argv[2]), int(sys.argv[3]),
                                             int(sys.argv[4]), float(sys.argv[5]), float(sys.argv[6]))
eps_ev, sigma_a, rc_a, mass, dt = 0.0103408116, 3.4, 8.5, 39.948, 0.01
ev_kjmol = 96.48533212331                                  # kJ/mol per eV
rows = [l.split() for l in open(atoms_file) if l.strip() and not l.startswith('#')]
x = [[float(v) for v in r[1:4]] for r in rows]
v = [[float(u) for u in r[4:7]] for r in rows]
n = len(rows)

with open('argon.gro', 'w') as g:
    g.write('liquid argon, 864 atoms, from %s\n%d\n' % (atoms_file, n))
    for k in range(n):
        xs = ''.join('%15.10f' % ((c % box) / 10.0) for c in x[k])
        vs = ''.join('%15.10f' % (c / 10.0) for c in v[k])
        g.write('%5d%-5s%5s%5d%s%s\n' % ((k + 1) % 100000, 'AR', 'AR', (k + 1) % 100000, xs, vs))
    g.write('%15.10f%15.10f%15.10f\n' % (box / 10.0, box / 10.0, box / 10.0))
with open('argon.top', 'w') as t:
    t.write('[ defaults ]\n; nbfunc comb-rule gen-pairs\n1 2 no\n\n[ atomtypes ]\n'
            '; name mass charge ptype sigma epsilon\nAR %.3f 0.0 A %.6f %.10f\n\n'
            '[ moleculetype ]\nAR 1\n\n[ atoms ]\n1 AR 1 AR AR 1 0.0 %.3f\n\n'
            '[ system ]\nliquid argon\n\n[ molecules ]\nAR %d\n'
            % (mass, sigma_a / 10.0, eps_ev * ev_kjmol, mass, n))
mdp = {'integrator': 'md', 'dt': dt, 'nsteps': nsteps, 'cutoff-scheme': 'Verlet', 'nstlist': 10,
       'verlet-buffer-tolerance': 0.005, 'pbc': 'xyz', 'coulombtype': 'Cut-off', 'rcoulomb': rc_a / 10.0,
       'vdwtype': 'Cut-off', 'vdw-modifier': 'Potential-shift', 'rvdw': rc_a / 10.0, 'DispCorr': 'no',
       'tcoupl': 'v-rescale', 'tc-grps': 'System', 'tau-t': tau, 'ref-t': temp, 'pcoupl': 'no',
       'comm-mode': 'None', 'constraints': 'none', 'gen-vel': 'no', 'continuation': 'yes',
       'nstcalcenergy': 100, 'nstenergy': every, 'nstlog': every, 'nstxout': every, 'nstvout': every,
       'nstfout': 0, 'nstxout-compressed': 0}
with open('argon.mdp', 'w') as m:
    for k, val in mdp.items():
        m.write('%-24s = %s\n' % (k, val))

with open('argon.data', 'w') as d:
    d.write('liquid argon from %s\n\n%d atoms\n1 atom types\n\n' % (atoms_file, n))
    d.write('0.0 %.10f xlo xhi\n0.0 %.10f ylo yhi\n0.0 %.10f zlo zhi\n\nMasses\n\n1 %.3f\n\nAtoms # atomic\n\n'
            % (box, box, box, mass))
    for k in range(n):
        d.write('%d 1 %.16e %.16e %.16e\n' % (k + 1, *[c % box for c in x[k]]))
    d.write('\nVelocities\n\n')
    for k in range(n):
        d.write('%d %.16e %.16e %.16e\n' % (k + 1, *v[k]))
with open('argon.in', 'w') as f:
    f.write('units metal\natom_style atomic\nread_data argon.data\n'
            'pair_style lj/cut %.1f\npair_coeff 1 1 %.10f %.1f\npair_modify shift yes\n'
            'neighbor 1.0 bin\nneigh_modify every 1 delay 0 check yes\n'
            'fix 1 all nve\nfix 2 all temp/berendsen %.1f %.1f %.1f\ntimestep %.2f\n'
            'thermo %d\ndump 1 all custom %d argon.lammpstrj id x y z vx vy vz\n'
            'run %d\nwrite_restart argon.restart\n'
            % (rc_a, eps_ev, sigma_a, temp, temp, tau, dt, every, every, nsteps))
