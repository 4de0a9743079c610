#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# The exposure-planning measurement of docs/acquisition.md ("Exposure planning"): a 10 x 10 (or 20 x 20) dot
# scan of the simulated nine-region sample on the linear display, black 0 with the fixed bracket,
# 0.2 % black with the fixed bracket and with --exposures-us auto; each fitted at a 4 mm map
# with held-out dots (the planned run also plans its frames at the longest exposure, 4 here).
# Usage: [DOTS=20] [SEED=6] bash scripts/exposure_plan_compare.sh OUTDIR (10 x 10 dots, seed 5 by
# default: about 1 minute; 20 x 20 dots: about 2 minutes).
set -euo pipefail
out=${1:?usage: exposure_plan_compare.sh OUTDIR}
T=${THINSLAB:-build/app/thinslab}
mkdir -p "$out"
base="acquire dot-scan --quiet --sim-sample true --sim-photons-k 100 --camera-width-px 240 --camera-height-px 180
      --grid-nx ${DOTS:-10} --grid-ny ${DOTS:-10} --sim-display-transfer linear --seed ${SEED:-5}"
run() {
  local name=$1; shift
  $T $base "$@" "$out/$name" > "$out/$name.acquire.log"
  $T fit dmf "$out/$name" --pitch-mm 4 --hold-out true > "$out/$name.fit.log"
  python3 - "$out/$name" <<'PY'
import json, sys
c = json.load(open(sys.argv[1] + "/fit/dmf/comparison.json"))
r = c["regions"]
print("%-8s ok %3d correct %3d  median held-out:" % (sys.argv[1].split("/")[-1], sum(x["ok"] for x in r),
      sum(x.get("correct", 0) for x in r)), " ".join("%s %.2f" % (x["name"], x["median_held_out_relative_rms"]) for x in r))
PY
}
run ideal --exposures-us 11765,9411765 --sim-display-black 0
run glow --exposures-us 11765,9411765
run planned --exposures-us auto --max-exposure-us 9411765
grep "exposure plan" "$out/planned.acquire.log"
