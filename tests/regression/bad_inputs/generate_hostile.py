#!/usr/bin/env python3
"""Hostile-input cases for check_bad_inputs.sh --hostile, generated from small valid
decks and files: NaN, Inf, overflowing and subnormal numbers for every real key and in every file
format, counts beyond what a file can hold, scenes too large for memory, over-long paths,
non-finite boxes and coordinates, ids the trajectory cannot take, colliding and special output
paths, outputs equal to inputs, a locked output, the smaller defects, the files users have, and
damaged H5MD trajectories (NaN, Inf and huge values in positions, velocities and box, wrong shapes,
missing datasets, shapes declaring 1e12 frames or atoms, a frame beyond the file) for the engine's
read_h5md and for terrace-analyze ('@analyze' cases), keys given twice in a group, decks with a
UTF-8 byte-order mark or that are devices, pipes or directories, damaged Gmsh meshes (MSH 2.2 and
4.1: declared counts beyond the file, second sections, repeated nodes, huge coordinates, physical
tags), and outputs through symbolic links. Needs numpy and h5py (check_bad_inputs.sh picks a
python that has them).

usage: generate_hostile.py OUT_DIR
Writes OUT_DIR/cases.txt (the manifest format of bad_inputs/cases.txt) and one directory per
case. Every case directory also holds a previous thermo.csv and forces.txt that the harness
checks are byte-identical afterwards (a failed run must not replace or remove them).
A case directory may hold '.hold_lock': the name of a lock file the harness holds (flock) while
the case runs, as a second run on the same outputs would.
"""
import os
import re
import stat
import sys

OUT = sys.argv[1]
os.makedirs(OUT, exist_ok=True)
manifest = []

LJ = {
    'run': "units='lj', dimension=3, n_steps=10, seed=1",
    'system': "lattice='fcc', density=0.8442, cells=3,3,3, mass=1.0, temperature=1.0",
    'potential': "style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5",
    'integrator': "style='velocity_verlet', dt=0.005",
    'neighbor': 'skin=0.3',
    'output': "thermo_every=5, thermo_file='thermo.csv', forces_file='forces.txt'",
}
GROUPS = ['run', 'system', 'potential', 'integrator', 'neighbor', 'output', 'thermostat', 'barostat', 'minimize']
LINE = {g: i + 2 for i, g in enumerate(GROUPS)}   # line 1 is a comment (the six groups of LJ)


def line_in(groups, group):
    """The deck line of `group` when the deck has `groups` (those not None, in GROUPS order)."""
    present = [g for g in GROUPS if groups.get(g) is not None]
    return present.index(group) + 2


def deck_text(name, groups):
    lines = ['! hostile case: ' + name]
    for g in GROUPS:
        if g in groups and groups[g] is not None:
            lines.append('&%s %s /' % (g, groups[g]))
    return '\n'.join(lines) + '\n'


PREVIOUS_THERMO = 'step,time,temp\n0,0.0,1.0\n'          # what an earlier run left
PREVIOUS_FORCES = '# an earlier run\n1 0.0 0.0 0.0\n'


def case(name, subs, groups=None, files=None, args=None, rc=1, hold_lock=None, deck_name=None,
         modes=None, links=None, fifos=None):
    """Add a case: the deck (groups, LJ by default), extra files, the expected substrings."""
    d = os.path.join(OUT, name)
    os.makedirs(d, exist_ok=True)
    deck = deck_name or (name + '.nml')
    g = dict(LJ)
    if groups:
        g.update(groups)
    os.makedirs(os.path.dirname(os.path.join(d, deck)) or d, exist_ok=True)
    with open(os.path.join(d, deck), 'w') as f:
        f.write(deck_text(name, g))
    with open(os.path.join(d, 'thermo.csv'), 'w') as f:
        f.write(PREVIOUS_THERMO)
    with open(os.path.join(d, 'forces.txt'), 'w') as f:
        f.write(PREVIOUS_FORCES)
    for fname, text in (files or {}).items():
        p = os.path.join(d, fname)
        os.makedirs(os.path.dirname(p), exist_ok=True)
        with open(p, 'w') as f:
            f.write(text)
    for fname, mode in (modes or {}).items():
        os.chmod(os.path.join(d, fname), mode)
    for fname, target in (links or {}).items():
        os.symlink(target, os.path.join(d, fname))
    for fname in fifos or []:
        os.mkfifo(os.path.join(d, fname))
    if hold_lock:
        with open(os.path.join(d, '.hold_lock'), 'w') as f:
            f.write(hold_lock + '\n')
    if args is None:
        args = deck
    manifest.append('%s | %d | %s | %s' % (name, rc, args, ' ; '.join(subs)))


_ASSIGN = re.compile(r"(?:^|,)\s*([A-Za-z_]\w*(?:\s*\([^)]*\))?)\s*=")


def _target(key):
    return re.sub(r'\s+', '', key).lower()


def with_key(group, assignment, base=None):
    """The deck `base` (LJ) with `assignment` in `group`, replacing the group's own assignment of
    that key (a key given twice in one group is an error of its own)."""
    b = dict(base or LJ)
    text = b[group]
    new = _target(_ASSIGN.match(assignment).group(1))
    starts = [(m.start(), _target(m.group(1))) for m in _ASSIGN.finditer(text)] + [(len(text), None)]
    kept = [text[a:starts[i + 1][0]].lstrip(', ') for i, (a, k) in enumerate(starts[:-1]) if k != new]
    b[group] = ', '.join(kept + [assignment])
    return b


def add_key(group, assignment, base=None):
    """The deck with `assignment` appended to `group` as it is (to give a key twice)."""
    b = dict(base or LJ)
    b[group] = b[group] + ', ' + assignment
    return b


# ------------------------------------------------------------------ class 1: reals in the deck
ES = dict(LJ, integrator="style='energy_stepping', terrace_height=0.05",
          potential="style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.true.")
real_keys = [
    ('run', 'run_time', None), ('run', 'walltime_limit', None),
    ('system', 'density', None), ('system', 'lattice_constant', None), ('system', 'temperature', None),
    ('system', 'mass', None), ('system', 'box_lo', None), ('system', 'box_hi', None),
    ('potential', 'epsilon', None), ('potential', 'sigma', None), ('potential', 'cutoff', None),
    ('potential', 'pair_cutoff(1,1)', None),
    ('integrator', 'dt', None), ('integrator', 'root_tolerance', None),
    ('neighbor', 'skin', None),
    ('output', 'thermo_interval', None), ('output', 'trajectory_interval', None),
    ('output', 'checkpoint_interval', None),
    ('integrator', 'terrace_height', ES), ('integrator', 'target_mean_dt', ES),
]
bad_reals = [('nan', 'NaN', 'not a finite number'), ('inf', 'Inf', 'not a finite number'),
             ('neginf', '-Infinity', 'not a finite number'), ('overflow', '1e400', 'not a finite number'),
             ('subnormal', '1e-320', 'out of range'), ('huge', '1e300', 'out of range')]
for group, key, base in real_keys:
    base_key = key.split('(')[0]
    for tag, value, what in bad_reals:
        name = 'real_%s_%s' % (base_key, tag)
        case(name, ['%s.nml:%d' % (name, LINE[group]), '&' + group, key, value, what],
             groups=with_key(group, '%s=%s' % (key, value), base))
