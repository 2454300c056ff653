#!/usr/bin/python3
"""The demo's short report: each stage (detection, calibration, clip) against the virtual
patient's truth."""
import json
import os
import sys

out = sys.argv[1]


def load(name):
    path = os.path.join(out, name)
    return json.load(open(path)) if os.path.exists(path) else None


cal = load("calibration.json")
clip = load("clipped.json")
det = load("detection.json")
truth_clip = load("clipped_truth.json")
tag = " [SYNTHETIC]" if cal.get("synthetic") else ""
print(f"Report for {cal['patient_id']}{tag}")

if det and "against_stored" in det:
    s = det["against_stored"]
    phases = ", ".join(f"{k} {v['error_mean_mm']:.2f}" for k, v in sorted(s["by_phase"].items()))
    print(f"  1. detection from the TEE: surface {s['error_mean_mm']:.2f} +- {s['error_sd_mm']:.2f} mm "
          f"over {s['frames']} frames ({phases}), papillary tips {s['papillary_error_mm']:.2f} mm, "
          f"{det['s_per_volume']:.2f} s per volume")
    lm = s["landmark_error_mm"]
    print("     landmarks (mm): " + ", ".join(f"{k} {v:.1f}" for k, v in sorted(lm.items())))
    print("     (the paper's detector: 2.75 +- 0.86 mm at 4.8 s per volume)")

src = "the detected valve" if "stored_valve_error_after_mm" in cal else "the stored valve"
print(f"  2. calibration ({cal['method']}) to {src}: error {cal['error_before_mm']:.3f} -> "
      f"{cal['error_after_mm']:.3f} mm, {cal['sims']} simulations ({cal['failed_sims']} failed), "
      f"{cal['wall_s']:.0f} s")
if "stored_valve_error_after_mm" in cal:
    print(f"     the calibrated closure against the truth's closed valve: "
          f"{cal['stored_valve_error_before_mm']:.3f} -> {cal['stored_valve_error_after_mm']:.3f} mm "
          f"(the truth's own observation noise is 0.5 mm)")
for p in cal["parameters"]:
    truth = "" if p["truth"] is None else f"  truth {p['truth']:.3f}  error {p['error']:+.3f}"
    flag = "" if p["identified"] else "  (not identified by the data)"
    print(f"     {p['name']:<42} {p['fitted']:8.3f}{truth}{flag}")

b = clip["before"]
bo = clip.get("before_open") or {}


def mva(o):
    return f"MVA {o['mva_cm2']:.2f} cm^2" if o and o.get("converged") else "MVA not simulated"


print(f"  3. clip, predicted on the detected, calibrated valve: before, EROA {b['eroa_mm2']:.1f} mm^2 "
      f"({b['mr_grade']} MR), coaptation {b['coaptation_length_mm']:.1f} mm, {mva(bo)}")
ranked = clip.get("ranked", [])
if ranked:
    best = ranked[0]
    a = best["after"]
    areas = ", ".join(f"{x:.1f}" for x in a["openings_mm2"])
    print(f"     best of {len(ranked)} options, {best['sites']}: EROA {a['eroa_mm2']:.1f} mm^2 "
          f"({a['mr_grade']} MR) in {len(a['openings_mm2'])} opening(s) (anatomic {areas} mm^2), coaptation "
          f"{a['coaptation_length_mm']:.1f} mm, {mva(best.get('open'))}"
          f"{' (STENOSIS)' if (best.get('open') or {}).get('stenosis') else ''}")
    if truth_clip:
        tb, ta = truth_clip["before"], truth_clip["after"]
        print(f"     the truth (its anatomy and hidden parameters, same model): before EROA "
              f"{tb['eroa_mm2']:.1f} mm^2, after the same clip {ta['eroa_mm2']:.1f} mm^2, "
              f"MVA {truth_clip['mva_cm2']:.2f} cm^2; prediction error "
              f"{a['eroa_mm2'] - ta['eroa_mm2']:+.1f} mm^2 after, "
              f"{b['eroa_mm2'] - tb['eroa_mm2']:+.1f} mm^2 before")
