#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The laser exposure-planning measurement of docs/acquisition.md ("Exposure planning"): the
# simulated laser rig (400 x 300 camera, tau 0.3, g 0.8, albedo 0.3) at three laser powers
# (1 = the spot fills half the range in 20 us), with the fixed bracket 20 us .. 2 s and with
# --exposures-us auto; each checked and fitted by `fit phase`.
# Usage: bash scripts/laser_plan_compare.sh OUTDIR (about 1 minute).
set -euo pipefail
out=${1:?usage: laser_plan_compare.sh OUTDIR}
T=${THINSLAB:-build/app/thinslab}
mkdir -p "$out"
base="acquire laser --camera sim --camera-width-px 400 --camera-height-px 300"
for power in 0.001 1 30; do
  for bracket in fixed auto; do
    name="p${power}_${bracket}"
    extra=""
    [ "$bracket" = auto ] && extra="--exposures-us auto"
    $T $base --sim-laser-power "$power" $extra "$out/$name" > "$out/$name.acquire.log" 2>&1
    $T fit phase "$out/$name" --quiet true > "$out/$name.fit.log" 2>&1
    python3 - "$out/$name" "$power" "$bracket" <<'PY'
import json, re, sys
folder, power, bracket = sys.argv[1:4]
s = json.load(open(folder + "/fit/phase/summary.json"))
m = json.load(open(folder + "/session.json"))
log = open(folder + ".acquire.log").read()
laser = sorted({f["exposure_time_us"] for f in m["frames"] if f["kind"] == "laser"})
verdict = re.search(r"verdict: (\w+)", log).group(1)
retakes = sorted(set(re.findall(r"retake \[(\w+)\]", log)))
print("| %s | %s | %d | %.4g .. %.4g | %s%s | %.4f +- %.4f |" % (power, bracket, len(m["frames"]), laser[0],
      laser[-1], verdict, (" (" + ", ".join(retakes) + ")") if retakes else "", s["g"], s["sigma_g"]))
PY
  done
done
