// SPDX-License-Identifier: Apache-2.0
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "thinslab/app/calibration_options.h"
#include "thinslab/app/capture_options.h"
#include "thinslab/app/command_progress.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/subcommands.h"
#include "thinslab/pipeline/layer_from_phase.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/pipeline/prediction_report.h"
#include "thinslab/calib/shadow_map_preparation.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/false_color.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/version.h"

namespace thinslab {

void AddFitTauOptions(OptionParser* parser, FitTauRun* run) {
  TauFitOptions& fit = run->fit;
  parser->AddBool("refine", &fit.refine_scattering, "model the scattered light (Gu Eq. 6); false = plain Eq. 7");
  parser->AddDouble("albedo", &fit.layer_albedo, "layer single-scattering albedo omega0 [0, 1]");
  parser->AddDouble("g", &fit.layer_g, "layer Henyey-Greenstein g (-1, 1)");
  parser->AddString("reference", &fit.reference,
                    "'frame' (clean-glass frames), 'auto' (surface fitted to clean regions) or 'flat' "
                    "(calib/flat_field.exr scaled to clean regions)");
  parser->AddDouble("tau-max", &fit.tau_max, "largest tau; darker pixels are clamped and flagged");
  parser->AddDouble("min-reference-fraction", &fit.min_reference_fraction, "dark mask threshold (of median)");
  parser->AddDouble("max-sigma-tau", &fit.max_sigma_tau, "tau noise above this: status 1 (dark)");
  parser->AddDouble("max-mixed-tau-step", &fit.max_mixed_tau_step,
                    "tau change across one camera footprint above which a pixel is mixed (status 6)");
  parser->AddBool("split-half-check", &run->split_half_check,
                  "also fit the even and odd shadow frames apart and compare them (summary.json consistency)");
  parser->AddDouble("smoothness-sigma-tau", &fit.smoothness_sigma_tau, "Huber smoothness prior scale; 0 = off");
  parser->AddInt("max-outer-iterations", &fit.max_outer_iterations, "scatter fixed-point iterations");
  parser->AddDouble("kernel-max-angle-deg", &fit.kernel_max_angle_deg, "largest scattering angle modelled");
  parser->AddInt("threads", &fit.num_threads, "threads for Ceres");
  parser->AddInt("supersample", &run->supersample, "rectification samples per pixel side");
  parser->AddDouble("board-distance-m", &run->board_distance_m,
                    "override of the manifest's board distance [m] (0: the manifest's); also the plane the frames are "
                    "rectified onto");
  AddCalibrationOptions(parser, &run->calibration);
  AddIncompleteCaptureOption(parser, &run->allow_incomplete_capture);
}

namespace {

int RunFitTau(int argc, char** argv) {
  FitTauRun run;
  std::string session_dir, out_dir;
  OptionParser parser("fit tau");
  parser.AddPositional("CAPTURE", &session_dir, "shadow-map capture session folder");
  parser.AddString("out", &out_dir, "output folder (default CAPTURE/fit/tau)");
  AddFitTauOptions(&parser, &run);
  parser.AddString("phase", &run.phase_dir,
                   "`fit phase` output folder of the same layer: its model ladder choice sets --refine and --g");
  std::string pixel;
  parser.AddString("pixel", &pixel, "X,Y: print this map pixel's data, iterations and result (as pbrt's --pixel)");
  parser.MarkDiagnostic("pixel");
  // Issue #29: does not change the maps, so it does not enter the options digest.
  double max_memory_gib = run.max_memory_bytes / double(1u << 30);
  parser.AddDouble("max-memory", &max_memory_gib,
                   "memory budget [GiB]: a map whose estimated need exceeds it is refused before any frame is read "
                   "(the fit keeps every map point in memory); 0 = no budget");
  parser.MarkDiagnostic("max-memory");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status = ParsePixelTrace(pixel, "--pixel", &run.fit.trace);
  run.fit.trace.out = &std::cout;
  if (status.ok() && !(max_memory_gib >= 0 && max_memory_gib <= 1 << 20)) {
    status = Status::Error("--max-memory: must be >= 0 GiB (0 = no budget), got " + std::to_string(max_memory_gib));
  }
  run.max_memory_bytes = max_memory_gib * double(1u << 30);
  if (status.ok() && !run.phase_dir.empty() && (parser.IsSet("g") || parser.IsSet("refine"))) {
    status = Status::Error("thinslab fit tau: --phase sets the layer's g and --refine; give either --phase or --g/--refine");
  }
  if (out_dir.empty()) out_dir = JoinPath(JoinPath(session_dir, "fit"), "tau");
  run.options_ini = parser.ToIni();
  run.fit.progress = CommandProgress();
  TauFitSummary summary;
  TauComparison comparison;
  bool has_truth = false;
  if (status.ok()) status = FitTauPipeline(session_dir, out_dir, run, &summary, &comparison, &has_truth);
  if (!status.ok()) return CommandFailed(status);
  std::cout << summary.BriefReport() << "\nwrote " << out_dir << "\n";
  if (has_truth) std::cout << comparison.ToJson();
  return 0;
}

}  // namespace

const std::vector<Subcommand>& FitSubcommands() {
  static const std::vector<Subcommand> table = {
      {"tau", RunFitTau, "CAPTURE", "optical thickness map from shadow maps (Gu et al. 2007 Eqs. 5-7)"},
      {"phase", RunFitPhase, "CAPTURE", "Henyey-Greenstein g from the laser lobe (Gu et al. 2007 Eq. 8)"},
      {"dmf", RunFitDmf, "CAPTURE", "dual-microfacet SVBTDF maps from a dot scan (Dai et al. 2009)"},
  };
  return table;
}

int RunFit(int argc, char** argv) { return DispatchSubcommand("fit", FitSubcommands(), argc, argv); }

}  // namespace thinslab
