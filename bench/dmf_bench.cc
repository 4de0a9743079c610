// SPDX-License-Identifier: Apache-2.0
// Whole-chain benchmark of the dual-microfacet fit (issue #5): synthesizes a dot-scan capture on
// the simulated rig (not timed), then times the chain from the recorded stack to maps (dot
// geometry, HDR merge + rectification + Eq. 12, Eq. 14, clustering, model fit, interpolation)
// for several cluster fractions, with the accuracy of each (median held-out in-lobe relative
// RMS error over all fitted points). Writes CSV to stdout.
//
//   dmf_bench [grid_points] [dots] [camera_width_px] [fractions...]
//   e.g. build/bench/dmf_bench 200 40 640 0 0.003 0.01 0.03 0.1
// (fraction 0 = every point fitted). docs/benchmarks.md records the figures.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "thinslab/core/memory.h"
#include "thinslab/fit/dmf_map_fit.h"
#include "thinslab/fit/dmf_processing.h"
#include "thinslab/sim/synthesize_dot_scan_session.h"

int main(int argc, char** argv) {
  using namespace thinslab;
  const int points = argc > 1 ? std::atoi(argv[1]) : 100;
  const int dots = argc > 2 ? std::atoi(argv[2]) : 40;
  const int camera_width = argc > 3 ? std::atoi(argv[3]) : 480;
  std::vector<double> fractions;
  for (int k = 4; k < argc; ++k) fractions.push_back(std::atof(argv[k]));
  if (fractions.empty()) fractions = {0, 0.01, 0.03, 0.1};

  const std::string dir = (std::filesystem::temp_directory_path() / "thinslab_dmf_bench").string();
  std::filesystem::remove_all(dir);
  SyntheticDotScanOptions sim;
  sim.session.grid_nx = dots;
  sim.session.grid_ny = dots;
  sim.rig.camera_width_px = camera_width;
  sim.rig.camera_height_px = camera_width * 3 / 4;
  sim.sample.photons_per_region = 1000000;
  sim.sample.table_bins = 96;
  const auto t0 = std::chrono::steady_clock::now();
  SyntheticDotScanResult result;
  Status s = SynthesizeDotScanSession(sim, dir, &result);
  if (!s.ok()) {
    std::fprintf(stderr, "error: %s\n", s.message().c_str());
    return 1;
  }
  const double sim_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::fprintf(stderr, "simulated %d frames in %.1f s (tables %.1f s)\n", result.frames, sim_s, result.tracing_s);

  DmfProcessingOptions processing;
  processing.pitch_m = 0.08 / points;
  processing.hold_out = true;
  DmfSliceSet slices;
  DmfProcessingReport report;
  s = PrepareDotScanSlices(dir, processing, &slices, &report);
  if (!s.ok()) {
    std::fprintf(stderr, "error: %s\n", s.message().c_str());
    return 1;
  }
  std::printf("points,dots,camera_px,fraction,fitted,processing_s,dot_geometry_s,merge_s,clustering_s,model_fit_s,"
              "interpolation_s,fit_total_s,chain_s,median_held_out,slice_mib,peak_mib\n");
  for (double fraction : fractions) {
    DmfMapFitOptions options;
    options.cluster = fraction > 0;
    if (fraction > 0) options.clustering.fraction = fraction;
    DmfMaps maps;
    s = FitDualMicrofacetMaps(slices, options, &maps);
    if (!s.ok()) {
      std::fprintf(stderr, "error: %s\n", s.message().c_str());
      return 1;
    }
    std::vector<double> errors;
    for (int p = 0; p < slices.num_points(); ++p) {
      const double e = DmfHeldOutError(slices, maps, p);
      if (e >= 0) errors.push_back(e);
    }
    std::nth_element(errors.begin(), errors.begin() + errors.size() / 2, errors.end());
    const double median = errors.empty() ? -1 : errors[errors.size() / 2];
    std::printf("%d,%d,%d,%g,%d,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.2f,%.4f,%.1f,%.1f\n", slices.num_points(),
                slices.num_dots(), camera_width, fraction, maps.num_fitted, report.total_s, report.geometry_s,
                report.merge_s, maps.timings.clustering_s, maps.timings.representative_fit_s,
                maps.timings.interpolation_s, maps.timings.total_s, report.total_s + maps.timings.total_s, median,
                report.slice_bytes / 1048576.0, PeakResidentMemoryMiB());
    std::fflush(stdout);
  }
  std::filesystem::remove_all(dir);
  return 0;
}
