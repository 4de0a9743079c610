#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Accuracy against cluster fraction of the dual-microfacet fit (issue #5): runs bench/dmf_bench
# (simulated 40 x 40 dot scan, 100 x 100 points) and charts the median held-out error and the
# fit time against the fraction of k-means representatives.
#   bash scripts/dmf_cluster_chart.sh [points] [dots] [camera_px]
# Writes docs/benchmarks/dmf_cluster_fraction_<points>.csv and docs/benchmarks/dmf_cluster_fraction.png.
set -euo pipefail
cd "$(dirname "$0")/.."
points=${1:-100}; dots=${2:-40}; camera=${3:-480}
csv=docs/benchmarks/dmf_cluster_fraction_${points}.csv
if [ "${REUSE_CSV:-0}" != "1" ]; then
  cmake --build build --target dmf_bench >/dev/null
  build/bench/dmf_bench "$points" "$dots" "$camera" 0 0.003 0.01 0.03 0.1 0.3 > "$csv"
fi
unclustered_err=$(awk -F, 'NR > 1 && $4 == 0 {print $14}' "$csv")
unclustered_t=$(awk -F, 'NR > 1 && $4 == 0 {print $12}' "$csv")
gnuplot <<GP
set terminal pngcairo size 900,540 font ",11"
set output "docs/benchmarks/dmf_cluster_fraction.png"
set datafile separator ","
set title "Dual-microfacet fit: accuracy against cluster fraction (${points}x${points} points, ${dots}x${dots} dots)"
set xlabel "representatives / points (k-means, Dai Sec. 4.3)"
set logscale x
set ylabel "median held-out in-lobe relative RMS error"
set y2label "fit time [s] (2 cores, excluding image processing)"
set ytics nomirror
set y2tics
set logscale y2
set key top right
set grid
plot "$csv" using (\$4 > 0 ? \$4 : 1/0):14 with linespoints lw 2 pt 7 title "clustered: error", \
     "$csv" using (\$4 > 0 ? \$4 : 1/0):12 axes x1y2 with linespoints lw 2 pt 5 dt 2 title "clustered: fit time", \
     ${unclustered_err} with lines lw 2 lc rgb "black" title "every point fitted: error", \
     ${unclustered_t} axes x1y2 with lines lw 1 dt 3 lc rgb "black" title "every point fitted: time"
GP
echo "wrote docs/benchmarks/dmf_cluster_fraction.png from $csv"
