#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Accuracy of the tau fit (plain Gu Eq. 7 and the scattering-aware refinement) over the layer
# albedo and the board distance, on the simulated rig with its default noise. Writes
#   docs/benchmarks/tau_sweep.csv  and  docs/models/tau_sweep.png
# Usage: bash scripts/tau_sweep.sh [build dir]   (about 6 minutes on 2 cores)
#        bash scripts/tau_sweep.sh --plot-only   (redraw the chart from the CSV)
set -euo pipefail
cd "$(dirname "$0")/.."
csv=docs/benchmarks/tau_sweep.csv
plot_only=0
[ "${1:-}" = "--plot-only" ] && plot_only=1
build=${1:-build}
bin="$build/app/thinslab"
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
if [ $plot_only = 0 ]; then
echo "sweep,board_distance_mm,albedo,g,plain_rms_rel,plain_bias_rel,refined_rms_rel,refined_bias_rel,fit_s" > "$csv.tmp"

run() {  # sweep D albedo g
  local s="$work/s_$1_$2_$3_$4"
  "$bin" sim shadow-maps "$s" --board-distance-mm "$2" --albedo "$3" --g "$4" >/dev/null
  local t0=$(date +%s.%N)
  "$bin" fit tau "$s" --albedo "$3" --g "$4" >/dev/null
  local t1=$(date +%s.%N)
  python3 - "$s/fit/tau/comparison.json" "$1" "$2" "$3" "$4" "$(echo "$t1 - $t0" | bc)" >> "$csv.tmp" <<'PY'
import json, sys
c = json.load(open(sys.argv[1]))
p, r = c["plain_eq7"], c["refined"]
print(",".join(sys.argv[2:6] + ["%.5f" % p["rms_relative"], "%.5f" % p["mean_relative_bias"],
                                "%.5f" % r["rms_relative"], "%.5f" % r["mean_relative_bias"], sys.argv[6]]))
PY
  rm -rf "$s"
}

for a in 0.1 0.3 0.5 0.7 0.9; do run albedo 1 "$a" 0.8; done
for a in 0.1 0.3 0.5 0.7 0.9; do run albedo 10 "$a" 0.8; done
for d in 0.5 1 2 5 10 20; do run distance "$d" 0.3 0.8; done
for g in 0.3 0.5 0.8 0.95; do run g 1 0.3 "$g"; done
mv "$csv.tmp" "$csv"
fi

gnuplot <<GP
set terminal pngcairo size 1500,450 font ",10" noenhanced
set output "docs/models/tau_sweep.png"
set datafile separator ","
set multiplot layout 1,3 title "tau map: RMS relative error over 0.05 <= tau <= 1.5 (simulated rig, default noise; 'bash scripts/tau_sweep.sh')"
set ylabel "RMS relative error"
set key top left
set grid
set yrange [0:*]
set xlabel "layer albedo (g 0.8)"
plot "< grep '^albedo,1,' $csv" u 3:5 w lp t "plain Eq. 7, D 1 mm", \
     "< grep '^albedo,1,' $csv" u 3:7 w lp t "refined, D 1 mm", \
     "< grep '^albedo,10,' $csv" u 3:5 w lp t "plain Eq. 7, D 10 mm", \
     "< grep '^albedo,10,' $csv" u 3:7 w lp t "refined, D 10 mm", 0.03 w l dt 2 t "3 %"
set xlabel "board distance D [mm] (albedo 0.3, g 0.8)"
set logscale x
set xrange [0.4:25]
plot "< grep '^distance,' $csv" u 2:5 w lp t "plain Eq. 7", "< grep '^distance,' $csv" u 2:7 w lp t "refined", 0.03 w l dt 2 t "3 %"
unset logscale x
set xrange [*:*]
set xlabel "HG g (albedo 0.3, D 1 mm)"
plot "< grep '^g,' $csv" u 4:5 w lp t "plain Eq. 7", "< grep '^g,' $csv" u 4:7 w lp t "refined", 0.03 w l dt 2 t "3 %"
unset multiplot
GP
echo "wrote $csv and docs/models/tau_sweep.png"
