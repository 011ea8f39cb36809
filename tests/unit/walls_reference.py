#!/usr/bin/env python3
"""The wall energy of test_walls.pf's state, computed independently with numpy: a 2 x 2 x 2 block of
unit cubes (node id 1 + i + 3 j + 9 k at (i, j, k)), every node but the centre on the boundary,
x = xref + 0.08 (sin 1.3 i, cos 2.1 i, sin(0.7 i + 1)) for node id i; three planes (point, normal);
V = sum over boundary nodes and planes with d < d0 of k/2 (d0 - d)^2, d = n.(x - q), n unit.
usage: python3 tests/unit/walls_reference.py   (prints V to 17 digits)"""
import numpy as np

k, d0 = 3.0e4, 0.6
ids = np.arange(1, 28)
ijk = np.array([((i - 1) % 3, ((i - 1) // 3) % 3, (i - 1) // 9) for i in ids], float)
x = ijk + 0.08 * np.stack([np.sin(1.3 * ids), np.cos(2.1 * ids), np.sin(0.7 * ids + 1)], axis=1)
boundary = ~np.all(ijk == 1, axis=1)
planes = np.array([[0.3, 0, 0, 2, 0, 0], [0.4, 0.4, 0.4, 1, 1, 1], [0, 0, 1.9, 0, 0, -1]], float)
v = 0.0
for p in planes:
    n = p[3:] / np.linalg.norm(p[3:])
    d = (x[boundary] - p[:3]) @ n
    v += np.sum(0.5 * k * (d0 - d[d < d0]) ** 2)
print(f"{v:.17g}")
