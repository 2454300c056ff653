#!/usr/bin/python3
"""Renders a closure simulation's atrial surface (mvtwin simulate --out R.h5) at its start,
middle and end as a PNG, seen along the annulus normal; anterior leaflet blue, posterior orange.

    scripts/render_closure.py R.h5 closure.png

Needs Debian's python3 with h5py and matplotlib (scripts/setup installs both). For real
inspection open the --vtk series in ParaView; this is for documentation and quick looks.
"""
import sys

import h5py
import matplotlib
import numpy as np

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402


def main(path, out):
    with h5py.File(path, "r") as f:
        if f.attrs.get("format") not in ("mvtwin-simulation", b"mvtwin-simulation"):
            sys.exit(f"{path}: not an mvtwin simulation file")
        surfaces = f["samples/la_surface"][:]
        times = f["samples/time_s"][:]
        orifice = f["samples/orifice_area_mm2"][:]
        synthetic = int(f.attrs.get("synthetic", 0))
        patient = f.attrs.get("patient_id", "")
    if isinstance(patient, bytes):
        patient = patient.decode()
    picks = [0, len(surfaces) // 2, len(surfaces) - 1]
    fig = plt.figure(figsize=(15, 5.4))
    for k, i in enumerate(picks):
        grid = surfaces[i]  # [v][u][xyz]
        nv, nu, _ = grid.shape
        ring = grid[0] - grid[0].mean(0)
        normal = sum(np.cross(ring[u], ring[(u + 1) % nu]) for u in range(nu))
        normal /= np.linalg.norm(normal)
        ax = fig.add_subplot(1, 3, k + 1, projection="3d")
        quads, colours = [], []
        for v in range(nv - 1):
            for u in range(nu):
                quads.append([grid[v, u], grid[v, (u + 1) % nu], grid[v + 1, (u + 1) % nu],
                              grid[v + 1, u]])
                colours.append("tab:blue" if u < nu // 2 else "tab:orange")
        ax.add_collection3d(Poly3DCollection(quads, facecolors=colours, edgecolors="k",
                                             linewidths=0.1, alpha=0.95))
        pts = grid.reshape(-1, 3)
        centre, reach = pts.mean(0), np.abs(pts - pts.mean(0)).max()
        for j, axis in enumerate("xyz"):
            getattr(ax, f"set_{axis}lim")(centre[j] - reach, centre[j] + reach)
        ax.view_init(np.degrees(np.arcsin(normal[2])), np.degrees(np.arctan2(normal[1], normal[0])))
        ax.set_title(f"t = {times[i]:.2f} s: orifice {orifice[i]:.1f} mm$^2$")
        ax.set_axis_off()
    fig.suptitle(f"{patient}{' (SYNTHETIC: virtual patient)' if synthetic else ''}: "
                 "anterior leaflet blue, posterior orange")
    plt.tight_layout(rect=(0, 0, 1, 0.93))
    plt.savefig(out, dpi=80)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(__doc__)
    main(sys.argv[1], sys.argv[2])