# several values in one key: the bad one is found wherever it is
case('real_cells_density_list', ['real_cells_density_list.nml:3', '&system', 'box_hi', 'nan', 'not a finite'],
     groups=with_key('system', 'box_hi=1.0, nan, 3.0'))
case('real_repeat_inf', ['real_repeat_inf.nml:3', '&system', 'box_lo', 'inf', 'not a finite'],
     groups=with_key('system', 'box_lo=3*inf'))
case('real_temperature_1e10', ['real_temperature_1e10.nml:3', '&system', 'temperature', 'out of range'],
     groups=with_key('system', 'temperature=1e10'))
case('real_run_time_steps', ['real_run_time_steps.nml', '&run', 'run_time', 'time steps'],
     groups=dict(LJ, run="units='lj', run_time=1e11, seed=1", integrator="style='velocity_verlet', dt=1e-6"))

# ------------------------------------------------------------------ files: a valid data file
def data_file(natoms_line='8 atoms', box=('0 4 xlo xhi', '0 4 ylo yhi', '0 4 zlo zhi'), types='1 atom types',
              masses='1 1.0', atoms=None, velocities=None, extra_header='', extra_sections=''):
    if atoms is None:
        atoms = ['%d 1 %g %g %g 0 0 0' % (i + 1, 0.5 + 2 * (i % 2), 0.5 + 2 * ((i // 2) % 2), 0.5 + 2 * (i // 4))
                 for i in range(8)]
    t = 'LAMMPS data file (hostile case)\n\n%s\n%s\n%s\n%s\n\n' % (natoms_line, types, extra_header, '\n'.join(box))
    t += 'Masses\n\n%s\n\n' % masses
    t += 'Atoms # atomic\n\n' + '\n'.join(atoms) + '\n'
    if velocities is not None:
        t += '\nVelocities\n\n' + '\n'.join(velocities) + '\n'
    t += extra_sections
    return t


DATA = dict(LJ, system="read_data='in.data', temperature=1.0",
            potential="style='lj', epsilon=1.0, sigma=1.0, cutoff=1.2")
atoms8 = ['%d 1 %g %g %g 0 0 0' % (i + 1, 0.5 + 2 * (i % 2), 0.5 + 2 * ((i // 2) % 2), 0.5 + 2 * (i // 4))
          for i in range(8)]
vel8 = ['%d 0.1 0.0 -0.1' % (i + 1) for i in range(8)]


def data_case(name, subs, rc=1, groups=None, **kw):
    case(name, ['in.data', '&system', 'read_data'] + subs, groups=groups or DATA, files={'in.data': data_file(**kw)},
         rc=rc)


for tag, v in [('nan', 'nan'), ('inf', 'inf'), ('neginf', '-inf'), ('overflow', '1e400')]:
    data_case('data_xhi_' + tag, ['box bounds'], box=('0 %s xlo xhi' % v, '0 4 ylo yhi', '0 4 zlo zhi'))
    data_case('data_zlo_' + tag, ['box bounds'], box=('0 4 xlo xhi', '0 4 ylo yhi', '%s 4 zlo zhi' % v))
    data_case('data_coord_' + tag, ['coordinates must be finite'],
              atoms=atoms8[:3] + ['4 1 %s 2.5 0.5 0 0 0' % v] + atoms8[4:])
    data_case('data_vel_' + tag, ['velocities must be finite'], velocities=vel8[:5] + ['6 0.1 %s 0.0' % v] + vel8[6:])
    data_case('data_mass_' + tag, ['mass'], masses='1 %s' % v)
data_case('data_box_huge', ['box bounds'], box=('0 1e12 xlo xhi', '0 4 ylo yhi', '0 4 zlo zhi'))
data_case('data_mass_zero', ['mass'], masses='1 0')
data_case('data_image_2e10', ['image flags'], atoms=atoms8[:2] + ['3 1 0.5 2.5 0.5 20000000000 0 0'] + atoms8[3:])
data_case('data_image_frac', ['image flags'], atoms=atoms8[:2] + ['3 1 0.5 2.5 0.5 0.5 0 0'] + atoms8[3:])
data_case('data_image_nan', ['image flags'], atoms=atoms8[:2] + ['3 1 0.5 2.5 0.5 nan 0 0'] + atoms8[3:])
# class 3: counts beyond what the file holds
data_case('data_2e9_atoms', ['2000000000 atoms', 'can hold at most'], natoms_line='2000000000 atoms')
data_case('data_1e15_atoms', ['can hold at most'], natoms_line='1000000000000000 atoms')
data_case('data_huge_types', ['atom types', 'max 8'], types='2147483647 atom types')
data_case('data_9_types', ['atom types', 'max 8'], types='9 atom types')
data_case('data_negative_atoms', ['atom count'], natoms_line='-5 atoms')
# class 11: the smaller ones
data_case('data_second_atoms', ['second Atoms section'],
          extra_sections='\nAtoms # atomic\n\n' + '\n'.join(atoms8) + '\n')
data_case('data_more_atoms_lines', ['more lines than the header', '8 atoms'],
          atoms=atoms8 + ['9 1 3.5 3.5 3.5 0 0 0'])
data_case('data_masses_type_beyond', ['Masses line for type 2', '1 atom types'], masses='2 1.0')
data_case('data_triclinic', ['triclinic'], extra_header='0 0 0 xy xz yz')
data_case('data_bonds', ['molecular topology'], extra_header='4 bonds')
data_case('data_bonds_section', ['molecular topology'], extra_sections='\nBonds\n\n1 1 1 2\n')
data_case('data_unknown_section', ["section 'Ellipsoids'"], extra_sections='\nEllipsoids\n\n1 1 1 1\n')
data_case('data_pair_coeffs_disagree', ['disagree', 'epsilon'], extra_sections='\nPair Coeffs # lj/cut\n\n1 2.0 1.0\n')
data_case('data_pair_coeffs_style', ['morse'], extra_sections='\nPair Coeffs # morse\n\n1 1.0 1.0\n')
data_case('data_pairij_nan', ['PairIJ Coeffs'], extra_sections='\nPairIJ Coeffs # lj/cut\n\n1 1 nan 1.0 2.5\n')
# class 6: ids the trajectory and checkpoint writers cannot take, found before any output
ids_far = ['%d 1 %g %g %g 0 0 0' % (i, 0.5 + 2 * (k % 2), 0.5 + 2 * ((k // 2) % 2), 0.5 + 2 * (k // 4))
           for k, i in enumerate([1, 2, 3, 4, 5, 6, 7, 10 ** 12])]
traj_out = DATA['output'] + ", trajectory_file='traj.h5'"
data_case('ids_gap_trajectory', ['ids 1..8', 'trajectory_file', '1000000000000'], atoms=ids_far,
          groups=dict(DATA, output=traj_out))
data_case('ids_gap_checkpoint', ['ids 1..8', 'checkpoint_file'],
          atoms=['%d 1 %s' % (i + 2, a.split(' ', 2)[2]) for i, a in enumerate(atoms8)],
          groups=dict(DATA, output=DATA['output'] + ", checkpoint_file='ck.h5', checkpoint_every=5"))

# ------------------------------------------------------------------ atoms files
ATOMS = dict(LJ, run="units='lj', dimension=3, n_steps=10, seed=1",
             system="atoms_file='in.atoms', box_lo=0,0,0, box_hi=4,4,4, mass=1.0",
             potential="style='lj', epsilon=1.0, sigma=1.0, cutoff=1.2")
atom_lines = ['1 %g %g %g' % (0.5 + 2 * (k % 2), 0.5 + 2 * ((k // 2) % 2), 0.5 + 2 * (k // 4)) for k in range(8)]
for tag, line, subs in [('x_nan', '1 nan 0.5 0.5', ['must be finite']), ('x_inf', '1 inf 0.5 0.5', ['must be finite']),
                        ('v_nan', '1 2.5 2.5 2.5 0 nan 0', ['must be finite']),
                        ('v_overflow', '1 2.5 2.5 2.5 0 1e999 0', ['must be finite']),
                        ('type_huge', '2147483647 2.5 2.5 2.5', ['more atom types', 'max 8']),
                        ('type_9', '9 2.5 2.5 2.5', ['more atom types']),
                        ('type_zero', '0 2.5 2.5 2.5', ['bad atom line'])]:
    lines = atom_lines[:3] + [line] + atom_lines[4:] if not tag.startswith('v_') else \
        [l + ' 0 0 0' for l in atom_lines[:3]] + [line] + [l + ' 0 0 0' for l in atom_lines[4:]]
    case('atoms_' + tag, ['in.atoms', '&system', 'atoms_file'] + subs, groups=ATOMS,
         files={'in.atoms': '\n'.join(lines) + '\n'})
FREE2D = dict(ATOMS, run="units='lj', dimension=2, n_steps=10, seed=1",
              system="atoms_file='in.atoms', box_lo=0,0,0, box_hi=4,4,1, periodic=.false.,.false., mass=1.0",
              potential="style='lj', epsilon=1.0, sigma=1.0, cutoff=0")
case('atoms_free2d_inf', ['in.atoms', '&system', 'atoms_file', 'finite'], groups=FREE2D,
     files={'in.atoms': '1 0.5 0.5 0\n1 1.5 0.5 0\n1 inf 1.5 0\n'})

# ------------------------------------------------------------------ EAM files
def setfl(n_el='1 Cu', grid='5 0.1 5 0.5 2.0', elem='29 63.546 3.615 fcc', f=None, rho=None, z2r=None):
    f = f or ['0 -1 -2 -3 -4']
    rho = rho or ['1 0.8 0.6 0.4 0.2']
    z2r = z2r or ['5 3 1 0.5 0']
    return 'c1\nc2\nc3\n%s\n%s\n%s\n%s\n%s\n%s\n' % (n_el, grid, elem, '\n'.join(f), '\n'.join(rho), '\n'.join(z2r))


EAM = dict(LJ, run="units='metal', dimension=3, n_steps=10, seed=1",
           system="lattice='fcc', lattice_constant=3.615, cells=3,3,3, temperature=300",
           potential="style='eam/alloy', file='Cu.set', elements='Cu'",
           integrator="style='velocity_verlet', dt=0.001", neighbor='skin=1.0')
for tag, kw, subs in [
        ('nr_2e9', dict(grid='5 0.1 2000000000 0.5 2.0'), ['can hold']),
        ('nrho_2e9', dict(grid='2000000000 0.1 5 0.5 2.0'), ['can hold']),
        ('nelem_2e9', dict(n_el='2000000000 Cu'), ['can hold']),
        ('nelem_max', dict(n_el='2147483647 Cu'), ['can hold']),
        ('dr_nan', dict(grid='5 0.1 5 nan 2.0'), ['dr']),
        ('cut_inf', dict(grid='5 0.1 5 0.5 inf'), ['cutoff']),
        ('mass_nan', dict(elem='29 nan 3.615 fcc'), ['mass']),
        ('f_nan', dict(f=['0 -1 nan -3 -4']), ['not a number']),
        ('f_overflow', dict(f=['0 -1 1e999 -3 -4']), ['out of range']),
        ('rho_inf', dict(rho=['1 0.8 inf 0.4 0.2']), ['not a number']),
        ('z2r_1e400', dict(z2r=['5 3 1e400 0.5 0']), ['out of range'])]:
    case('eam_' + tag, ['Cu.set'] + subs, groups=EAM, files={'Cu.set': setfl(**kw)})
case('eam_units_lj', ['&run', 'units', 'metal'], groups=dict(EAM, run="units='lj', n_steps=10, seed=1",
     system="lattice='fcc', density=0.8442, cells=3,3,3, temperature=1.0"), files={'Cu.set': setfl()})

# ------------------------------------------------------------------ class 3: scenes beyond memory
for tag, cells in [('2000cubed', '2000,2000,2000'), ('flat', '100000,100000,10'), ('int_max', '2147483647,2,2'),
                   ('1e5cubed', '100000,100000,100000')]:
    case('mem_cells_' + tag, ['mem_cells_%s.nml:3' % tag, '&system', 'cells', 'GiB', 'available'],
         groups=with_key('system', 'cells=' + cells))
case('mem_cells_2d', ['mem_cells_2d.nml:3', '&system', 'cells', 'GiB'],
     groups=dict(LJ, run="units='lj', dimension=2, n_steps=10, seed=1",
                 system="lattice='hex', density=0.8, cells=1000000,1000000, mass=1.0, temperature=1.0"))

# ------------------------------------------------------------------ class 4: paths beyond the buffer
long_name = 'x' * 5000
for key, group in [('thermo_file', 'output'), ('forces_file', 'output'), ('trajectory_file', 'output'),
                   ('final_atoms_file', 'output'), ('checkpoint_file', 'output'), ('read_data', 'system'),
                   ('atoms_file', 'system')]:
    g = dict(LJ)
    if group == 'system':
        g['system'] = "%s='%s', mass=1.0" % (key, long_name)
    else:
        g = with_key(group, "%s='%s'" % (key, long_name))
    case('path_long_' + key, ['&' + group, key, '5000 characters', '4096'], groups=g)
# a path component longer than the file system allows (NAME_MAX 255)
case('path_component_long', ['&output', 'thermo_file'],
     groups=dict(LJ, output="thermo_every=5, thermo_file='%s', forces_file='forces.txt'" % ('y' * 300)))

# ------------------------------------------------------------------ class 6, 8, 10: outputs
def out_case(name, output, subs, **kw):
    case(name, subs, groups=dict(LJ, output=output), **kw)


case('out_thermo_is_data', ['&output', 'thermo_file', 'read_data', 'its input'],
     groups=dict(DATA, output="thermo_file='in.data', forces_file='forces.txt'"), files={'in.data': data_file()})
case('out_thermo_is_data_dotslash', ['&output', 'thermo_file', 'read_data', 'its input'],
     groups=dict(DATA, output="thermo_file='./sub/../in.data'"), files={'in.data': data_file(), 'sub/keep': ''})
case('out_thermo_symlink_to_data', ['&output', 'thermo_file', 'read_data', 'its input'],
     groups=dict(DATA, output="thermo_file='link.csv'"), files={'in.data': data_file()}, links={'link.csv': 'in.data'})
case('out_forces_is_atoms', ['&output', 'forces_file', 'atoms_file', 'its input'],
     groups=dict(ATOMS, output="forces_file='in.atoms'"), files={'in.atoms': '\n'.join(atom_lines) + '\n'})
case('out_final_is_atoms', ['&output', 'final_atoms_file', 'atoms_file', 'its input'],
     groups=dict(ATOMS, output="final_atoms_file='in.atoms'"), files={'in.atoms': '\n'.join(atom_lines) + '\n'})
case('out_thermo_is_deck', ['&output', 'thermo_file', 'input deck'],
     groups=dict(LJ, output="thermo_file='out_thermo_is_deck.nml'"))
case('out_thermo_is_eam', ['&output', 'thermo_file', '&potential file', 'its input'],
     groups=dict(EAM, output="thermo_file='Cu.set'"), files={'Cu.set': setfl()})
pairs = [('thermo_file', 'forces_file'), ('thermo_file', 'final_atoms_file'), ('forces_file', 'final_atoms_file'),
         ('trajectory_file', 'checkpoint_file'), ('thermo_file', 'trajectory_file'),
         ('forces_file', 'checkpoint_file')]
for a, b in pairs:
    extra = ", checkpoint_every=5" if 'checkpoint' in a + b else ''
    out_case('out_same_%s_%s' % (a.split('_')[0], b.split('_')[0]), "%s='same.out', %s='./same.out'%s" % (a, b, extra),
             ['&output', b, 'same file as &output ' + a])
out_case('out_thermo_dev_full', "thermo_file='/dev/full'", ['/dev/full', '&output', 'thermo_file', 'not a regular file'])
out_case('out_forces_dev_null', "forces_file='/dev/null'", ['/dev/null', '&output', 'forces_file', 'not a regular'])
out_case('out_final_dev_full', "final_atoms_file='/dev/full'", ['/dev/full', '&output', 'final_atoms_file',
                                                                 'not a regular'])
out_case('out_traj_dev_full', "trajectory_file='/dev/full', overwrite=.true.", ['/dev/full', '&output',
                                                                                 'trajectory_file', 'not a regular'])
out_case('out_ckpt_dev_full', "checkpoint_file='/dev/full', checkpoint_every=5", ['/dev/full', '&output',
                                                                                   'checkpoint_file', 'not a regular'])
out_case('out_thermo_directory', "thermo_file='adir'", ['adir', '&output', 'thermo_file', 'not a regular'],
         files={'adir/keep': 'x'})
out_case('out_forces_fifo', "forces_file='pipe'", ['pipe', '&output', 'forces_file', 'not a regular'], fifos=['pipe'])
out_case('out_final_missing_dir', "final_atoms_file='nodir/final.atoms'",
         ['nodir/final.atoms', '&output', 'final_atoms_file', 'does not exist'])
out_case('out_thermo_missing_dir', "thermo_file='nodir/t.csv'", ['nodir/t.csv', '&output', 'thermo_file',
                                                                  'does not exist'])
out_case('out_final_in_file', "final_atoms_file='afile/x'", ['afile/x', '&output', 'final_atoms_file'],
         files={'afile': 'x'})
out_case('out_thermo_locked', "thermo_every=5, thermo_file='thermo.csv', forces_file='forces.txt'",
         ['&output', 'thermo_file', 'another terrace run'], hold_lock='.thermo.csv.terrace-lock')
out_case('out_forces_locked', "thermo_every=5, thermo_file='thermo.csv', forces_file='forces.txt'",
         ['&output', 'forces_file', 'another terrace run'], hold_lock='.forces.txt.terrace-lock')
if os.geteuid() != 0:      # root writes read-only files anyway
    out_case('out_final_readonly', "final_atoms_file='ro.atoms'", ['&output', 'final_atoms_file', 'read-only'],
             files={'ro.atoms': 'old\n'}, modes={'ro.atoms': stat.S_IRUSR})
    out_case('out_dir_readonly', "thermo_file='rodir/t.csv'", ['&output', 'thermo_file', 'cannot create a file'],
             files={'rodir/keep': ''}, modes={'rodir': stat.S_IRUSR | stat.S_IXUSR})

# outputs through symbolic links are written to the target: the target's directory is checked
out_case('out_thermo_link_missing_dir', "thermo_file='link.csv'", ['link.csv', '&output', 'thermo_file',
                                                                  'does not exist'], links={'link.csv': 'nodir/t.csv'})
out_case('out_forces_link_to_dir', "forces_file='link.txt'", ['link.txt', '&output', 'forces_file', 'not a regular'],
         files={'adir/keep': 'x'}, links={'link.txt': 'adir'})
out_case('out_final_link_to_dev_full', "final_atoms_file='link.atoms'", ['link.atoms', '&output', 'final_atoms_file',
                                                                        'not a regular'],
         links={'link.atoms': '/dev/full'})
out_case('out_thermo_link_same_as_forces', "thermo_file='link.csv', forces_file='real.txt'",
         ['&output', 'forces_file', 'same file as &output thermo_file'], files={'real.txt': 'x\n'},
         links={'link.csv': 'real.txt'})
out_case('out_thermo_link_locked', "thermo_every=5, thermo_file='link.csv', forces_file='forces.txt'",
         ['&output', 'thermo_file', 'another terrace run'], files={'sub/t.csv': 'old\n'},
         links={'link.csv': 'sub/t.csv'}, hold_lock='sub/.t.csv.terrace-lock')

# ------------------------------------------------------------------ class 11: the smaller ones
case('str_lattice_two_words', ['&system', 'lattice', 'not one word'],
     groups=dict(LJ, system="lattice='fcc     bogus', density=0.8442, cells=3,3,3, mass=1.0"))
case('str_units_two_words', ['&run', 'units', 'not one word'], groups=dict(LJ, run="units='lj   furlongs', n_steps=10"))
case('str_style_two_words', ['&potential', 'style', 'not one word'],
     groups=dict(LJ, potential="style='lj cut', epsilon=1.0, sigma=1.0, cutoff=2.5"))
case('str_integrator_too_long', ['&integrator', 'style', 'not one word'],
     groups=dict(LJ, integrator="style='velocity_verlet_with_a_very_long_name'"))
case('str_list_two_words', ['&neighbor', 'list', 'not one word'], groups=dict(LJ, neighbor="list='cells auto'"))
case('str_elements_long', ['&potential', 'elements', 'not one word'],
     groups=dict(EAM, potential="style='eam/alloy', file='Cu.set', elements='Copper-alloy'"), files={'Cu.set': setfl()})

# ------------------------------------------------------------------ files users have: paths
case('rel_path_beside_deck', ['in.data', '&system', 'read_data', 'no such file', 'next to the deck'],
     groups=dict(DATA), deck_name='sub/deck.nml', args='sub/deck.nml', files={'sub/in.data': data_file()})
case('rel_path_missing', ['nothere.data', '&system', 'read_data', 'no such file', '/nothere.data'],
     groups=dict(DATA, system="read_data='nothere.data'"))
case('input_is_directory', ['adir', '&system', 'read_data', 'directory'],
     groups=dict(DATA, system="read_data='adir'"), files={'adir/keep': ''})
case('input_is_device', ['/dev/zero', '&system', 'atoms_file', 'not a regular file'],
     groups=dict(ATOMS, system="atoms_file='/dev/zero', box_lo=0,0,0, box_hi=4,4,4, mass=1.0"))
case('eam_file_missing_beside', ['Cu.set', '&potential', 'file', 'next to the deck'], groups=EAM,
     deck_name='sub/deck.nml', args='sub/deck.nml', files={'sub/Cu.set': setfl()})

# ------------------------------------------------------------------ classes 1, 5: damaged H5MD trajectories
# A small valid trajectory (16 atoms on a jittered lattice in a periodic box of 10, 40 frames, the
# layout Terrace writes: box/edges a time-dependent element), damaged one way per case, read by the
# engine (&system read_h5md, the damaged frame) and by terrace-analyze (the analysis that reads the
# damaged element). Every message must name the file, the key and the dataset.
import h5py  # noqa: E402  (the harness runs this generator with a python that has h5py)
import numpy as np  # noqa: E402

from terrace_tools.h5md import write_synthetic as write_h5md  # noqa: E402

H5_NF, H5_N = 40, 16
_rng = np.random.default_rng(15)
_grid = np.array([[2.5 * i + 1.25, 5.0 * j + 2.5, 5.0 * k + 2.5] for i in range(4) for j in range(2) for k in range(2)])
H5_X = _grid[None, :, :] + _rng.uniform(-0.2, 0.2, size=(H5_NF, H5_N, 3))
H5_V = _rng.normal(scale=0.5, size=(H5_NF, H5_N, 3))
H5_T = np.arange(H5_NF) * 0.01


def h5_file(path, x=None, v=None, edges=(10.0, 10.0, 10.0), edit=None):
    """The valid trajectory with positions x / velocities v replaced (None: the valid ones), then
    edit(f) applied to the open file (to delete or reshape a dataset)."""
    x = H5_X if x is None else x
    v = H5_V if v is None else v
    write_h5md(path, 3, positions=x, velocities=v, images=np.zeros(x.shape, np.int32), times=H5_T,
               edges=list(edges), edges_series=True, species=np.ones(x.shape[1]), mass=np.ones(x.shape[1]))
    if edit is not None:
        with h5py.File(path, 'a') as f:
            edit(f)


H5_DECK = dict(LJ, system="read_h5md='in.h5', mass=1.0")


def h5_cases(name, engine_subs, analyze_subs, compute='rdf', frame=None, **kw):
    """Two cases on one damaged file in.h5: the engine starting from it (frame: h5md_frame) and
    terrace-analyze --compute=compute on it."""
    system = "read_h5md='in.h5', mass=1.0" + ('' if frame is None else ', h5md_frame=%d' % frame)
    for who, subs, args in (('eng', engine_subs, None),
                            ('ana', analyze_subs, '@analyze --trajectory_file=in.h5 --compute=' + compute)):
        cname = 'h5_%s_%s' % (who, name)
        case(cname, subs, groups=dict(H5_DECK, system=system), args=args)
        h5_file(os.path.join(OUT, cname, 'in.h5'), **kw)


ENG = ['in.h5', '&system', 'read_h5md']
ANA = ['in.h5', 'trajectory_file']
# non-finite and huge values in positions and velocities: first, middle and last frame
for field, compute in (('position', 'rdf'), ('velocity', 'vdos')):
    for tag, value, what in (('nan', np.nan, 'NaN or infinite'), ('inf', np.inf, 'NaN or infinite'),
                             ('neginf', -np.inf, 'NaN or infinite'), ('huge', 1e300, 'beyond 1e9'),
                             ('1e10', -1e10, 'beyond 1e9')):
        for frame, atom in ((0, 0), (H5_NF // 2, 7), (H5_NF - 1, H5_N - 1)):
            if tag in ('neginf', '1e10') and frame != H5_NF // 2:
                continue
            a = (H5_X if field == 'position' else H5_V).copy()
            a[frame, atom, frame % 3] = value
            ds = '/particles/all/%s/value' % field
            where = 'frame %d, atom row %d' % (frame + 1, atom + 1)
            c = compute if frame != H5_NF - 1 or field == 'velocity' else 'msd'
            h5_cases('%s_%s_f%d' % (field, tag, frame + 1), ENG + [ds, where, what], ANA + [ds, where, what],
                     compute=c, frame=frame + 1, **{'x' if field == 'position' else 'v': a})
# every frame damaged (a run that blew up): still one line on every rank count
h5_cases('position_all_nan', ENG + ['/particles/all/position/value', 'NaN or infinite'],
         ANA + ['/particles/all/position/value', 'NaN or infinite'], compute='sq', x=np.full(H5_X.shape, np.nan))
# the box
for tag, value, what in (('nan', np.nan, 'NaN or infinite'), ('inf', np.inf, 'NaN or infinite'),
                         ('huge', 1e300, 'beyond 1e9'), ('zero', 0.0, 'not positive'),
                         ('negative', -10.0, 'not positive')):
    h5_cases('box_edge_%s' % tag, ENG + ['/particles/all/box/edges', what], ANA + ['/particles/all/box/edges', what],
             edges=(10.0, value, 10.0))


def _replace(path, data):
    def edit(f):
        attrs = dict(f[path].attrs)
        del f[path]
        f[path] = data
        for k, val in attrs.items():
            f[path].attrs[k] = val
    return edit


def _delete(*paths):
    def edit(f):
        for q in paths:
            del f[q]
    return edit


P = '/particles/all/'
# wrong shapes
h5_cases('position_rank2', ENG + [P + 'position/value', 'wrong shape'], ANA + [P + 'position/value', 'wrong shape'],
         edit=_replace(P + 'position/value', H5_X[0]))
h5_cases('position_dim4', ENG + [P + 'position/value'], ANA + [P + 'position/value'],
         edit=_replace(P + 'position/value', np.zeros((H5_NF, H5_N, 4))))
h5_cases('velocity_atoms', ENG + [P + 'velocity/value'], ANA + [P + 'velocity/value', 'wrong shape'], compute='vdos',
         edit=_replace(P + 'velocity/value', H5_V[:, :-1]))
h5_cases('velocity_frames', ENG + [P + 'velocity/time', 'wrong shape', 'velocity/value'],
         ANA + [P + 'velocity/time', 'wrong shape', 'velocity/value'], compute='vdos',
         edit=_replace(P + 'velocity/value', H5_V[:-1]))
h5_cases('box_edges_dim2', ENG + [P + 'box/edges/value', 'wrong shape'], ANA + [P + 'box/edges/value', 'wrong shape'],
         edit=_replace(P + 'box/edges/value', np.full((H5_NF, 2), 10.0)))
h5_cases('box_edges_frames', ENG + [P + 'box/edges/value', 'wrong shape'],
         ANA + [P + 'box/edges/value', 'wrong shape'], edit=_replace(P + 'box/edges/value', np.full((7, 3), 10.0)))
h5_cases('position_time_length', ENG + [P + 'position/time', 'wrong shape'],
         ANA + [P + 'position/time', 'wrong shape'], edit=_replace(P + 'position/time', H5_T[:-3]))
# missing datasets and groups
h5_cases('no_position', ENG + [P + 'position/value', 'missing'], ANA + [P + 'position/value', 'missing'],
         edit=_delete(P + 'position'))
h5_cases('no_velocity_vdos', ENG + [P + 'position/value', 'missing'], ANA + [P + 'velocity/value', 'missing'],
         compute='vdos', edit=_delete(P + 'velocity', P + 'position'))
h5_cases('no_particles', ENG + ['/particles/all', 'missing'], ANA + ['/particles/all', 'missing'],
         edit=_delete('/particles'))
h5_cases('no_edges_value', ENG + [P + 'box/edges/value', 'missing'], ANA + [P + 'box/edges/value', 'missing'],
         edit=_delete(P + 'box/edges/value'))
h5_cases('no_position_step', ENG + [P + 'position/step', 'missing'], ANA + [P + 'position/time', 'missing'], compute='msd',
         edit=_delete(P + 'position/step', P + 'position/time'))


# damaged H5MD files that declare more than they hold: a dataset's shape costs nothing in the file
# (chunks never written), so a count is bounded by the file's size before anything is allocated
def _huge(frames, atoms, scalar_clock):
    def edit(f):
        g = f[P + 'position']
        del g['value']
        g.create_dataset('value', shape=(frames, atoms, 3), dtype='f8', chunks=(1, min(atoms, 1000), 3))
        if scalar_clock:
            del g['time'], g['step']
            g['time'] = 0.01
            g['step'] = np.int64(1)
    return edit


h5_cases('position_1e12_frames', ENG + [P + 'position/value', '1000000000000 frames', 'can hold'],
         ANA + [P + 'position/value', '1000000000000 frames', 'can hold'], edit=_huge(10 ** 12, H5_N, True))
h5_cases('position_1e12_frames_series', ENG + [P + 'position/value', '1000000000000 frames', 'can hold'],
         ANA + [P + 'position/value', '1000000000000 frames', 'can hold'], edit=_huge(10 ** 12, H5_N, False))
h5_cases('position_2e9_frames', ENG + [P + 'position/value', '2147483648 frames', 'can hold'],
         ANA + [P + 'position/value', '2147483648 frames', 'can hold'], edit=_huge(2 ** 31, H5_N, True))
h5_cases('position_1e12_atoms', ENG + [P + 'position/value', '1000000000000 atoms', 'can hold'],
         ANA + [P + 'position/value', '1000000000000 atoms', 'can hold'], edit=_huge(H5_NF, 10 ** 12, True))
# a frame beyond the file: the key and the file's frame count
for fr in (H5_NF + 1, -(H5_NF + 1), 10 ** 12):
    tag = ('m%d' % -fr) if fr < 0 else str(fr)
    case('h5_eng_frame_' + tag, ['in.h5', '&system', 'read_h5md', 'h5md_frame = %d' % fr, '%d frames' % H5_NF,
                                 '1..%d' % H5_NF], groups=dict(H5_DECK, system="read_h5md='in.h5', mass=1.0, h5md_frame=%d" % fr))
    h5_file(os.path.join(OUT, 'h5_eng_frame_' + tag, 'in.h5'))

# ------------------------------------------------------------------ the namelist file itself
# a key given twice in one group: refused where it is read, with both lines
for name, groups, line, group, key in (
        ('nml_repeat_units', add_key('run', "units='metal'"), 2, '&run', 'units'),
        ('nml_repeat_cutoff', add_key('potential', 'cutoff=3.0'), 4, '&potential', 'cutoff'),
        ('nml_repeat_case', add_key('potential', 'CUTOFF = 2.5'), 4, '&potential', 'cutoff'),
        ('nml_repeat_same_value', add_key('integrator', 'dt=0.005'), 5, '&integrator', 'dt'),
        ('nml_repeat_array', add_key('system', 'cells=4,4,4'), 3, '&system', 'cells'),
        ('nml_repeat_subscript', dict(LJ, potential="style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, "
                                                    "pair_cutoff(1,1)=2.5, pair_cutoff(1, 1)=2.0"),
         4, '&potential', 'pair_cutoff(1,1)'),
        ('nml_repeat_output', add_key('output', "thermo_file='other.csv'"), 7, '&output', 'thermo_file')):
    case(name, ['%s.nml:%d' % (name, line), group, key, 'given twice'], groups=groups)
# ... on lines of its own: the message gives both
d = os.path.join(OUT, 'nml_repeat_lines')
case('nml_repeat_lines', ['nml_repeat_lines.nml:4', '&run', 'n_steps', 'given twice', 'first at line 3'])
with open(os.path.join(d, 'nml_repeat_lines.nml'), 'w') as f:
    f.write(deck_text('nml_repeat_lines', dict(LJ, run=None)).replace(
        '! hostile case: nml_repeat_lines\n',
        "! hostile case: nml_repeat_lines\n&run units='lj',\n     n_steps=10,\n     n_steps=20, seed=1 /\n"))
# a deck saved with a UTF-8 byte-order mark is read (the error is the deck's own, on its line)
BOM = '\ufeff'
for name, groups, subs in (
        ('nml_bom_unknown_key', add_key('potential', 'cutof=2.5'), ['nml_bom_unknown_key.nml:4', '&potential', 'cutof',
                                                                      'unknown key']),
        ('nml_bom_repeat', add_key('run', 'seed=2'), ['nml_bom_repeat.nml:2', '&run', 'seed', 'given twice'])):
    case(name, subs, groups=groups)
    path = os.path.join(OUT, name, name + '.nml')
    text = open(path).read()
    with open(path, 'w', encoding='utf-8') as f:
        f.write(BOM + text)
# a deck that is not a regular file: said so, never read (a pipe would not end)
case('deck_dev_zero', ['/dev/zero', 'not a regular file'], args='/dev/zero')
case('deck_dev_null', ['/dev/null', 'not a regular file'], args='/dev/null')
case('deck_directory', ['adir', 'is a directory'], args='adir', files={'adir/keep': ''})
case('deck_fifo', ['pipe', 'not a regular file'], args='pipe', fifos=['pipe'])
case('deck_missing', ['nothere.nml', 'no such file'], args='nothere.nml')
case('deck_symlink_to_dir', ['dlink', 'is a directory'], args='dlink', files={'adir/keep': ''}, links={'dlink': 'adir'})

# ------------------------------------------------------------------ Gmsh meshes
MESH = dict(run="units='si', dimension=3, n_steps=10, seed=1",
            system="mesh_file='in.msh', mass_density=1000.0, periodic=.false.,.false.,.false.",
            potential="style='neohookean', lambda=1.0e6, mu=1.0e6", integrator="style='velocity_verlet', dt=1.0e-6",
            neighbor=None, output="thermo_every=5, thermo_file='thermo.csv', forces_file='forces.txt'")
M_X = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (1, 1, 1)]
M_T = [(1, 2, 3, 4), (2, 3, 4, 5)]


def msh22(x=M_X, t=M_T, phys=(1, 1), nodes_count=None, elems_count=None, extra=''):
    s = '$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n%s\n' % (nodes_count or len(x))
    s += ''.join('%d %r %r %r\n' % ((i + 1,) + tuple(p)) for i, p in enumerate(x)) + '$EndNodes\n'
    s += '$Elements\n%s\n1 15 2 1 1 1\n' % (elems_count or len(t) + 1)
    s += ''.join('%d 4 2 %d 1 %d %d %d %d\n' % ((k + 2, ph) + tuple(e)) for k, (e, ph) in enumerate(zip(t, phys)))
    return s + '$EndElements\n' + extra


def msh41(x=M_X, t=M_T, vol_phys='1 1', nodes_head=None, elems_head=None, block_entity=1, extra=''):
    s = '$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n1 0 0 1\n1 0 0 0 1 7\n1 0 0 0 1 1 1 %s 0\n$EndEntities\n' % vol_phys
    s += '$Nodes\n%s\n0 1 0 1\n1\n0 0 0\n3 1 0 %d\n' % (nodes_head or '2 %d 1 %d' % (len(x), len(x)), len(x) - 1)
    s += ''.join('%d\n' % (i + 2) for i in range(len(x) - 1))
    s += ''.join('%r %r %r\n' % tuple(p) for p in x[1:]) + '$EndNodes\n'
    s += '$Elements\n%s\n0 1 15 1\n1 1\n3 %d 4 %d\n' % (elems_head or '2 %d 1 %d' % (len(t) + 1, len(t) + 1),
                                                      block_entity, len(t))
    s += ''.join('%d %d %d %d %d\n' % ((k + 2,) + tuple(e)) for k, e in enumerate(t))
    return s + '$EndElements\n' + extra


def line_of(text, start, nth=1):
    """1-based number of the nth line that starts with start."""
    hits = [i + 1 for i, l in enumerate(text.split('\n')) if l.startswith(start)]
    return hits[nth - 1]


def mesh_case(name, text, subs, line_start=None, nth=1, deck=None):
    where = 'in.msh' if line_start is None else 'in.msh:%d' % line_of(text, line_start, nth)
    case(name, [where, '&system', 'mesh_file'] + subs, groups=dict(MESH, **(deck or {})), files={'in.msh': text})


for fmt, writer in (('22', msh22), ('41', msh41)):
    h = '' if fmt == '22' else '2 '        # 4.1 headers start with the block count
    mesh_case('mesh%s_elements_999999999' % fmt, writer(elems_count='999999999') if fmt == '22' else
              writer(elems_head='2 999999999 1 999999999'), ['$Elements declares 999999999', 'can hold'],
              h + '999999999')
    mesh_case('mesh%s_nodes_999999999' % fmt, writer(nodes_count='999999999') if fmt == '22' else
              writer(nodes_head='2 999999999 1 999999999'), ['$Nodes declares 999999999', 'can hold'],
              h + '999999999')
    mesh_case('mesh%s_elements_negative' % fmt, writer(elems_count='-3') if fmt == '22' else
              writer(elems_head='2 -3 1 3'), ['$Elements declares -3'], h + '-3')
    good = writer()
    mesh_case('mesh%s_second_nodes' % fmt, good + good[good.index('$Nodes'):good.index('$Elements')],
              ['second $Nodes section', 'first is at line %d' % line_of(good, '$Nodes')], '$Nodes', 2)
    mesh_case('mesh%s_second_elements' % fmt, good + good[good.index('$Elements'):],
              ['second $Elements section'], '$Elements', 2)
    for tag, t in (('12', [(1, 1, 3, 4), (2, 3, 4, 5)]), ('34', [(1, 2, 3, 4), (2, 3, 5, 5)])):
        text = writer(t=t)
        node = t[0][0] if tag == '12' else 5
        mesh_case('mesh%s_repeated_node_%s' % (fmt, tag), text, ['degenerate', 'node %d is repeated' % node])
    for tag, v in (('1e200', 1e200), ('neg1e300', -1e300), ('2e9', 2e9)):
        x = list(M_X)
        x[2] = (0.0, v, 0.0)
        text = writer(x=x)
        mesh_case('mesh%s_coordinate_%s' % (fmt, tag), text, ['node coordinate', 'out of range', '1e9'])
# a physical volume tag beyond the bodies &system velocity can name
mesh_case('mesh22_physical_17', msh22(phys=(17, 17)), ['physical volume tag 17', '1..16'])
mesh_case('mesh41_physical_17', msh41(vol_phys='1 17'), ['physical volume tag 17', '1..16'])
mesh_case('mesh22_physical_0_and_1', msh22(phys=(0, 1)), ['no physical volume', 'tag 0'])
# MSH 4.1: the volume's physical tags come from $Entities
mesh_case('mesh41_entity_unknown', msh41(block_entity=9), ['volume entity 9', 'not in the $Entities'])
mesh_case('mesh41_two_physical', msh41(vol_phys='2 1 2'), ['volume entity 1', 'several physical volumes'])
mesh_case('mesh41_entities_count', msh41().replace('$Entities\n1 0 0 1', '$Entities\n1 0 0 999999999'),
          ['$Entities declares 999999999', 'can hold'], '1 0 0 999999999')
mesh_case('mesh41_node_blocks_huge', msh41(nodes_head='999999999 5 1 5'), ['$Nodes declares blocks: 999999999',
                                                                        'can hold'], '999999999 5')

# ------------------------------------------------------------------ the newer groups' reals
# Every real key of &thermostat (each style), &barostat, &minimize, the stepped potentials, the
# mesh and &output progress_seconds through the same finite-and-range check: two of the six bad
# values per key, rotating, so that each value meets every group.
NVT = {st: dict(LJ, thermostat="style='%s', temperature=1.0, damping=0.5" % st)
       for st in ('langevin', 'csvr', 'nose_hoover', 'andersen')}
ES_T = {st: dict(ES, thermostat="style='%s', temperature=1.0, %s" % (st, extra))
        for st, extra in (('csvr', 'damping=0.5, interval=0.1'), ('andersen', 'damping=0.5'))}
NPT = dict(NVT['csvr'], barostat="style='c_rescale', pressure=1.0, damping=5.0, compressibility=0.1")
ES_MC = dict(ES_T['andersen'], barostat="style='mc', pressure=1.0, interval=0.5")
MIN = dict(LJ, minimize="style='cg', etol=1e-8, ftol=1e-8")
MIN_BOX = dict(LJ, minimize="style='cg', etol=1e-8, ftol=1e-8, box_relax='iso', pressure=0.0")
ED = dict(LJ, run="units='lj', dimension=3, run_time=1.0, seed=1",
          system="lattice='fcc', density=0.5, cells=3,3,3, mass=1.0, temperature=1.0",
          potential="style='hard_sphere', diameter=1.0", integrator="style='event_driven'", neighbor=None,
          output="thermo_interval=0.5, thermo_file='thermo.csv', forces_file='forces.txt'")
SW = dict(ED, potential="style='square_well', diameter=1.0, well_depth=1.0, well_lambda=1.5")
SW_R = dict(ED, potential="style='square_well', diameter=1.0, well_depth=1.0, well_radius=1.5")
MESH2 = dict(MESH, system="mesh_file='in.msh', mass_density=1000.0, periodic=.false.,.false.,.false., "
                          "velocity(:,1)=1.0,0.0,0.0, angular_velocity(:,1)=0.0,0.0,1.0",
             potential="style='neohookean', lambda=1.0e6, mu=1.0e6, contact_stiffness=1.0e4, contact_distance=0.1")
newer_keys = [
    ('thermostat', 'temperature', NVT['langevin'], 'langevin'), ('thermostat', 'damping', NVT['langevin'], 'langevin'),
    ('thermostat', 'temperature', NVT['csvr'], 'csvr'), ('thermostat', 'damping', NVT['csvr'], 'csvr'),
    ('thermostat', 'temperature_end', NVT['csvr'], 'csvr'),
    ('thermostat', 'temperature', NVT['nose_hoover'], 'nh'), ('thermostat', 'damping', NVT['nose_hoover'], 'nh'),
    ('thermostat', 'temperature', NVT['andersen'], 'andersen'),
    ('thermostat', 'damping', NVT['andersen'], 'andersen'),
    ('thermostat', 'interval', ES_T['csvr'], 'es_csvr'), ('thermostat', 'damping', ES_T['andersen'], 'es_andersen'),
    ('barostat', 'pressure', NPT, 'c_rescale'), ('barostat', 'damping', NPT, 'c_rescale'),
    ('barostat', 'compressibility', NPT, 'c_rescale'), ('barostat', 'pressure', ES_MC, 'mc'),
    ('barostat', 'interval', ES_MC, 'mc'),
    ('minimize', 'etol', MIN, 'cg'), ('minimize', 'ftol', MIN, 'cg'), ('minimize', 'pressure', MIN_BOX, 'box'),
    ('potential', 'diameter', ED, 'hs'), ('potential', 'well_depth', SW, 'sw'),
    ('potential', 'well_lambda', SW, 'sw'), ('potential', 'well_radius', SW_R, 'sw'),
    ('output', 'thermo_interval', ED, 'ed'),
    ('potential', 'lambda', MESH2, 'mesh'), ('potential', 'mu', MESH2, 'mesh'),
    ('system', 'mass_density', MESH2, 'mesh'), ('potential', 'contact_stiffness', MESH2, 'mesh'),
    ('potential', 'contact_distance', MESH2, 'mesh'), ('system', 'velocity(:,1)', MESH2, 'mesh'),
    ('system', 'angular_velocity(:,1)', MESH2, 'mesh'), ('output', 'progress_seconds', LJ, 'lj'),
]
for i, (group, key, base, tag) in enumerate(newer_keys):
    for tag_v, value, what in (bad_reals[i % 6], bad_reals[(i + 3) % 6]):
        name = 'real_%s_%s_%s_%s' % (group[:4], tag, re.sub(r'\W', '', key.split('(')[0]), tag_v)
        if ':,' in key:
            value = '%s,0.0,0.0' % value
        groups = with_key(group, '%s=%s' % (key, value), base)
        files = {'in.msh': msh22(phys=(1, 2))} if base is MESH2 else None
        case(name, ['%s.nml:%d' % (name, line_in(groups, group)), '&' + group, key.split('(')[0],
                    value.split(',')[0], what], groups=groups, files=files)

# ------------------------------------------------------------------ run-away schedules, run-time failures
# Energy stepping counted in events (n_steps, no run_time to bound the schedule by): a calendar
# interval far below the time the atoms need to move ends window after window with no event; the
# run stops with the key after 1000 such windows. Velocity Verlet: an interval below half a step.
ES_N = dict(ES, run="units='lj', dimension=3, n_steps=100, seed=1")
for tag, groups, key in [
        ('thermo', dict(ES_N, output=ES_N['output'].replace('thermo_every=5', 'thermo_interval=1e-20')),
         'thermo_interval'),
        ('thermo_1e-29', dict(ES_N, output=ES_N['output'].replace('thermo_every=5', 'thermo_interval=1e-29')),
         'thermo_interval'),
        ('andersen', dict(ES_N, thermostat="style='andersen', temperature=1.0, damping=1e-21"), '&thermostat'),
        ('csvr', dict(ES_N, thermostat="style='csvr', temperature=1.0, damping=0.5, interval=1e-22"), '&thermostat'),
        ('mc', dict(ES_N, thermostat="style='andersen', temperature=1.0, damping=0.5",
                    barostat="style='mc', pressure=1.0, interval=1e-22"), '&barostat interval')]:
    case('runaway_es_events_' + tag, [key, 'windows in a row', 'would not finish'], groups=groups)
MC_RT = dict(ES, run="units='lj', dimension=3, run_time=1.0, seed=1",
             thermostat="style='andersen', temperature=1.0, damping=0.5",
             barostat="style='mc', pressure=1.0, interval=1e-25")
case('runaway_es_mc_run_time', ['runaway_es_mc_run_time.nml:%d' % line_in(MC_RT, 'barostat'), '&barostat',
                                'interval', 'volume moves', 'would not finish'], groups=MC_RT)
for key in ('thermo_interval', 'trajectory_interval', 'checkpoint_interval'):
    extra = {'trajectory_interval': ", trajectory_file='t.h5'", 'checkpoint_interval': ", checkpoint_file='c.h5'"}
    out = LJ['output'].replace('thermo_every=5', '') + extra.get(key, '') + ', %s=1e-20' % key
    case('runaway_vv_%s_below_dt' % key, ['&output', key, 'shorter than half a time step', 'dt/2'],
         groups=dict(LJ, output=out.lstrip(', ')))
# two tetrahedra 2 m apart, bodies 1 and 2; body 2 thrown at body 1
TWO_X = [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (3, 0, 0), (4, 0, 0), (3, 1, 0), (3, 0, 1)]
TWO = msh22(x=TWO_X, t=[(1, 2, 3, 4), (5, 6, 7, 8)], phys=(1, 2))
THROWN = dict(MESH, run="units='si', dimension=3, n_steps=3000, seed=1",
              system="mesh_file='in.msh', mass_density=1000.0, periodic=.false.,.false.,.false., "
                     "velocity(:,2)=-2000.0,0.0,0.0",
              potential="style='neohookean', lambda=1.0e6, mu=1.0e6, contact_stiffness=1.0e13")
case('runtime_contact_thrown_stiff', ['turned inside out', '&integrator dt', 'step'], groups=THROWN,
     files={'in.msh': TWO})
case('runtime_contact_skin_stretch', ['stretched', '&neighbor skin', 'beyond the'],
     groups=dict(THROWN, potential="style='neohookean', lambda=1.0e6, mu=1.0e6, contact_stiffness=1.0e4",
                 system=THROWN['system'].replace('-2000.0', '-20.0'), neighbor='skin=1.0'),
     files={'in.msh': TWO})

with open(os.path.join(OUT, 'cases.txt'), 'w') as f:
    f.write('# generated by generate_hostile.py: name | exit | arguments | substrings\n')
    f.write('\n'.join(manifest) + '\n')
print(len(manifest))
