#!/usr/bin/env python3
"""Prototype (issue 39): a virtual patient's marginal chordae lengths tuned to its own simulated
closure, so that a normal valve closes. Not part of the generator yet; docs/virtual-patients.md,
"Chordae tuned to the simulated closure", gives the rule and what it measured.

    scripts/experiments/tune_chordae.py PATIENT.h5 OUT.h5 [--iterations 8] [--gain 1.0]
        [--reach 2.5] [--low 0.9] [--high 1.3] [--mvtwin build/release/tools/mvtwin]

Each iteration simulates OUT.h5 at the paper's grid (mvtwin simulate, the hidden parameters) and
reads the closed valve's regurgitant orifice (/orifice: per leaflet column its narrowest gap to
the other leaflet and the two closest points). Where a column is open (gap above the 0.6 mm seal),
the chordae of its leaflet within `reach` insertion sites (of the 28) are lengthened if the other
leaflet lies above it (it must rise) and shortened if below, by gain x (gap - seal, at most 3 mm)
x a tent weight over the sites; every length stays within [low, high] x the patient's own
(/sequence/marginal_chordae_lengths). Needs h5py and numpy (Debian: python3-h5py).
"""
import argparse
import re
import shutil
import subprocess
import sys

import h5py
import numpy as np

SEAL_MM = 0.6


def simulate(mvtwin, patient, result):
    run = subprocess.run([mvtwin, "simulate", patient, "--out", result, "--force", "--set",
                          "threads=1"], capture_output=True, text=True)
    found = re.search(r"EROA ([0-9.]+) mm\^2", run.stdout)
    return float(found.group(1)) if found else None, run.stdout


def length_changes(result, sites, reach, gain):
    with h5py.File(result, "r") as r:
        o = r["orifice"]
        pos, gap = o["column_position"][:], o["column_gap_mm"][:]
        anterior, points = o["column_anterior"][:], o["column_points"][:]
        first = r["samples/la_surface"][0]
        last = r["samples/la_surface"][-1]
    annulus = first[0]
    centre = annulus.mean(0)
    normal = np.linalg.svd(annulus - centre)[2][2]
    if ((last[-1] - centre) @ normal).mean() > 0:
        normal = -normal  # towards the atrium: the closed free edges lie below the annulus
    delta = np.zeros(len(sites))
    width = reach / 28.0
    for i in range(len(pos)):
        if gap[i] <= SEAL_MM:
            continue
        other_above = (points[i, 1] - points[i, 0]) @ normal > 0
        s = pos[i] / 2 if anterior[i] else 1 - pos[i] / 2
        step = (1.0 if other_above else -1.0) * gain * min(gap[i] - SEAL_MM, 3.0)
        for j, sj in enumerate(sites):
            same = (sj < 0.5) == bool(anterior[i]) or sj in (0.0, 0.5)
            ds = min(abs(sj - s), 1 - abs(sj - s))
            if same and ds < width:
                delta[j] += step * (1 - ds / width)
    return delta


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("patient")
    ap.add_argument("out")
    ap.add_argument("--iterations", type=int, default=8)
    ap.add_argument("--gain", type=float, default=1.0)
    ap.add_argument("--reach", type=float, default=2.5, help="insertion sites either side")
    ap.add_argument("--low", type=float, default=0.9)
    ap.add_argument("--high", type=float, default=1.3)
    ap.add_argument("--mvtwin", default="build/release/tools/mvtwin")
    a = ap.parse_args()
    shutil.copy(a.patient, a.out)
    with h5py.File(a.patient, "r") as f:
        if "sequence/marginal_chordae_lengths" not in f:
            sys.exit(a.patient + ": no /sequence/marginal_chordae_lengths to tune")
        original = f["sequence/marginal_chordae_lengths"][:]
    result = a.out + ".closure.h5"
    for it in range(a.iterations + 1):
        eroa, log = simulate(a.mvtwin, a.out, result)
        print("iteration %d: EROA %s mm^2" % (it, "failed" if eroa is None else "%.1f" % eroa),
              flush=True)
        if eroa is None:
            sys.exit(log[-400:])
        if it == a.iterations:
            break
        with h5py.File(a.out, "r+") as f:
            lengths = f["sequence/marginal_chordae_lengths"][:]
            lengths[:, 1] = np.clip(
                lengths[:, 1] + length_changes(result, lengths[:, 0], a.reach, a.gain),
                a.low * original[:, 1], a.high * original[:, 1])
            f["sequence/marginal_chordae_lengths"][:] = lengths
    with h5py.File(a.out, "r") as f:
        print("length / the patient's:",
              np.round(f["sequence/marginal_chordae_lengths"][:, 1] / original[:, 1], 2).tolist())


if __name__ == "__main__":
    main()
