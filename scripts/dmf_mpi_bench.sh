#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# `fit dmf` as one process against `mpirun -n N` (issue #29 item 2) on the 40 x 40 dot scan of
# scripts/dmf_memory_chart.sh (WORKDIR/cap40, simulated when missing), at 300 x 300 points under
# the default 2 GiB budget: wall time, per-stage times and peak memory of each run, and whether
# the maps are the same bit for bit. On one machine the processes share its cores (each runs
# --threads cores/N), so this measures what sharing the work out costs, not a cluster's speed-up.
#   bash scripts/dmf_mpi_bench.sh WORKDIR [N]
# About 4 minutes on the 2-core machine (plus 7 for the simulation). Prints a table.
set -euo pipefail
cd "$(dirname "$0")/.."
work=${1:?usage: dmf_mpi_bench.sh WORKDIR [N]}
n=${2:-2}
thinslab=$PWD/build/app/thinslab
cores=$(nproc)
mkdir -p "$work"
if [ ! -f "$work/cap40/session.json" ]; then
  "$thinslab" sim dot-scan "$work/cap40" --grid-nx 40 --grid-ny 40 --camera-width-px 800 --camera-height-px 600 \
    --photons-k 1000 --table-bins 96 --quiet
fi
fit=(fit dmf "$work/cap40" --pitch-mm 0.266667 --hold-out true)
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
rm -rf "$work/mpi_1" "$work/mpi_$n"
/usr/bin/time -v "$thinslab" "${fit[@]}" --threads "$cores" --out "$work/mpi_1" > "$work/mpi_1.log" 2> "$work/mpi_1.time"
/usr/bin/time -v mpirun -n "$n" --oversubscribe --mca btl self,vader --mca oob_tcp_if_include lo \
  "$thinslab" "${fit[@]}" --threads $(( cores / n > 0 ? cores / n : 1 )) --out "$work/mpi_$n" \
  > "$work/mpi_$n.log" 2> "$work/mpi_$n.time"
/usr/bin/python3 - "$work" "$n" <<'PY'
import json, re, sys
import numpy as np, OpenImageIO as oiio
work, n = sys.argv[1], sys.argv[2]
def wall(path):
    t = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): (\S+)", open(path).read()).group(1)
    parts = [float(x) for x in t.split(":")]
    return sum(p * 60 ** i for i, p in enumerate(reversed(parts)))
print("processes,wall_s,hdr_merge_rectify_eq12_s,diffuse_s,clustering_s,model_fit_s,interpolation_s,writing_s,rank0_peak_mib")
for tag in ["1", n]:
    s = json.load(open(f"{work}/mpi_{tag}/summary.json"))
    t = s["timings_s"]
    print(f'{s["processes"]},{wall(f"{work}/mpi_{tag}.time"):.1f},{t["hdr_merge_rectify_eq12"]:.1f},'
          f'{t["diffuse_separation"]:.1f},{t["clustering"]:.1f},{t["model_fit"]:.1f},{t["interpolation"]:.1f},'
          f'{t["writing"]:.1f},{s["peak_memory_mib"]:.0f}')
for f in ["maps.exr", "ndf_atlas.exr"]:
    a = oiio.ImageBuf(f"{work}/mpi_1/{f}").get_pixels(oiio.FLOAT)
    b = oiio.ImageBuf(f"{work}/mpi_{n}/{f}").get_pixels(oiio.FLOAT)
    print(f, "identical" if np.array_equal(a, b, equal_nan=True) else "DIFFERENT")
PY
