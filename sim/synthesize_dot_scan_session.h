// SPDX-License-Identifier: Apache-2.0
// SynthesizeDotScanSession: the simulated CRT dot rig (sim/sim_dot_monitor.h) with the region
// sample (sim/slab_sample.h) in the light path, driven by the unchanged acquisition script
// RunDotScanSession (all-dots frame without the sample, dark bracket and one bracket per dot
// with it), writing a real capture session plus its ground truth
// (docs/models/dot_scan_rig.md, docs/format.md):
//   <session>/ground_truth/truth.json    sample rectangle; every region: rectangle [m], NDF kinds,
//                                        alphas, eta, rho_d, k_s, traced view direction (sample
//                                        and optical frame), table statistics; conventions
//   <session>/ground_truth/regions.exr   channel "region": region index (-1 off the sample) on the
//                                        manifest's sample grid (rig.sample region and pitch)
//   <session>/ground_truth/btdf_tables.exr  channel "region_<k>" per rough region: the Monte
//                                        Carlo table rho(i, o_k) [1/sr] on the orthographic
//                                        (i.x, i.y) grid of the sample frame (row = i.y)
#pragma once

#include <memory>
#include <string>

#include "thinslab/acquire/dot_scan_session.h"
#include "thinslab/core/progress.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"
#include "thinslab/sim/sim_dot_monitor.h"
#include "thinslab/sim/slab_sample.h"

namespace thinslab {

struct SyntheticDotScanOptions {
  // The constructor sets the defaults of this rig (test size): camera 240 x 180 px viewing
  // 0.12 m, no distortion, 2 x 2 supersampling; 16 x 16 dots over 96 % of a 400 x 400 px,
  // 0.25 mm screen (0.096 m, 1.2 x the sample) centred d tan(45 deg) = 0.04 m away from the
  // camera; dot_radiance 0.05; exposures of 1 and 800 refresh periods; sample 0.08 m square, the
  // nine-region preset, 200000 photons per region, 64 x 64 table bins.
  SyntheticDotScanOptions();

  SimDotMonitorOptions rig;
  DotScanSessionOptions session;  // monitor_width_px/height_px are taken from `rig`.
  SlabSampleOptions sample;       // Empty regions = DefaultSlabRegions.
  double truth_pitch_m = 0.25e-3;  // Pitch of regions.exr and of the manifest's sample grid.
  int validation_dots = 0;  // DotScanValidationDots of the grid, captured as validation frames.
  std::string name = "sim_dot_scan";
  // Reports the frames rendered of those planned; returning false cancels (core/progress.h).
  ProgressCallback progress;

  Status Check() const;  // Errors name the struct and field.
};

struct SyntheticDotScanResult {
  std::shared_ptr<const SlabSample> sample;  // Region materials and tables (ground truth).
  RigInfo rig;
  double tracing_s = 0;      // Monte Carlo tables.
  double acquisition_s = 0;  // Rendering, sensor, PNG writing of the whole session.
  int frames = 0;            // Frames recorded.
};

// Builds the rig with the sample attached (traces the tables for the rig's camera); the sample
// is out of the path until the sample state changes to something other than "none".
Status BuildDotScanRig(const SyntheticDotScanOptions& options, std::unique_ptr<SimDotMonitor>* rig,
                       std::shared_ptr<const SlabSample>* sample);

// Writes <session_dir>/ground_truth/ (regions.exr, btdf_tables.exr, truth.json; see the top of
// this file) for a dot scan of `sample` on `monitor`, built from `options` (BuildDotScanRig);
// `acquisition_s` is recorded. Also used by `thinslab acquire dot-scan --sim-sample`.
Status WriteDotScanTruth(const SyntheticDotScanOptions& options, const SlabSample& sample, const SimDotMonitor& monitor,
                         double acquisition_s, const std::string& session_dir);

// `session_dir` must not exist yet (or be empty). `result` may be null.
Status SynthesizeDotScanSession(const SyntheticDotScanOptions& options, const std::string& session_dir,
                                SyntheticDotScanResult* result = nullptr);

}  // namespace thinslab
