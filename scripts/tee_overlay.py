#!/usr/bin/python3
"""Slices of a patient's TEE volumes with the stored (red) and detected (green) LA surfaces.

    scripts/tee_overlay.py patient.h5 out.png [frame ...]

Reads the mvtwin patient file with h5py (docs/patient-file.md): /images, /sequence and, when
present, /detected. For each frame, the three central slices of the volume (lateral-beam,
elevation-beam, across the beam); surface grid points within 0.75 voxel of a slice are drawn.
"""
import sys

import h5py
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np


def surface(group, frame):
    if group is None or "la_surface" not in group:
        return None
    s = group["la_surface"][frame]  # (vres, ures, 3)
    pts = s.reshape(-1, 3)
    return None if np.isnan(pts).any() else pts


def main():
    path, out = sys.argv[1], sys.argv[2]
    f = h5py.File(path, "r")
    seq = f["sequence"]
    det = f["detected/sequence"] if "detected" in f else None
    frames = [int(x) for x in sys.argv[3:]] or [int(seq.attrs["end_diastole"]), int(seq.attrs["first_closed"])]
    fig, axes = plt.subplots(len(frames), 3, figsize=(11, 3.8 * len(frames)), squeeze=False)
    for row, fr in enumerate(frames):
        v = f["images"][f"volume_{fr:04d}"]
        vol = v[()]  # (nz, ny, nx)
        M = np.array(v.attrs["direction"]).reshape(3, 3) @ np.diag(v.attrs["spacing"])
        Minv = np.linalg.inv(M)
        origin = np.array(v.attrs["origin"])
        for col, axis in enumerate([0, 1, 2]):  # fixed voxel axis i, j, k
            c = vol.shape[2 - axis] // 2
            img = [vol[:, :, c], vol[:, c, :], vol[c, :, :]][axis]  # rows: k (beam) or j
            ax = axes[row][col]
            ax.imshow(img, cmap="gray", vmin=0, vmax=255, origin="upper")
            for pts, colour, label in ((surface(seq, fr), "red", "stored"), (surface(det, fr), "lime", "detected")):
                if pts is None:
                    continue
                idx = (Minv @ (pts - origin).T).T  # (i, j, k)
                near = np.abs(idx[:, axis] - c) < 0.75
                other = [a for a in (0, 1, 2) if a != axis]
                ax.scatter(idx[near, other[0]], idx[near, other[1]], s=4, c=colour, label=label)
            ax.set_title(f"frame {fr} ({f['sequence/time'][fr]:.2f} s), slice {'ijk'[axis]} = {c}")
            ax.axis("off")
        axes[row][0].legend(loc="lower left", fontsize=7)
    tag = "SYNTHETIC " if f.attrs.get("synthetic", 0) else ""
    pid = f.attrs["patient_id"]
    pid = pid.decode() if isinstance(pid, bytes) else pid  # fixed-length text since 2026-11-27
    fig.suptitle(f"{tag}{pid}: TEE with the stored (red) and detected (green) LA surface")
    fig.tight_layout()
    fig.savefig(out, dpi=70)


if __name__ == "__main__":
    main()
