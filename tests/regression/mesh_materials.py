#!/usr/bin/env python3
"""Materials of mesh volumes (&potential volume_lambda(v), volume_mu(v)) reach the right elements.

usage: mesh_materials.py TERRACE OUTDIR NPROCS

The Gmsh-written mesh tests/regression/gmsh/two_bodies_22.msh holds three separate boxes: a 2 m cube
(volume entity 3, physical volume 1) and two unit cubes (entities 1 and 2, physical volume 2). Every
body spins about its centre; no box touches another within the run. Velocity Verlet, 150 steps:
  R1  lambda = 1e6, mu = 1e6 everywhere;
  R2  lambda = 1e7, mu = 2e7 everywhere;
  R3  lambda = 1e6, mu = 1e6 with volume_lambda(2) = 1e7, volume_mu(2) = 2e7;
  R4  lambda = 1e6, mu = 1e6 with volume_lambda(3) = 1e6, volume_mu(3) = 1e6 (the default again).
The boxes share no node, so each moves under its own elements only: R3's nodes of entity 2 must
end where R2's do and all its other nodes where R1's do, bitwise (a node sums its elements' forces
in element order on any rank count); R4 must equal R1 bitwise; and entity 2's nodes must move
differently in R1 and R2 (by more than 1e-4 m), so that a reader that ignored the volume keys, or
gave the material to another entity, fails. Energy stepping with R3's materials (h = 0.05 J, 5 ms): the
run ends and max |E - E0| <= h.
"""
import csv
import os
import shutil
import subprocess
import sys

here = os.path.dirname(os.path.abspath(__file__))
MESH = os.path.join(here, 'gmsh', 'two_bodies_22.msh')
DECK = """&run units='si', dimension=3, {length}, seed=1 /
&system mesh_file='mesh.msh', mass_density=1000.0, periodic=.false.,.false.,.false.,
        angular_velocity(:,1) = 0.0,0.0,5.0, angular_velocity(:,2) = 0.0,3.0,4.0 /
&potential style='neohookean', {material} /
&integrator {integrator} /
&output thermo_every={every}, thermo_file='thermo.csv', final_atoms_file='final.txt' /
"""
SOFT = 'lambda=1.0e6, mu=1.0e6'
STIFF = 'lambda=1.0e7, mu=2.0e7'
VERLET = ("n_steps=150", "style='velocity_verlet', dt=1.0e-4", 10)
H = 0.05


def fail(msg):
    print('FAIL ' + msg)
    sys.exit(1)


def run(terrace, np_, d, material, kind=VERLET):
    os.makedirs(d)
    shutil.copy(MESH, os.path.join(d, 'mesh.msh'))
    with open(os.path.join(d, 'run.nml'), 'w') as f:
        f.write(DECK.format(length=kind[0], integrator=kind[1], every=kind[2], material=material))
    env = dict(os.environ, OMPI_ALLOW_RUN_AS_ROOT='1', OMPI_ALLOW_RUN_AS_ROOT_CONFIRM='1')
    cmd = ([terrace] if np_ == 1 else ['mpirun', '--oversubscribe', '-np', str(np_), terrace]) + ['run.nml']
    p = subprocess.run(cmd, cwd=d, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=300)
    if p.returncode != 0:
        fail('%s: exit %d:\n%s' % (d, p.returncode, p.stdout[-2000:]))
    pos = {}
    for line in open(os.path.join(d, 'final.txt')):        # type x y z vx vy vz, one line per node in id order
        t = line.split()
        if not t or line.startswith('#'):
            continue
        pos[len(pos) + 1] = tuple(float(v) for v in t[1:4])
    with open(os.path.join(d, 'thermo.csv')) as f:
        e = [float(r['etotal']) for r in csv.DictReader(f)]
    return pos, e


def entity_nodes(path, entity):
    text = open(path).read().split('$Elements\n')[1].split('$EndElements')[0].split('\n')
    nodes = set()
    for line in text[1:int(text[0]) + 1]:
        t = [int(v) for v in line.split()]
        if t[1] == 4 and t[2] >= 2 and t[4] == entity:
            nodes.update(t[3 + t[2]:7 + t[2]])
    return nodes


def main():
    terrace, out, np_ = os.path.abspath(sys.argv[1]), sys.argv[2], int(sys.argv[3])
    shutil.rmtree(out, ignore_errors=True)
    os.makedirs(out)
    two = entity_nodes(MESH, 2)
    if not two or not entity_nodes(MESH, 3):
        fail('the mesh has no tetrahedra in volume entities 2 and 3')
    r1, _ = run(terrace, np_, os.path.join(out, 'r1'), SOFT)
    r2, _ = run(terrace, np_, os.path.join(out, 'r2'), STIFF)
    r3, _ = run(terrace, np_, os.path.join(out, 'r3'), SOFT + ', volume_lambda(2)=1.0e7, volume_mu(2)=2.0e7')
    r4, _ = run(terrace, np_, os.path.join(out, 'r4'), SOFT + ', volume_lambda(3)=1.0e6, volume_mu(3)=1.0e6')
    spread = max(max(abs(a - b) for a, b in zip(r1[i], r2[i])) for i in two)
    if not spread > 1e-4:
        fail('entity 2 moves the same with both materials (largest difference %.3g m): the test cannot tell' % spread)
    bad = [i for i in r3 if r3[i] != (r2[i] if i in two else r1[i])]
    if bad:
        i = bad[0]
        fail('R3: %d nodes not where the one-material runs put them (node %d: %s, expected %s)'
             % (len(bad), i, r3[i], r2[i] if i in two else r1[i]))
    if r4 != r1:
        fail('R4 (volume 3 given the default material) differs from R1')
    _, e = run(terrace, np_, os.path.join(out, 'es'), SOFT + ', volume_lambda(2)=1.0e7, volume_mu(2)=2.0e7',
               ("run_time=0.005", "style='energy_stepping', terrace_height=%r" % H, 1))
    de = max(abs(x - e[0]) for x in e)
    if not de <= H * (1 + 1e-9):
        fail('energy stepping with two materials: max |E - E0| = %.3g J > h = %g J' % (de, H))
    print('ok: %d ranks; entity 2 (%d nodes) moves with volume 2\'s material (R1 vs R2 differ by up to %.3g m), the '
          'rest with the default, bitwise; energy stepping max |E - E0| = %.3g J <= h over %d thermo rows'
          % (np_, len(two), spread, de, len(e)))


if __name__ == '__main__':
    main()
