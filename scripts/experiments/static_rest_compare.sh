#!/usr/bin/env bash
# The static solve (--set static_rest=on, issue 40) against settling on virtual patients, one
# thread each, one run after the other, each against the same grid's own rest (settled to
# 0.001 mm per step, at most 20 s): wall time, settling steps, Newton iterations and the
# residual reached (fraction of the pressure load), node-wise distance from that rest (mean /
# max mm), EROA. Modes: settle (the default), static from the closure's end
# (static_start_mm=0), static after settling to 0.03 mm (the static solve's default).
#   scripts/experiments/static_rest_compare.sh MVTWIN COHORT_DIR OUT_DIR patient...
# e.g. (cohort from `mvtwin cohort --n 10 --seed 2026 --out c2026`):
#   scripts/experiments/static_rest_compare.sh build/release/tools/mvtwin c2026 cmp 1 2 3 4 5
set -euo pipefail
mv=$1 cohort=$2 out=$3
shift 3
mkdir -p "$out"
run() {  # name input extra-settings...
  local name=$1 in=$2
  shift 2
  "$mv" simulate "$in" --out "$out/$name.h5" --force --set threads=1 "$@" > /dev/null 2>&1 ||
    echo "$name: the simulation failed (see $out/$name.json)"
}
for p in "$@"; do
  in="$cohort/patient_$(printf %04d "$p").h5"
  [ -f "$out/p${p}_rest.h5" ] || run "p${p}_rest" "$in" --set settle_mm=0.001 --set settle_max_s=20
  run "p${p}_settle" "$in"
  run "p${p}_static0" "$in" --set static_rest=on --set static_start_mm=0
  run "p${p}_static" "$in" --set static_rest=on
  /usr/bin/python3 - "$out" "$p" <<'PY'
import sys
import h5py
import numpy as np
out, p = sys.argv[1], sys.argv[2]
ref = h5py.File(f"{out}/p{p}_rest.h5", "r")
x0 = ref["final/final_positions"][()].reshape(-1, 3)
s = ref["summary"]
row = [f"patient {p}: rest {s['wall_s'][()]:.2f} s, {int(s['settle_steps'][()])} steps"]
for mode in ("settle", "static0", "static"):
    f = h5py.File(f"{out}/p{p}_{mode}.h5", "r")
    s = f["summary"]
    d = np.linalg.norm(f["final/final_positions"][()].reshape(-1, 3) - x0, axis=1)
    it = int(s["static_iterations"][()]) if "static_iterations" in s else 0
    rel = float(s["static_relative_residual"][()]) if "static_relative_residual" in s else 0.0
    failed = mode != "settle" and s["static_converged"][()] == 0
    row.append(f"{mode} {s['wall_s'][()]:.2f} s, {int(s['settle_steps'][()])} steps, "
               f"{it} Newton ({rel:.1e}{', failed' if failed else ''}), "
               f"{d.mean():.4f} / {d.max():.3f} mm, EROA {float(f['orifice/eroa_mm2'][()]):.1f}")
print(" | ".join(row))
PY
done
