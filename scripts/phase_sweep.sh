#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Where the laser-lobe g fit (Gu Eq. 8) becomes unstable: bias and sigma_g over tau, albedo, g,
# sensor noise (full well) and board distance, on the simulated rig (1024 x 768 camera, default
# bracket). Unstable = sigma_g > 0.1 or |bias| > 0.05. Writes
#   docs/benchmarks/phase_sweep.csv  and  docs/models/phase_sweep.png
# Usage: bash scripts/phase_sweep.sh [build dir] | --plot-only     (about 3 minutes on 2 cores)
set -euo pipefail
cd "$(dirname "$0")/.."
csv=docs/benchmarks/phase_sweep.csv
plot_only=0
[ "${1:-}" = "--plot-only" ] && plot_only=1
build=${1:-build}
bin="$build/app/thinslab"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

run() {  # sweep tau albedo g full_well distance_mm
  local s="$work/s"
  rm -rf "$s"
  "$bin" sim laser "$s" --tau "$2" --albedo "$3" --g "$4" --full-well-e "$5" --board-distance-mm "$6" \
    --camera-width-px 1024 --camera-height-px 768 --capture-clean false >/dev/null
  "$bin" fit phase "$s" --tau "$2" >/dev/null || true
  python3 - "$s/fit/phase/summary.json" "$@" >> "$csv.tmp" <<'PY'
import json, os, sys
path, sweep, tau, albedo, g, fw, d = sys.argv[1:8]
if os.path.exists(path):
    s = json.load(open(path))
    res, gf, sg = s["result"], s["g"], s["sigma_g"]
else:
    res, gf, sg = "error", float("nan"), float("nan")
print(",".join([sweep, tau, albedo, g, fw, d, res, "%.5f" % gf, "%.5f" % sg, "%.5f" % (gf - float(g))]))
PY
}

if [ $plot_only = 0 ]; then
  echo "sweep,tau,albedo,g,full_well_e,board_distance_mm,result,g_fit,sigma_g,bias" > "$csv.tmp"
  for t in 0.05 0.1 0.3 0.6 1 1.5 2; do run tau "$t" 0.3 0.8 30000 20; done
  for a in 0.1 0.3 0.5 0.7 0.9; do run albedo 0.3 "$a" 0.8 30000 20; done
  for g in 0.2 0.5 0.8 0.9 0.95 0.98; do run g 0.3 0.3 "$g" 30000 20; done
  for fw in 30000 3000 1000 300 100; do run noise 0.3 0.3 0.8 "$fw" 20; done
  for d in 5 10 20 40; do run distance 0.3 0.3 0.8 30000 "$d"; done
  mv "$csv.tmp" "$csv"
fi

gnuplot <<GP
set terminal pngcairo size 1700,420 font ",10" noenhanced
set output "docs/models/phase_sweep.png"
set datafile separator ","
set multiplot layout 1,5 title "laser-lobe g fit: bias (g_fit - g_true) and sigma_g; unstable where |bias| > 0.05 or sigma_g > 0.1  ('bash scripts/phase_sweep.sh')"
set grid
set key top left
set yrange [-0.25:0.25]
set ylabel "g_fit - g_true, sigma_g"
set xlabel "tau (albedo 0.3, g 0.8)"
set logscale x
plot "< grep '^tau,' $csv" u 2:10 w lp t "bias", "" u 2:9 w lp t "sigma_g", 0.05 w l dt 2 lc rgb "gray" t "+-0.05", -0.05 w l dt 2 lc rgb "gray" notitle, 0.1 w l dt 3 lc rgb "red" t "0.1"
unset logscale x
set xlabel "albedo (tau 0.3, g 0.8)"
plot "< grep '^albedo,' $csv" u 3:10 w lp t "bias", "" u 3:9 w lp t "sigma_g", 0.05 w l dt 2 lc rgb "gray" notitle, -0.05 w l dt 2 lc rgb "gray" notitle, 0.1 w l dt 3 lc rgb "red" notitle
set xlabel "g (tau 0.3, albedo 0.3)"
plot "< grep '^g,' $csv" u 4:10 w lp t "bias", "" u 4:9 w lp t "sigma_g", 0.05 w l dt 2 lc rgb "gray" notitle, -0.05 w l dt 2 lc rgb "gray" notitle, 0.1 w l dt 3 lc rgb "red" notitle
set xlabel "full well [e-] (more noise to the right)"
set logscale x
set xrange [*:*] reverse
plot "< grep '^noise,' $csv" u 5:10 w lp t "bias", "" u 5:9 w lp t "sigma_g", 0.05 w l dt 2 lc rgb "gray" notitle, -0.05 w l dt 2 lc rgb "gray" notitle, 0.1 w l dt 3 lc rgb "red" notitle
set xrange [*:*] noreverse
set xlabel "board distance d [mm]"
plot "< grep '^distance,' $csv" u 6:10 w lp t "bias", "" u 6:9 w lp t "sigma_g", 0.05 w l dt 2 lc rgb "gray" notitle, -0.05 w l dt 2 lc rgb "gray" notitle, 0.1 w l dt 3 lc rgb "red" notitle
unset multiplot
GP
echo "wrote $csv and docs/models/phase_sweep.png"
