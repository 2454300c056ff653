#!/usr/bin/python3
"""FEBio's closed valve against mvtwin's, for the same exported scene (docs/febio-export.md).

    scripts/experiments/febio_compare.py DIR/febio_nodes.txt R.h5 [R2.h5 ...]

DIR is `mvtwin export-model P.h5 --out DIR`, run there by `febio4 -i valve.feb`; R.h5 is
`mvtwin simulate P.h5 --out R.h5` (any settings: one line per file). febio_nodes.txt holds, at
every converged step, one line per node of mvtwin's model in mvtwin's order; its last step is
compared with R.h5's `final/final_positions` (the corner nodes):
  - node-wise: the same material point's distance, mean / 95th percentile / max, over all
    corner nodes and per leaflet (a node of both leaflets' elements counts as anterior);
  - surfaces: symmetric point-to-surface distance between the two boundaries of the corner
    tetrahedra (each node of one against the other's triangles), mean / max.
Needs Debian's python3 with h5py and numpy.
"""
import sys

import h5py
import numpy as np


def febio_last_step(path):
    """The positions of the last complete step of a FEBio node_data log (id x y z lines)."""
    steps, current = [], None
    with open(path) as f:
        for line in f:
            if line.startswith("*Step"):
                current = []
                steps.append(current)
            elif line.startswith("*") or not line.strip():
                continue
            elif current is not None:
                v = line.replace(",", " ").split()
                current.append([float(x) for x in v[1:4]])
    if not steps:
        raise SystemExit(f"{path}: no step logged")
    n = max(len(s) for s in steps)
    last = [s for s in steps if len(s) == n][-1]
    return np.array(last), len(steps)


def boundary_faces(tets):
    faces = {}
    for t in tets:
        for f in ((t[0], t[1], t[2]), (t[0], t[1], t[3]), (t[0], t[2], t[3]), (t[1], t[2], t[3])):
            key = tuple(sorted(f))
            faces[key] = faces.get(key, 0) + 1
    return np.array([k for k, c in faces.items() if c == 1])


def point_triangle_distance(p, a, b, c):
    """Distance of each point p (n, 3) to every triangle (m, 3 each): (n, m), vectorized
    (Ericson's closest point on a triangle)."""
    p = p[:, None, :]
    ab, ac, ap = b - a, c - a, p - a
    d1, d2 = (ab * ap).sum(-1), (ac * ap).sum(-1)
    bp = p - b
    d3, d4 = (ab * bp).sum(-1), (ac * bp).sum(-1)
    cp = p - c
    d5, d6 = (ab * cp).sum(-1), (ac * cp).sum(-1)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    denom = va + vb + vc
    with np.errstate(divide="ignore", invalid="ignore"):
        v = vb / denom
        w = vc / denom
        q = a + ab * v[..., None] + ac * w[..., None]  # interior
        # edges and corners
        cand = [q]
        for s, e in ((a, b), (a, c), (b, c)):
            se = e - s
            t = np.clip(((p - s) * se).sum(-1) / (se * se).sum(-1), 0, 1)
            cand.append(s + se * t[..., None])
    inside = (va >= 0) & (vb >= 0) & (vc >= 0) & (denom > 0)
    d = np.full(inside.shape, np.inf)
    d = np.where(inside, np.linalg.norm(p - cand[0], axis=-1), d)
    for k in range(1, 4):
        d = np.minimum(d, np.linalg.norm(p - cand[k], axis=-1))
    return d


def surface_distance(points, x, faces):
    a, b, c = x[faces[:, 0]], x[faces[:, 1]], x[faces[:, 2]]
    out = []
    for chunk in np.array_split(points, max(1, len(points) // 200)):
        out.append(point_triangle_distance(chunk, a, b, c).min(axis=1))
    return np.concatenate(out)


def stats(d):
    return f"{d.mean():.3f} / {np.percentile(d, 95):.3f} / {d.max():.3f}"


def main():
    if len(sys.argv) < 3:
        raise SystemExit(__doc__)
    fe_all, nsteps = febio_last_step(sys.argv[1])
    for path in sys.argv[2:]:
        with h5py.File(path, "r") as f:
            x = f["final/final_positions"][()]
            tets = f["final/tets"][()]
            tag = f["final/tag"][()]
        fe = fe_all[: len(x)]
        anterior = np.zeros(len(x), bool)
        anterior[np.unique(tets[tag == tag.min()])] = True
        d = np.linalg.norm(fe - x, axis=1)
        faces = boundary_faces(tets)
        s1 = surface_distance(x[np.unique(faces)], fe, faces)
        s2 = surface_distance(fe[np.unique(faces)], x, faces)
        s = np.concatenate([s1, s2])
        print(f"{path} (FEBio: {nsteps} steps logged)\n"
              f"  node-wise mean / p95 / max mm: all {stats(d)}; anterior {stats(d[anterior])};"
              f" posterior {stats(d[~anterior])}\n"
              f"  surfaces, symmetric point-to-surface mean / max mm: {s.mean():.3f} / {s.max():.3f}")


if __name__ == "__main__":
    main()
