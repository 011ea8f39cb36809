"""The five scenes of the study, with their quick and full parameters, and the decks and LAMMPS
inputs that start every method from the same state (positions and velocities in id order).

Every scene starts from a prepared state `start.atoms` in its work dir; LAMMPS reads the same state
from `start.data`. The potential is the same in all codes and for both integrators: energy
stepping needs a continuous potential, so the periodic LJ scenes use the energy-shifted LJ
(Terrace shift=.true., LAMMPS pair_modify shift yes) for every method.
"""
import os
import shutil

import numpy as np

from .common import REPO, KB_METAL, run_terrace, read_atoms_file, write_lammps_data

CU_EAM = '/usr/share/lammps/potentials/Cu_u3.eam'


class Scene:
    def __init__(self, key, title, units, dim, periodic, pot, skin, mass, quick, full, observables,
                 es_note=''):
        self.key, self.title, self.units, self.dim = key, title, units, dim
        self.periodic, self.pot, self.skin, self.mass = periodic, pot, skin, mass
        self.params = {'quick': quick, 'full': full}
        self.observables = observables
        self.es_note = es_note
        self.natoms = 0
        self.lo = self.hi = None

    # units ---------------------------------------------------------------------------------
    @property
    def tunit(self):
        return 'ps' if self.units == 'metal' else 'tau'

    @property
    def eunit(self):
        return 'eV' if self.units == 'metal' else 'eps'

    @property
    def lunit(self):
        return 'A' if self.units == 'metal' else 'sigma'

    def h_label(self, h):
        if self.units == 'metal':
            return '%.3g eV (%.3g K)' % (h, h / KB_METAL)
        return '%.3g eps' % h

    # start state ---------------------------------------------------------------------------
    def prepare(self, terrace, work, mode):
        """Make start.atoms (and start.data for LAMMPS) in WORK. Returns the preparation run (or None)."""
        p = self.params[mode]
        prep = None
        if self.key == 'cluster7':
            shutil.copy(os.path.join(REPO, 'input', 'argon_frozen_2d.atoms'), os.path.join(work, 'start.atoms'))
        elif self.key == 'ico147':
            shutil.copy(os.path.join(REPO, 'input', 'argon_ico147.atoms'), work)
            deck = ("&run units='metal', dimension=3, run_time=%r, seed=147 /\n"
                    "&system atoms_file='argon_ico147.atoms', periodic=.false.,.false.,.false., mass=39.951, "
                    "temperature=40.0 /\n%s\n&integrator style='velocity_verlet', dt=0.002 /\n"
                    "&neighbor skin=1.0 /\n&output thermo_interval=1.0, thermo_file='', "
                    "final_atoms_file='start.atoms' /\n" % (p['prep_time'], self.terrace_potential()))
            prep = run_terrace(terrace, work, 'prep', deck)
        elif self.key == 'rahman':
            deck = open(os.path.join(REPO, 'input', 'argon_liquid.nml')).read()
            deck = deck.replace("thermo_file='argon_liquid.csv'", "thermo_file=''")
            deck = deck.replace("final_atoms_file='argon_liquid_eq.atoms'", "final_atoms_file='start.atoms'")
            prep = run_terrace(terrace, work, 'prep', deck)
        elif self.key == 'ljbench':
            n = p['cells']
            deck = ("&run units='lj', dimension=3, n_steps=500, seed=87287 /\n"
                    "&system lattice='fcc', density=0.8442, cells=%d,%d,%d, periodic=.true.,.true.,.true., "
                    "mass=1.0, temperature=1.44 /\n%s\n&integrator style='velocity_verlet', dt=0.005 /\n"
                    "&neighbor skin=0.3 /\n&output thermo_every=100, thermo_file='', final_atoms_file='start.atoms' /\n"
                    % (n, n, n, self.terrace_potential()))
            prep = run_terrace(terrace, work, 'prep', deck)
        elif self.key == 'cu_eam':
            n = p['cells']
            deck = ("&run units='metal', dimension=3, run_time=%r, seed=2021 /\n"
                    "&system lattice='fcc', lattice_constant=3.615, cells=%d,%d,%d, periodic=.true.,.true.,.true., "
                    "temperature=600.0 /\n%s\n&integrator style='velocity_verlet', dt=0.002 /\n"
                    "&neighbor skin=1.0 /\n&output thermo_interval=0.1, thermo_file='', final_atoms_file='start.atoms' /\n"
                    % (p['prep_time'], n, n, n, self.terrace_potential()))
            prep = run_terrace(terrace, work, 'prep', deck)
        if prep is not None and prep['rc'] != 0:
            raise RuntimeError('%s: preparation run failed: %s' % (self.key, prep['error']))
        types, x, v = read_atoms_file(os.path.join(work, 'start.atoms'))
        self.natoms = len(types)
        self.types = types
        if self.key == 'rahman':
            self.lo, self.hi = np.zeros(3), np.full(3, 34.6809019)
        elif self.key == 'ljbench':
            L = p['cells'] * (4.0 / 0.8442) ** (1.0 / 3.0)
            self.lo, self.hi = np.zeros(3), np.full(3, L)
        elif self.key == 'cu_eam':
            self.lo, self.hi = np.zeros(3), np.full(3, p['cells'] * 3.615)
        else:   # free: a box around the atoms for LAMMPS's shrink-wrapped boundaries
            self.lo = x.min(0) - 5.0
            self.hi = x.max(0) + 5.0
            if self.dim == 2:
                self.lo[2], self.hi[2] = -0.5, 0.5
        masses = [self.mass if self.mass else 63.55]
        write_lammps_data(os.path.join(work, 'start.data'), types, x, v, self.lo, self.hi, masses, self.dim)
        return prep

    # Terrace -------------------------------------------------------------------------------
    def terrace_potential(self):
        p = self.pot
        if p['style'] == 'eam':
            return "&potential style='eam', file='%s' /" % p['file']
        return ("&potential style='lj', epsilon=%r, sigma=%r, cutoff=%r, shift=%s /"
                % (p['eps'], p['sigma'], p['cutoff'], '.true.' if p['shift'] else '.false.'))

    def terrace_deck(self, name, integrator, t_end, thermo_int, traj_int, final=False):
        per = ','.join('.true.' if self.periodic else '.false.' for _ in range(self.dim))
        box = ''
        if self.periodic:
            box = 'box_lo=%s, box_hi=%s, ' % (','.join('%r' % float(v) for v in self.lo),
                                             ','.join('%r' % float(v) for v in self.hi))
        mass = ', mass=%r' % self.mass if self.mass else ''
        out = "thermo_interval=%r, thermo_file='%s.csv'" % (thermo_int, name)
        if traj_int:
            out += ", trajectory_file='%s.h5', trajectory_interval=%r, overwrite=.true." % (name, traj_int)
        if final:
            out += ", final_atoms_file='%s.final'" % name
        return ("&run units='%s', dimension=%d, run_time=%r, seed=1 /\n"
                "&system atoms_file='start.atoms', %speriodic=%s%s /\n%s\n%s\n&neighbor skin=%r /\n&output %s /\n"
                % (self.units, self.dim, t_end, box, per, mass, self.terrace_potential(), integrator, self.skin, out))

    @staticmethod
    def verlet(dt):
        return "&integrator style='velocity_verlet', dt=%r /" % dt

    @staticmethod
    def stepping(h):
        return "&integrator style='energy_stepping', terrace_height=%.10g /" % h

    # LAMMPS --------------------------------------------------------------------------------
    def lammps_input(self, name, dt, t_end, thermo_int, traj_int):
        nsteps = int(round(t_end / dt))
        nth = max(1, int(round(thermo_int / dt)))
        ndump = max(1, int(round(traj_int / dt))) if traj_int else 0
        if self.periodic:
            bnd = 'p p p'
        else:
            bnd = 's s p' if self.dim == 2 else 's s s'
        p = self.pot
        if p['style'] == 'eam':
            pair = 'pair_style eam\npair_coeff * * %s\n' % p['file']
        else:
            rc = p['cutoff'] if p['cutoff'] > 0 else 100.0
            pair = ('pair_style lj/cut %r\npair_coeff 1 1 %r %r\npair_modify shift %s\n'
                    % (rc, p['eps'], p['sigma'], 'yes' if p['shift'] else 'no'))
        lines = ['units %s' % self.units, 'dimension %d' % self.dim, 'boundary %s' % bnd,
                 'atom_style atomic', 'atom_modify map array', 'read_data start.data', pair.strip(),
                 'neighbor %r %s' % (self.skin, 'nsq' if p.get('cutoff', 1) == 0 else 'bin'), 'neigh_modify delay 0 every 1 check yes',
                 'fix 1 all nve']
        if self.dim == 2:
            lines.append('fix 2 all enforce2d')
        lines += ['timestep %r' % dt,
                  'variable px equal mass(all)*vcm(all,x)', 'variable py equal mass(all)*vcm(all,y)',
                  'variable pz equal mass(all)*vcm(all,z)',
                  'thermo_style custom step time temp pe ke etotal press v_px v_py v_pz',
                  'thermo_modify norm no lost error format float %.15g', 'thermo %d' % nth]
        if ndump:
            lines += ['dump 1 all custom %d %s.dump id xu yu zu vx vy vz' % (ndump, name),
                      'dump_modify 1 sort id format float %.15g']
        lines.append('run %d' % nsteps)
        return '\n'.join(lines) + '\n'


