#!/usr/bin/env python3
"""Measure (issue 39, item 1): does the regurgitant orifice converge under mesh refinement, without
and with a clip? Runs `mvtwin clip PATIENT --true-params --device D --at P --no-intervals --set
ures=N --set vres=N --jobs 1` for every patient and grid (kept where its summary exists, so a run
resumes), then prints the table of docs/regurgitant-orifice.md "Convergence": EROA without -> with
the clip per grid, whether the paper's grid lies within max(1 mm^2, 10 %) of the finest, the MVA
without / with the clip, and each run's wall time.

    scripts/experiments/orifice_convergence.py --mvtwin build/release/tools/mvtwin \
        --out conv/ c2026/patient_000{0..9}.h5

The patients come from `mvtwin cohort --n 10 --seed 2026 --out c2026`. Needs only the standard
library.
"""
import argparse
import json
import os
import subprocess
import sys
import time


def tolerance_met(coarse, fine):
    return abs(coarse - fine) <= max(1.0, 0.1 * fine)


def verdict(coarse, fine):
    d = coarse - fine
    text = f"{d:+.1f} mm^2" if abs(d) <= 1.0 or abs(fine) < 10 else f"{100 * d / fine:+.0f} %"
    return text + (": yes" if tolerance_met(coarse, fine) else ": **no**")


def run(args, patient, grid):
    stem = os.path.splitext(os.path.basename(patient))[0]
    out = os.path.join(args.out, f"{stem}_{grid}.h5")
    summary = out[:-3] + ".json"
    timing = out[:-3] + ".time"
    if not os.path.exists(summary):
        command = [args.mvtwin, "clip", patient, "--true-params", "--device", args.device,
                   "--at", args.at, "--no-intervals", "--set", f"ures={grid}",
                   "--set", f"vres={grid}", "--jobs", "1", "--out", out, "--force"]
        start = time.monotonic()
        done = subprocess.run(command, capture_output=True, text=True)
        if done.returncode != 0:
            print(f"{stem} at {grid} x {grid} failed: {done.stderr.strip()}", file=sys.stderr)
            return None, None
        with open(timing, "w") as f:
            f.write(f"{time.monotonic() - start:.2f}\n")
        print(f"{stem} at {grid} x {grid}: done", file=sys.stderr)
    with open(summary) as f:
        result = json.load(f)
    seconds = float("nan")
    if os.path.exists(timing):
        with open(timing) as f:
            seconds = float(f.read())
    return result, seconds


def area(value):
    """An MVA in cm^2, or "fail" where the diastole did not open (the summary holds null)."""
    return "fail" if value is None else f"{value:.2f}"


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("patients", nargs="+")
    parser.add_argument("--mvtwin", default="build/release/tools/mvtwin")
    parser.add_argument("--out", required=True)
    parser.add_argument("--grids", default="30,40,50", help="ures = vres per run; first = paper's")
    parser.add_argument("--device", default="XTW")
    parser.add_argument("--at", default="0.5")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)
    grids = [int(g) for g in args.grids.split(",")]
    paper, finest = grids[0], grids[-1]
    print(f"| patient | {' | '.join(f'{g} x {g}' for g in grids)} | without a clip, {paper} vs "
          f"{finest} | with the clip, {paper} vs {finest} | MVA without / with at {paper}; at "
          f"{finest} | s at {' / '.join(str(g) for g in grids)} |")
    print("|---" * (len(grids) + 5) + "|")
    met = [0, 0]
    rows = 0
    for patient in args.patients:
        runs = {g: run(args, patient, g) for g in grids}
        if any(r[0] is None for r in runs.values()):
            print(f"| {patient} | failed (see above) |")
            continue
        eroa = {g: (r[0]["before"]["eroa_mm2"], r[0]["eroa_mm2"]) for g, r in runs.items()}
        mva = {g: (r[0]["before_open"].get("mva_cm2"), r[0].get("mva_cm2")) for g, r in runs.items()}
        rows += 1
        met[0] += tolerance_met(eroa[paper][0], eroa[finest][0])
        met[1] += tolerance_met(eroa[paper][1], eroa[finest][1])
        cells = " | ".join(f"{eroa[g][0]:.1f} -> {eroa[g][1]:.1f}" for g in grids)
        seconds = " / ".join(f"{runs[g][1]:.0f}" for g in grids)
        print(f"| {runs[paper][0]['patient_id']} | {cells} | "
              f"{verdict(eroa[paper][0], eroa[finest][0])} | "
              f"{verdict(eroa[paper][1], eroa[finest][1])} | "
              f"{area(mva[paper][0])} / {area(mva[paper][1])}; {area(mva[finest][0])} / "
              f"{area(mva[finest][1])} | {seconds} |")
    print(f"\nwithin max(1 mm^2, 10 %) of {finest} x {finest}: without a clip {met[0]} of {rows}, "
          f"with the clip {met[1]} of {rows}")


if __name__ == "__main__":
    main()
