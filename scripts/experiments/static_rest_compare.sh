#!/usr/bin/env bash
# The static solve (--set static_rest=on, issue 40) against settling on virtual patients, one
# thread each, one after the other: wall time, Newton iterations and the residual reached, the
# node-wise distance between the two end states, the EROA of both.
#   scripts/experiments/static_rest_compare.sh MVTWIN COHORT_DIR OUT_DIR patient...
# e.g. (cohort from `mvtwin cohort --n 10 --seed 2026 --out c2026`):
#   scripts/experiments/static_rest_compare.sh build/release/tools/mvtwin c2026 cmp 1 2 3 4 5
set -euo pipefail
mv=$1 cohort=$2 out=$3
shift 3
mkdir -p "$out"
for p in "$@"; do
  in="$cohort/patient_$(printf %04d "$p").h5"
  for mode in off on; do
    "$mv" simulate "$in" --out "$out/p${p}_$mode.h5" --force --set threads=1 \
      --set static_rest=$mode > /dev/null 2>&1
  done
  /usr/bin/python3 - "$out/p${p}_off.h5" "$out/p${p}_on.h5" "$p" <<'PY'
import sys
import h5py
import numpy as np
a, b = h5py.File(sys.argv[1], "r"), h5py.File(sys.argv[2], "r")
d = np.linalg.norm((a["final/final_positions"][()] - b["final/final_positions"][()]).reshape(-1, 3), axis=1)
sa, sb = a["summary"], b["summary"]
g = lambda s, k: float(s[k][()])
print(f"patient {sys.argv[3]}: settling {g(sa, 'wall_s'):.2f} s ({int(g(sa, 'settle_steps'))} steps) | "
      f"static {g(sb, 'wall_s'):.2f} s (Newton {int(g(sb, 'static_iterations'))} iterations, "
      f"{g(sb, 'static_s'):.2f} s, residual {g(sb, 'static_relative_residual'):.1e} of the load, "
      f"then {int(g(sb, 'settle_steps'))} settling steps) | end states apart: mean {d.mean():.4f}, "
      f"max {d.max():.3f} mm | EROA {float(a['orifice/eroa_mm2'][()]):.1f} / {float(b['orifice/eroa_mm2'][()]):.1f} mm^2")
PY
done
