// SPDX-License-Identifier: Apache-2.0
// `thinslab fit dmf CAPTURE`: dual-microfacet SVBTDF maps from a CRT dot scan (Dai et al. 2009;
// fit/dmf_processing.h, fit/dmf_map_fit.h). Writes, atomically, into CAPTURE/fit/dmf/:
//   maps.exr         alpha, smith_alpha, k_s, rho_d, residual, status, measured_ndf_fraction,
//                    transmittance (docs/format.md)
//   ndf_atlas.exr    channel D: the N x N NDF tile of every atlas_stride-th point
//   *_falsecolor.png the maps; ndf_<col>_<row>.png the NDF at chosen points (Dai Fig. 6)
//   summary.json/.txt timings per stage, status counts, peak memory; options.ini
//   comparison.json  per-region accuracy when the capture has ground_truth/truth.json (sim)
//   ladder.exr       with --ladder: the issue #8 rung chosen per point and each rung's error
#include <cstdio>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <map>
#include <sstream>

#include "thinslab/app/calibration_options.h"
#include "thinslab/app/capture_options.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/command_progress.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/pipeline/dmf_pipeline.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/false_color.h"
#include "thinslab/core/file.h"
#include "thinslab/core/memory.h"
#include "thinslab/core/parallel.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/version.h"
#include "thinslab/fit/dmf_evaluation.h"
#include "thinslab/fit/dmf_map_fit.h"
#include "thinslab/fit/dmf_model_ladder.h"
#include "thinslab/fit/dmf_processing.h"

