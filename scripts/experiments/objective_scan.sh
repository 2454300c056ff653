#!/usr/bin/env bash
# The calibration's objective along one parameter, for the ways the closed valve can end (issue
# 40: is the objective smooth?): the closed valve settled at rest (the default), by the static
# solve (static_rest=on), and unsettled (settle_mm=0, the state when the pressure peaks). Each
# point is one closure on the calibration's search model (24 x 24 by default) with one thread,
# and the symmetric point-to-mesh distance (mean, mm) of its end surface to the patient's
# observed first closed frame (`mvtwin distance`). Writes OUT/scan.csv and OUT/scan.png.
#   scripts/experiments/objective_scan.sh MVTWIN OBSERVED_PATIENT OUT PARAM FROM TO N [--set ...]
# e.g. scripts/experiments/objective_scan.sh build/release/tools/mvtwin obs.h5 scan \
#        restlength_factor_anterolateral_marginal 0.9 1.1 21
set -euo pipefail
mv=$1 patient=$2 out=$3 param=$4 from=$5 to=$6 n=$7
shift 7
mkdir -p "$out"
echo "mode,$param,distance_mm,wall_s,status" > "$out/scan.csv"
for ((i = 0; i < n; ++i)); do
  v=$(/usr/bin/python3 -c "print(f'{$from + ($to - $from) * $i / max(1, $n - 1):.6f}')")
  for mode in settle static unsettled; do
    case $mode in
      settle) extra=() ;;
      static) extra=(--set static_rest=on) ;;
      unsettled) extra=(--set settle_mm=0) ;;
    esac
    f="$out/${mode}_$i.h5"
    status=ok
    "$mv" simulate "$patient" --out "$f" --force --set threads=1 --set ures=24 --set vres=24 \
      --set orifice_refine=0 --set "$param=$v" "${extra[@]}" "$@" > /dev/null 2>&1 || status=failed
    if [ "$status" = ok ]; then
      d=$("$mv" distance "$f" "$patient" --json |
        /usr/bin/python3 -c "import json, sys; print(json.load(sys.stdin)['symmetric']['mean_mm'])")
      w=$(/usr/bin/python3 -c "import h5py; print(h5py.File('$f')['summary/wall_s'][()])")
    else
      d=nan w=nan
    fi
    echo "$mode,$v,$d,$w,$status" >> "$out/scan.csv"
  done
  echo "$param = $v done"
done
/usr/bin/python3 - "$out" "$param" "$*" <<'PY'
import csv, sys
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
out, param = sys.argv[1], sys.argv[2]
rows = list(csv.DictReader(open(f"{out}/scan.csv")))
fig, ax = plt.subplots(figsize=(7, 4.2))
labels = {"settle": "settled at rest (default)", "static": "static solve (static_rest=on)",
          "unsettled": "unsettled (settle_mm=0)"}
for mode, style in (("unsettled", "s:"), ("settle", "o-"), ("static", "^--")):
    pts = [(float(r[param]), float(r["distance_mm"])) for r in rows
           if r["mode"] == mode and r["status"] == "ok"]
    if pts:
        ax.plot(*zip(*pts), style, ms=4, label=labels[mode])
ax.set_xlabel(param)
ax.set_ylabel("distance to the observed closed frame, mm (mean)")
model = "ures = vres = 24" + (", then " + sys.argv[3] if sys.argv[3] else "")
ax.set_title(f"The objective along one parameter ({model})", fontsize=10)
ax.grid(alpha=0.3)
ax.legend(fontsize=8)
fig.tight_layout()
fig.savefig(f"{out}/scan.png", dpi=120)
PY
echo "wrote $out/scan.csv and $out/scan.png"