K = KB_METAL
ARGON_CLUSTER = dict(style='lj', eps=0.010323577, sigma=3.41, cutoff=0.0, shift=False)
ARGON_ICO = dict(style='lj', eps=0.010323577, sigma=3.41, cutoff=8.525, shift=True)
ARGON_RAHMAN = dict(style='lj', eps=0.0103408116, sigma=3.4, cutoff=8.5, shift=True)
LJ_BENCH = dict(style='lj', eps=1.0, sigma=1.0, cutoff=2.5, shift=True)

# per mode: t_long (run length of every sweep run), thermo (sample interval), traj (frame interval),
# t_short (trajectory-error horizon, a multiple of traj), dts (Verlet, Terrace and LAMMPS),
# hs (energy stepping), dt_ref (the reference: Terrace Verlet over t_long, frames every traj).
SCENES = [
    Scene('cluster7', 'seven-atom frozen argon cluster (2-D, LJ without cutoff)', 'metal', 2, False,
          ARGON_CLUSTER, 1.0, 39.951,
          quick=dict(t_long=2000.0, thermo=2.0, traj=4.0, t_short=4.0, dts=[0.002, 0.005, 0.01, 0.02, 0.04, 0.08],
                     hs=[x * K for x in (2, 4, 8, 16, 32)], dt_ref=0.00025),
          full=dict(t_long=100000.0, thermo=20.0, traj=4.0, t_short=4.0,
                    dts=[0.001, 0.002, 0.005, 0.01, 0.02, 0.04, 0.08], hs=[x * K for x in (1, 2, 4, 8, 16, 32, 64)],
                    dt_ref=0.00025),
          observables=['temp']),
    Scene('ico147', '147-atom argon icosahedron (3-D, free, ~40 K start)', 'metal', 3, False, ARGON_ICO, 1.0,
          39.951,
          quick=dict(prep_time=10.0, t_long=20.0, thermo=0.2, traj=1.0, t_short=1.0,
                     dts=[0.002, 0.005, 0.01, 0.02, 0.04], hs=[2.5e-4, 5e-4, 1e-3, 2e-3], dt_ref=0.0005),
          full=dict(prep_time=50.0, t_long=1000.0, thermo=1.0, traj=1.0, t_short=1.0,
                    dts=[0.001, 0.002, 0.005, 0.01, 0.02, 0.04], hs=[1.25e-4, 2.5e-4, 5e-4, 1e-3, 2e-3, 4e-3],
                    dt_ref=0.0005),
          observables=['temp']),
    Scene('rahman', "Rahman's liquid argon (864 atoms, ~94 K, periodic)", 'metal', 3, True, ARGON_RAHMAN, 1.0,
          39.948,
          quick=dict(t_long=2.0, thermo=0.04, traj=0.04, t_short=0.2, dts=[0.002, 0.005, 0.01, 0.02, 0.04],
                     hs=[1e-3, 2e-3, 4e-3, 8e-3], dt_ref=0.0005),
          full=dict(t_long=100.0, thermo=0.2, traj=0.04, t_short=0.2, dts=[0.001, 0.002, 0.005, 0.01, 0.02, 0.04],
                    hs=[5e-4, 1e-3, 2e-3, 4e-3, 8e-3], dt_ref=0.0005),
          observables=['temp', 'press', 'gr', 'msd', 'vdos']),
    Scene('ljbench', 'LAMMPS LJ benchmark scene (fcc rho*=0.8442 melted, shifted LJ rc 2.5)', 'lj', 3, True,
          LJ_BENCH, 0.3, 1.0,
          quick=dict(cells=10, t_long=0.25, thermo=0.01, traj=0.01, t_short=0.05,
                     dts=[0.001, 0.002, 0.005, 0.01], hs=[0.1, 0.3, 0.6, 1.2], dt_ref=0.00025),
          full=dict(cells=20, t_long=2.0, thermo=0.01, traj=0.02, t_short=0.06,
                    dts=[0.001, 0.002, 0.005, 0.01], hs=[0.3, 0.6, 1.2], dt_ref=0.00025),
          observables=['temp', 'press', 'gr', 'msd']),
    Scene('cu_eam', 'Cu with EAM (Foiles Cu_u3.eam, fcc, ~300 K)', 'metal', 3, True,
          dict(style='eam', file=CU_EAM), 1.0, None,
          # quick: 108 atoms (3x3x3 cells, the smallest box the cutoff allows) so that energy stepping
          # fits the quick budget: its cost per ps grows like N^1.5 (events ~ sqrt(N), work per event
          # ~ N; doc/energy_stepping.md). h up to 6e-3 eV (~kT/4 at 300 K) does not trap here; 0.012 eV
          # trapped from an equilibrated 108-atom state (same page, "EAM").
          quick=dict(cells=3, prep_time=1.0, t_long=1.0, thermo=0.01, traj=0.01, t_short=0.1,
                     dts=[0.001, 0.002, 0.005, 0.01], hs=[1.5e-3, 3e-3, 6e-3], dt_ref=0.00025),
          full=dict(cells=5, prep_time=5.0, t_long=20.0, thermo=0.02, traj=0.02, t_short=0.1,
                    dts=[0.001, 0.002, 0.005, 0.01], hs=[1.5e-3, 3e-3, 6e-3], dt_ref=0.00025),
          observables=['temp', 'press', 'gr', 'vdos']),
]
SCENE_KEYS = [s.key for s in SCENES]


def get(key):
    for s in SCENES:
        if s.key == key:
            return s
    raise KeyError(key)
