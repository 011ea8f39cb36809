#!/usr/bin/env python3
"""Meshes as Gmsh writes them: the right bodies get the right rigid velocities.

usage: gmsh_bodies.py TERRACE OUTDIR NPROCS

Reads the Gmsh-written files of tests/regression/gmsh/ (make_gmsh_meshes.py: a 2 m cube in
physical volume 1, two unit cubes, two volume entities, in physical volume 2, with physical
surfaces, a curve and a point; and the same geometry without physical groups), in MSH 4.1 and 2.2.
When the gmsh Python package is there it also writes them anew with it and reads those. Each file
runs one step (mass_density 1000 kg/m^3) with &system velocity given to one body, and the step-0
thermo row must hold exactly that body's kinetic energy and momentum:
  velocity(:,1) = 1,0,0   KE = 1/2 rho 8 m^3 = 4000 J, px = 8000 kg m/s   (the big cube only)
  velocity(:,2) = 0,1,0   KE = 1/2 rho 2 m^3 = 1000 J, py = 2000 kg m/s   (both unit cubes)
  both                    KE = 5000 J
  no physical groups: one body, velocity(:,1) = 1,0,0: KE = 1/2 rho 10 m^3 = 5000 J, px = 10000
(relative tolerance 1e-9: the tetrahedra fill the boxes exactly). A reader that took the volume
entity tag for the body (entity 1 is a unit cube) or skipped an entity of a group fails.
"""
import csv
import os
import shutil
import subprocess
import sys

here = os.path.dirname(os.path.abspath(__file__))
RHO = 1000.0
DECK = """&run units='si', dimension=3, n_steps=1, seed=1 /
&system mesh_file='{mesh}', mass_density={rho}, periodic=.false.,.false.,.false.{vel} /
&potential style='neohookean', lambda=1.0e6, mu=1.0e6 /
&integrator style='velocity_verlet', dt=1.0e-7 /
&output thermo_every=1, thermo_file='thermo.csv' /
"""
CASES = {  # name: (velocity keys, KE, (px, py, pz))
    'body1': (', velocity(:,1) = 1.0,0.0,0.0', 0.5 * RHO * 8, (RHO * 8, 0, 0)),
    'body2': (', velocity(:,2) = 0.0,1.0,0.0', 0.5 * RHO * 2, (0, RHO * 2, 0)),
    'both': (', velocity(:,1) = 1.0,0.0,0.0, velocity(:,2) = 0.0,1.0,0.0', 0.5 * RHO * 10, (RHO * 8, RHO * 2, 0)),
}
ONE_BODY = {'one': (', velocity(:,1) = 1.0,0.0,0.0', 0.5 * RHO * 10, (RHO * 10, 0, 0))}


def fail(msg):
    print('FAIL ' + msg)
    sys.exit(1)


def close(a, b):
    return abs(a - b) <= 1e-9 * max(1.0, abs(b))


def run_case(terrace, np_, d, mesh, vel):
    os.makedirs(d)
    with open(os.path.join(d, 'run.nml'), 'w') as f:
        f.write(DECK.format(mesh=mesh, rho=RHO, vel=vel))
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT='1', OMPI_ALLOW_RUN_AS_ROOT_CONFIRM='1')
    cmd = ([terrace] if np_ == 1 else ['mpirun', '--oversubscribe', '-np', str(np_), terrace]) + ['run.nml']
    p = subprocess.run(cmd, cwd=d, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
    if p.returncode != 0:
        fail('%s in %s: exit %d:\n%s' % (mesh, d, p.returncode, p.stdout[-2000:]))
    with open(os.path.join(d, 'thermo.csv')) as f:
        row = next(r for r in csv.DictReader(f) if int(r['step']) == 0)
    return float(row['ke']), tuple(float(row[k]) for k in ('px', 'py', 'pz'))


def check_dir(terrace, np_, src, out, label):
    n = 0
    for stem, cases in (('two_bodies', CASES), ('no_physical', ONE_BODY)):
        for fmt in ('41', '22'):
            mesh = os.path.join(src, '%s_%s.msh' % (stem, fmt))
            if not os.path.isfile(mesh):
                fail('%s: missing' % mesh)
            for name, (vel, ke_want, p_want) in cases.items():
                ke, p = run_case(terrace, np_, os.path.join(out, label, '%s_%s_%s' % (stem, fmt, name)), mesh, vel)
                if not close(ke, ke_want) or not all(close(a, b) for a, b in zip(p, p_want)):
                    fail('%s (%s files), %s: KE %.12g J and momentum %s, expected %.12g J and %s'
                         % (os.path.basename(mesh), label, vel.strip(', '), ke, p, ke_want, p_want))
                n += 1
    return n


def main():
    if len(sys.argv) != 4:
        fail(__doc__)
    terrace, out, np_ = os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2]), int(sys.argv[3])
    shutil.rmtree(out, ignore_errors=True)
    n = check_dir(terrace, np_, os.path.join(here, 'gmsh'), out, 'committed')
    note = 'the gmsh package is not installed: the committed Gmsh 4.15.2 files only'
    for py in dict.fromkeys([sys.executable, shutil.which('python3') or sys.executable]):
        v = subprocess.run([py, '-c', 'import gmsh; print(gmsh.__version__)'], stdout=subprocess.PIPE,
                           stderr=subprocess.DEVNULL, text=True)
        if v.returncode != 0:
            continue
        fresh = os.path.join(out, 'fresh_meshes')
        subprocess.run([py, os.path.join(here, 'gmsh', 'make_gmsh_meshes.py'), fresh], check=True)
        n += check_dir(terrace, np_, fresh, out, 'fresh')
        note = 'and the same files written anew by gmsh %s' % v.stdout.strip()
        break
    print('PASS gmsh_bodies on %d rank(s): %d runs of Gmsh-written MSH 4.1 and 2.2 meshes (physical volumes, '
          'surfaces, curves, points; and none), each body with its own velocity, kinetic energy and momentum '
          'exact (%s)' % (np_, n, note))


if __name__ == '__main__':
    main()