namespace thinslab {

int RunFitDmf(int argc, char** argv) {
  FitDmfRun run;
  std::string session_dir, out_dir;
  double pitch_mm = 0;
  OptionParser parser("fit dmf");
  parser.AddPositional("CAPTURE", &session_dir, "CRT dot-scan capture session folder");
  parser.AddString("out", &out_dir, "output folder (default CAPTURE/fit/dmf)");
  parser.AddDouble("pitch-mm", &pitch_mm, "sample grid pitch [mm]; 0 = the manifest's");
  parser.AddDouble("eta", &run.eta, "slab refractive index; 0 = the manifest's sample.glass_ior");
  parser.AddInt("ndf-resolution", &run.fit.point.ndf_resolution, "N of the N x N NDF grid");
  parser.AddDouble("smoothness", &run.fit.point.smoothness, "weight of the Eq. 17 Laplacian rows");
  parser.AddString("ndf-tail", &run.fit.point.ndf_tail,
                   "the NDF beyond the hull of the measured cells: 'smooth' (Eq. 17's fill) or 'family' (the "
                   "analytic family fitted to the measured cells)");
  parser.AddDouble("ndf-tail-max-misfit", &run.fit.point.ndf_tail_max_misfit,
                   "--ndf-tail family only where the family fits the measured cells within this relative L2 misfit");
  parser.AddBool("fit-smith", &run.fit.point.fit_smith_alpha, "fit the Smith roughness (Levenberg-Marquardt)");
  parser.AddDouble("alpha-lobe-fraction", &run.fit.point.alpha_lobe_fraction,
                   "Eq. 18 compares mean directions over the dots above this fraction of the lobe's peak");
  parser.AddDouble("min-measured-ndf-fraction", &run.fit.point.min_measured_ndf_fraction,
                   "below this measured share of the fitted NDF: status undersampled");
  parser.AddDouble("max-edge-fraction", &run.fit.point.max_edge_fraction,
                   "lobe above this fraction of its peak on two opposite borders of the dot grid: status undersampled");
  parser.AddDouble("max-alpha-residual", &run.fit.point.max_alpha_residual,
                   "Eq. 18 still moving alpha by more than this at the result: status not_converged");
  parser.AddDouble("max-transmittance", &run.fit.point.max_transmittance,
                   "above this directional transmittance of the fit: status unphysical");
  parser.AddDouble("max-k-s", &run.fit.point.max_k_s, "above this k_s: status unphysical");
  parser.AddDouble("family-ratio", &run.fit.point.roughness.family_ratio,
                   "ndf_family: the GGX or Beckmann fit whose misfit is smaller by this factor; closer: undecided");
  parser.AddDouble("one-face-alpha", &run.fit.point.roughness.one_face_alpha,
                   "rough_face: top at alpha >= this, bottom at alpha <= 1 - this, else both");
  parser.AddDouble("min-unit-transmittance", &run.fit.point.min_unit_transmittance,
                   "below this directional transmittance per unit k_s: status unphysical");
  parser.AddBool("split-half", &run.fit.split_half,
                 "also fit each half of the training dots (error bars of alpha and roughness; 3x the point-fit time)");
  parser.AddDouble("cluster-fraction", &run.cluster_fraction, "k-means representatives per point; 0 = fit every point");
  parser.AddInt("neighbors", &run.fit.clustering.num_neighbors, "representatives per interpolated point (Eq. 20)");
  parser.AddBool("hold-out", &run.processing.hold_out, "hold out dots from the fit (--hold-out-pattern)");
  HoldOutPattern& pattern = run.processing.hold_out_pattern;
  parser.AddString("hold-out-pattern", &pattern.kind,
                   "checkerboard (every other dot), random (--hold-out-fraction, --hold-out-seed) or blocks "
                   "(--hold-out-block x block tiles of dots in a checkerboard)");
  parser.AddDouble("hold-out-fraction", &pattern.fraction, "random pattern: share of dots held out (0, 0.9]");
  parser.AddInt("hold-out-block", &pattern.block, "blocks pattern: tile side in dots (1..64)");
  parser.AddUint64("hold-out-seed", &pattern.seed, "random pattern: seed");
  parser.AddBool("refine-monitor-distance", &run.processing.dot_geometry.refine_distance,
                 "set the monitor distance d from the all-dots grid's scale (not with calib dots' rig.json)");
  // rig.json's dot radius and positions replace these when it holds calib dots' dot calibration.
  AddDotDetectionOptions(&parser, &run.processing.dot_geometry, &run.processing.dot_radius_px);
  double glass_thickness_mm = -1;
  parser.AddDouble("glass-thickness-mm", &glass_thickness_mm,
                   "slab thickness [mm] (where the dots' light enters); -1 = rig.sample.glass_thickness_m");
  AddCalibrationOptions(&parser, &run.processing.calibration);
  AddIncompleteCaptureOption(&parser, &run.allow_incomplete_capture);
  parser.AddInt("threads", &run.fit.num_threads, "threads");
  parser.AddInt("atlas-stride", &run.atlas_stride, "NDF atlas keeps every n-th point; 0 = at most 64 x 64 tiles");
  parser.AddString("ndf-pixels", &run.ndf_pixels, "points for NDF pictures, '<col>,<row>;...'");
  parser.AddBool("ladder", &run.ladder, "also fit the issue #8 model ladder and pick per tile (needs --hold-out)");
  parser.AddInt("ladder-tile", &run.ladder_tile, "grid points per side of a ladder tile (its points decide together)");
  parser.AddString("ladder-criterion", &run.ladder_criterion,
                   "held-out (simplest rung within noise of the best on held-out dots) or bic (training data)");
  parser.AddBool("ladder-apply", &run.ladder_apply,
                 "maps.exr and the NDF atlas hold the chosen rung's model (false: the tabulated fit everywhere)");
  std::string pixel;
  parser.AddString("pixel", &pixel, "X,Y: print this map point's dots, alpha iterations and result (as pbrt's --pixel)");
  parser.MarkDiagnostic("pixel");
  // Issue #29: neither changes the maps, so neither enters the options digest.
  double max_memory_gib = kDefaultMaxMemoryGiB;
  parser.AddDouble("max-memory", &max_memory_gib,
                   "memory budget [GiB] of the whole fit; a larger grid streams its slices from disk (same maps); "
                   "0 = no budget");
  parser.MarkDiagnostic("max-memory");
  parser.AddString("spill-dir", &run.processing.spill_dir,
                   "folder of the streamed slices' file (unlinked, never left behind); default: beside the output");
  parser.MarkDiagnostic("spill-dir");
  parser.AddInt("stream-band-points", &run.processing.stream_band_points,
                "stream the slices from disk whatever --max-memory, in bands of at most this many points (whole "
                "grid rows); 0 = only over the budget");
  parser.MarkDiagnostic("stream-band-points");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status = ParsePixelTrace(pixel, "--pixel", &run.fit.trace);
  run.fit.trace.out = &std::cout;
  if (status.ok()) status = CheckDotRadiusOption(parser, run.processing.dot_radius_px);
  if (status.ok() && !(max_memory_gib >= 0 && max_memory_gib <= 1 << 20)) {
    status = Status::Error("--max-memory: must be >= 0 GiB (0 = no budget), got " + std::to_string(max_memory_gib));
  }
  run.processing.max_memory_bytes = max_memory_gib * double(1u << 30);
  run.processing.pitch_m = pitch_mm * 1e-3;
  run.processing.glass_thickness_m = glass_thickness_mm < 0 ? -1 : glass_thickness_mm * 1e-3;
  if (status.ok() && parser.IsSet("glass-thickness-mm") && glass_thickness_mm != -1 &&
      !(glass_thickness_mm >= 0 && glass_thickness_mm <= 50)) {
    status = Status::Error("--glass-thickness-mm: must be in [0, 50] mm (or -1: the manifest's), got " +
                           std::to_string(glass_thickness_mm));
  }
  if (out_dir.empty()) out_dir = JoinPath(JoinPath(session_dir, "fit"), "dmf");
  run.options_ini = parser.ToIni();
  run.fit.progress = CommandProgress();
  run.processing.progress = run.fit.progress;
  std::string brief;
  if (status.ok()) status = FitDmfPipeline(session_dir, out_dir, run, &brief);
  if (!status.ok()) return CommandFailed(status);
  std::cout << brief << "wrote " << out_dir << "\n";
  return 0;
}

}  // namespace thinslab
