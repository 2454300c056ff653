#!/usr/bin/python3
"""The demo's short report: closure, calibration against the virtual patient's truth, clip."""
import json
import sys

out = sys.argv[1]
cal = json.load(open(f"{out}/calibration.json"))
clip = json.load(open(f"{out}/clipped.json"))
tag = " [SYNTHETIC]" if cal.get("synthetic") else ""
print(f"Report for {cal['patient_id']}{tag}")
print(f"  calibration ({cal['method']}): error {cal['error_before_mm']:.3f} -> "
      f"{cal['error_after_mm']:.3f} mm (noise SD for the uncertainty {cal['noise_mm']:.2f} mm), "
      f"{cal['sims']} simulations ({cal['failed_sims']} failed), {cal['wall_s']:.0f} s")
for p in cal["parameters"]:
    truth = "" if p["truth"] is None else f"  truth {p['truth']:.3f}  error {p['error']:+.3f}"
    flag = "" if p["identified"] else "  (not identified by the data)"
    print(f"    {p['name']:<42} {p['fitted']:8.3f}{truth}{flag}")
b = clip["before"]
print(f"  before the clip: orifice {b['orifice_area_mm2']:.1f} mm^2 of "
      f"{b['annulus_area_mm2']:.0f} mm^2 annulus, coaptation {b['coaptation_length_mm']:.1f} mm")
ranked = clip.get("ranked", [])
if ranked:
    best = ranked[0]
    a = best["after"]
    areas = ", ".join(f"{x:.1f}" for x in a["component_areas_mm2"])
    print(f"  best clip of {len(ranked)} at position,depth {best['sites']}: orifice "
          f"{a['orifice_area_mm2']:.1f} mm^2 in {a['orifice_components']} opening(s) ({areas}), "
          f"coaptation {a['coaptation_length_mm']:.1f} mm, clip gap "
          f"{', '.join(f'{g:.1f}' for g in a['clip_gap_end_mm'])} mm")
