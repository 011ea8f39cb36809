#!/usr/bin/env python3
"""Meshes written by Gmsh itself (its Python package, `pip install gmsh`) for gmsh_bodies.py.

usage: make_gmsh_meshes.py OUT_DIR

Three boxes meshed with tetrahedra: two unit cubes (volume entities 1 and 2, at x = 0..1 and
2..3) and a 2 m cube (entity 3, at x = 4..6); 1 m gaps between them. Physical groups as a user
makes them: physical volume 1 = entity 3 (the big cube: the physical tag is not the entity tag),
physical volume 2 = entities 1 and 2 (two entities, one body), physical surfaces (the big cube's
faces, tag 5; a small cube's faces, tag 6), a physical curve (tag 8) and a physical point (tag 7),
so that the files also hold triangles, lines and points. Written as
  two_bodies_41.msh, two_bodies_22.msh   Gmsh's MSH 4.1 and 2.2 (only the physical groups' elements)
  no_physical_41.msh, no_physical_22.msh the same geometry without any physical group (every
                                         element saved; MSH 2.2 writes physical tag 0)
The files in this directory were written so with gmsh 4.15.2 (the test reads them, and writes and
reads them again when the gmsh package is there).
"""
import os
import sys

import gmsh


def build(physical):
    gmsh.model.add('three_boxes')
    a = gmsh.model.occ.addBox(0, 0, 0, 1, 1, 1)
    b = gmsh.model.occ.addBox(2, 0, 0, 1, 1, 1)
    c = gmsh.model.occ.addBox(4, 0, 0, 2, 2, 2)
    gmsh.model.occ.synchronize()
    if physical:
        gmsh.model.addPhysicalGroup(3, [c], 1, name='big')
        gmsh.model.addPhysicalGroup(3, [a, b], 2, name='small')
        big_faces = [t for _, t in gmsh.model.getBoundary([(3, c)], oriented=False)]
        small_faces = [t for _, t in gmsh.model.getBoundary([(3, a)], oriented=False)]
        gmsh.model.addPhysicalGroup(2, big_faces, 5, name='big_surface')
        gmsh.model.addPhysicalGroup(2, small_faces, 6, name='small_surface')
        gmsh.model.addPhysicalGroup(0, [1], 7, name='corner')
        gmsh.model.addPhysicalGroup(1, [1], 8, name='edge')
    gmsh.option.setNumber('Mesh.MeshSizeMax', 0.7)
    gmsh.model.mesh.generate(3)


def main():
    out = sys.argv[1]
    os.makedirs(out, exist_ok=True)
    gmsh.initialize(['gmsh', '-nopopup'])
    gmsh.option.setNumber('General.Terminal', 0)
    for physical, stem in ((True, 'two_bodies'), (False, 'no_physical')):
        build(physical)
        for version in ('4.1', '2.2'):
            gmsh.option.setNumber('Mesh.MshFileVersion', float(version))
            gmsh.write(os.path.join(out, '%s_%s.msh' % (stem, version.replace('.', ''))))
        gmsh.model.remove()
    gmsh.finalize()


if __name__ == '__main__':
    main()
