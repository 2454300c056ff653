#!/usr/bin/env python3
"""Measure (issue 39): where a flail's torn segment ends in the closed valve. For each posterior
column of the result's last sample, the free edge's height above the annulus plane (+ = atrial) and
its distance to the facing anterior column (u and ures - u); the columns inside the torn range are
marked. docs/virtual-patients.md, "Severity as the clinic sees it", reads it: segments that leak
evert (edges 4-8 mm above the plane), the others rest on the anterior leaflet's atrial face.

    scripts/experiments/flail_sections.py PATIENT.h5 RESULT.h5

PATIENT.h5 is the virtual patient (its /sequence/ruptured_chordae), RESULT.h5 what
`mvtwin simulate PATIENT.h5 --out RESULT.h5` wrote. Needs h5py and numpy (Debian: python3-h5py).
"""
import sys

import h5py
import numpy as np


def main(patient_path, result_path):
    with h5py.File(patient_path, "r") as p, h5py.File(result_path, "r") as r:
        if "sequence/ruptured_chordae" not in p:
            sys.exit(f"{patient_path}: no torn chordae (/sequence/ruptured_chordae)")
        torn = p["sequence/ruptured_chordae"][()]
        surface = np.asarray(r["samples/la_surface"][-1])  # (vres, ures, 3)
        eroa = r["orifice/eroa_mm2"][()]
    annulus = surface[0]
    centre = annulus.mean(axis=0)
    normal = np.linalg.svd(annulus - centre)[2][2]
    if ((surface[surface.shape[0] // 2] - centre) @ normal).mean() > 0:
        normal = -normal  # the leaflets hang below the plane: + points to the atrium
    ures = surface.shape[1]
    print(f"{result_path}: EROA {eroa:.1f} mm^2; torn s in "
          + ", ".join(f"[{a:.3f}, {b:.3f})" for a, b in torn))
    for u in range(ures // 2, ures):
        s = u / ures
        inside = any(a <= s < b for a, b in torn)
        edge = surface[-1, u]
        height = (edge - centre) @ normal
        facing = surface[:, (ures - u) % ures]
        distance = np.min(np.linalg.norm(facing - edge, axis=1))
        print(f"  u {u:3d}  s {s:.3f}  {'torn' if inside else '    '}  edge {height:+6.1f} mm"
              f"  to the anterior leaflet {distance:5.1f} mm")


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
