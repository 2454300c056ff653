#!/usr/bin/python3
"""Error of the valve detector against the noise of the synthetic TEE, from bench detect's JSON.

    scripts/plot_detect_curve.py detect.json curve.png
"""
import json
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt


def main():
    j = json.load(open(sys.argv[1]))
    curve = sorted(j["curve"], key=lambda c: c["noise"])
    x = [c["noise"] for c in curve]
    fig, ax = plt.subplots(figsize=(6.4, 4.0))
    ax.errorbar(x, [c["error_mean_mm"] for c in curve], yerr=[c["error_sd_mm"] for c in curve],
                marker="o", capsize=3, label="LA surface (mean, SD over frames)")
    ax.plot(x, [c["papillary_error_mm"] for c in curve], marker="s", label="papillary tips (mean)")
    ax.axhline(2.75, color="grey", ls="--", lw=1, label="Mansi et al. 2012 detector: 2.75 mm")
    ax.axhline(1.5, color="grey", ls=":", lw=1, label="target: 1.5 mm")
    ax.axvline(j["render"]["noise"], color="k", lw=0.5)
    ax.set_xscale("symlog", linthresh=0.002)
    ax.set_xlim(0, max(x) * 1.3)
    ax.set_xlabel("electronic noise SD (relative to a leaflet's echo); default 0.004")
    ax.set_ylabel("error, mm")
    top = 8.0
    ax.set_ylim(0, top)
    for c in curve:  # values above the frame, written out
        for v, dy in ((c["papillary_error_mm"], -0.6), (c["error_mean_mm"] + c["error_sd_mm"], -1.2)):
            if v > top:
                ax.annotate(f"{v:.1f} mm", (c["noise"], top), xytext=(-40, -12 if dy > -1 else -24),
                            textcoords="offset points", fontsize=7)
    ax.set_title(f"detection on {j['n_test']} held-out virtual patients [SYNTHETIC] "
                 f"(trained on {j['n_train']}), {j['render']['voxel_mm']} mm voxels", fontsize=9)
    ax.legend(fontsize=8, loc="upper left")
    fig.text(0.01, 0.01, f"mvtwin {j['provenance']['mvtwin_version']}: {j['provenance']['command']}",
             fontsize=6, color="grey")
    fig.tight_layout(rect=(0, 0.03, 1, 1))
    fig.savefig(sys.argv[2], dpi=120)


if __name__ == "__main__":
    main()
