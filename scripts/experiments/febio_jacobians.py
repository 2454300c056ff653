#!/usr/bin/python3
"""Where FEBio's elements collapse: the exported quadratic tetrahedra's Jacobian at FEBio's last
logged step against the reference, lowest first, with each element's leaflet and its distance to
the nearest chorda end point and to the nearest prescribed (annulus) node (docs/febio-export.md).

    scripts/experiments/febio_jacobians.py DIR

DIR is `mvtwin export-model P.h5 --out DIR`, run there by `febio4 -i valve.feb`. The Jacobian
ratio det(J) / det(J0) is taken at the 4 corners and the centroid of each tet10 (VTK node order).
Needs Debian's python3 with numpy.
"""
import os
import re
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from febio_compare import febio_last_step  # noqa: E402


def data_array(text, name):
    m = re.search(r'<DataArray[^>]*Name="%s"[^>]*>(.*?)</DataArray>' % name, text, re.S)
    return np.array(m.group(1).split(), float)


def points(text):
    m = re.search(r"<Points>\s*<DataArray[^>]*>(.*?)</DataArray>", text, re.S)
    return np.array(m.group(1).split(), float).reshape(-1, 3)


def tet10_gradients(r, s, t):
    L = [1 - r - s - t, r, s, t]
    dL = np.array([[-1, -1, -1], [1, 0, 0], [0, 1, 0], [0, 0, 1]], float)
    d = np.zeros((10, 3))
    for i in range(4):
        d[i] = (4 * L[i] - 1) * dL[i]
    for k, (a, b) in enumerate([(0, 1), (1, 2), (0, 2), (0, 3), (1, 3), (2, 3)]):
        d[4 + k] = 4 * (L[a] * dL[b] + L[b] * dL[a])
    return d


def main():
    if len(sys.argv) != 2:
        raise SystemExit(__doc__)
    folder = sys.argv[1]
    mesh = open(os.path.join(folder, "leaflets_quadratic.vtu")).read()
    conn = data_array(mesh, "connectivity").astype(int).reshape(-1, 10)
    tag = data_array(mesh, "tag").astype(int)
    prescribed = data_array(mesh, "prescribed").astype(int) == 1
    X = points(mesh)
    x, steps = febio_last_step(os.path.join(folder, "febio_nodes.txt"))
    x = x[: len(X)]
    grads = [tet10_gradients(*p) for p in [(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1), (0.25,) * 3]]
    ratio = np.array([min(np.linalg.det(x[c].T @ d) / np.linalg.det(X[c].T @ d) for d in grads)
                      for c in conn])
    chord_ends = points(open(os.path.join(folder, "chordae.vtp")).read())
    print(f"{folder}: {steps} steps logged; elements with ratio < 0.5: {(ratio < 0.5).sum()}")
    print("ratio  leaflet    to a chorda end, mm  to the annulus, mm")
    for e in np.argsort(ratio)[:12]:
        c = X[conn[e]].mean(axis=0)
        print(f"{ratio[e]:.3f}  {'anterior ' if tag[e] == 1 else 'posterior'}  "
              f"{np.linalg.norm(chord_ends - c, axis=1).min():19.2f}  "
              f"{np.linalg.norm(X[prescribed] - c, axis=1).min():18.2f}")


if __name__ == "__main__":
    main()
