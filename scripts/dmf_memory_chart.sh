#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Peak memory and time of `fit dmf` against the number of map points (issue #29): one simulated
# 40 x 40 dot scan (800 x 600 camera, the paper's workload at 600 x 600 points), fitted at
# 300^2, 600^2 and 1200^2 points under the default 2 GiB budget (streamed) and at 600^2 in
# memory (--max-memory 0), each timed by /usr/bin/time (wall clock, peak resident set).
#   bash scripts/dmf_memory_chart.sh WORKDIR
# Reuses WORKDIR/cap40 and every WORKDIR/r<points>_m<GiB> fit already there (delete one to
# rerun it). About 50 minutes on the 2-core machine from nothing (7 of them the simulation).
# Writes docs/benchmarks/dmf_memory.csv and docs/benchmarks/dmf_memory.png.
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:?usage: dmf_memory_chart.sh WORKDIR}
thinslab=$PWD/build/app/thinslab
mkdir -p "$work"
if [ ! -f "$work/cap40/session.json" ]; then
  "$thinslab" sim dot-scan "$work/cap40" --grid-nx 40 --grid-ny 40 --camera-width-px 800 --camera-height-px 600 \
    --photons-k 1000 --table-bins 96 --quiet
fi
runs="300:0.266667:2 600:0.133333:2 1200:0.0666667:2 600:0.133333:0"
for run in $runs; do
  IFS=: read -r points pitch gib <<< "$run"
  out="$work/r${points}_m${gib}"
  [ -f "$out/summary.json" ] && continue
  /usr/bin/time -v "$thinslab" fit dmf "$work/cap40" --pitch-mm "$pitch" --hold-out true --max-memory "$gib" \
    --out "$out" > "$out.log" 2> "$out.time"
done
csv=docs/benchmarks/dmf_memory.csv
{
  echo "points,max_memory_gib,streamed,band_points,wall_s,peak_rss_mib,estimated_peak_mib,estimated_in_memory_mib,processing_s,fit_s,writing_s,spill_file_gib"
  for run in $runs; do
    IFS=: read -r points pitch gib <<< "$run"
    out="$work/r${points}_m${gib}"
    wall=$(awk -F': ' '/Elapsed \(wall clock\)/ {n = split($2, t, ":"); s = 0; for (i = 1; i <= n; ++i) s = s * 60 + t[i]; print s}' "$out.time")
    rss=$(awk -F': ' '/Maximum resident set size/ {printf "%.0f", $2 / 1024}' "$out.time")
    python3 - "$out/summary.json" "$points" "$gib" "$wall" "$rss" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
m, t = s["memory"], s["timings_s"]
mib = 1 << 20
print(",".join(str(v) for v in [sys.argv[2], sys.argv[3], str(m["streamed"]).lower(), m["band_points"], sys.argv[4],
                                sys.argv[5], round(m["estimated_peak_bytes"] / mib), round(m["estimated_in_memory_bytes"] / mib),
                                round(t["processing_total"], 1), round(t["fit_total"], 1), round(t["writing"], 1),
                                round(m["spill_file_bytes"] / (1 << 30), 2)]))
PY
  done
} > "$csv"
gnuplot <<GP
set terminal pngcairo size 900,540 font ",11"
set output "docs/benchmarks/dmf_memory.png"
set datafile separator ","
set title "fit dmf: peak memory and time against map points (40 x 40 dots, 800 x 600 camera, 2 cores)"
set xlabel "map points"
set logscale xy
set xrange [60000:2000000]
set ylabel "peak resident memory [MiB]"
set y2label "wall time [s]"
set logscale y2
set ytics nomirror
set y2tics
set key below
set grid
plot "$csv" using (strcol(3) eq "true" ? \$1 * \$1 : 1/0):6 with linespoints lw 2 pt 7 title "streamed, --max-memory 2: peak", \
     "$csv" using (strcol(3) eq "false" ? \$1 * \$1 : 1/0):6 with points pt 9 ps 2 title "in memory (--max-memory 0): peak", \
     2048 with lines lw 1 dt 2 lc rgb "black" title "2 GiB budget", \
     "$csv" using (strcol(3) eq "true" ? \$1 * \$1 : 1/0):5 axes x1y2 with linespoints lw 2 pt 5 dt 3 title "streamed: wall time", \
     "$csv" using (strcol(3) eq "false" ? \$1 * \$1 : 1/0):5 axes x1y2 with points pt 8 ps 2 title "in memory: wall time"
GP
echo "wrote docs/benchmarks/dmf_memory.png from $csv"
