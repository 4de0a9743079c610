// SPDX-License-Identifier: Apache-2.0
// `thinslab sim laser` and `thinslab fit phase` (pipeline/phase_pipeline.h): the laser-lobe
// measurement of g (Gu et al. 2007, Sec. 5.2).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "thinslab/app/calibration_options.h"
#include "thinslab/app/capture_options.h"
#include "thinslab/app/command_progress.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/plot.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/version.h"
#include "thinslab/fit/laser_lobe_ladder.h"
#include "thinslab/pipeline/prediction_report.h"
#include "thinslab/sim/laser_lobe_rig.h"

namespace thinslab {

int RunFitPhase(int argc, char** argv) {
  PhaseFitOptions options;
  LaserLobePreparationOptions preparation;
  std::string session_dir, out_dir, tau_map;
  OptionParser parser("fit phase");
  parser.AddPositional("CAPTURE", &session_dir, "laser-lobe capture session folder");
  parser.AddString("out", &out_dir, "output folder (default CAPTURE/fit/phase)");
  parser.AddDouble("tau", &options.tau, "layer optical thickness (given)");
  parser.AddString("tau-map", &tau_map, "take tau as the median of a `fit tau` map (tau.exr) of the same layer");
  parser.AddBool("tau-free", &options.tau_free, "fit tau too, with a Gaussian prior around --tau");
  parser.AddDouble("tau-prior-sigma", &options.tau_prior_sigma, "prior standard deviation of tau");
  parser.AddDouble("albedo", &options.layer_albedo,
                   "layer single-scattering albedo omega0 [0, 1] (given, as for fit tau): bounds sigma_g's "
                   "multiple-scattering term");
  parser.AddDouble("ring-width-px", &options.ring_width_px, "ring width [board pixels]");
  parser.AddDouble("core-beam-radii", &options.core_beam_radii, "excluded core radius [beam radii]");
  parser.AddDouble("core-margin-px", &options.core_margin_px, "excluded core: at least beam radius + this [px]");
  std::string max_theta = "auto";
  parser.AddString("max-theta-deg", &max_theta,
                   "outermost ring angle [deg], or auto: of 30, 45 and 60 the one whose fit has the smallest sigma_g");
  parser.AddBool("subtract-clean", &options.subtract_clean, "subtract the clean-glass lobe if captured");
  parser.AddBool("flat-field", &options.flat_field, "divide by the board flat field if captured");
  parser.AddDouble("huber-scale", &options.huber_scale, "robust loss scale [standard errors]");
  parser.AddDouble("min-significance", &options.min_significance, "lobe detection threshold [sigma]");
  parser.AddDouble("max-sigma-g", &options.max_sigma_g, "sigma_g above this: g not determined (failure)");
  parser.AddInt("supersample", &preparation.supersample, "rectification sub-samples per board pixel side");
  parser.AddDouble("board-distance-m", &preparation.board_distance_m,
                   "override of the manifest's board distance [m] (0: the manifest's); also the plane the frames are "
                   "rectified onto");
  parser.AddDouble("board-pitch-m", &preparation.board_pitch_m,
                   "board grid pitch the lobe is rectified onto [m] (0: the manifest's rig.sample.pixel_pitch_m)");
  AddCalibrationOptions(&parser, &preparation.calibration);
  bool allow_incomplete = false;
  AddIncompleteCaptureOption(&parser, &allow_incomplete);
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  if (status.ok() && max_theta != "auto") {
    char* end = nullptr;
    options.max_theta_deg = std::strtod(max_theta.c_str(), &end);
    options.max_theta_auto = false;
    if (end == max_theta.c_str() || *end != '\0') {
      status = Status::Error("thinslab fit phase: option --max-theta-deg = '" + max_theta + "': expected auto or degrees");
    }
  }
  if (status.ok() && !tau_map.empty()) status = MedianTauFromMap(tau_map, &options.tau);
  if (out_dir.empty()) out_dir = JoinPath(JoinPath(session_dir, "fit"), "phase");
  PhaseFitSummary summary;
  std::vector<LaserRing> rings;
  LaserLadderResult ladder;
  if (status.ok()) {
    status =
        FitPhasePipeline(session_dir, out_dir, options, preparation, allow_incomplete, parser.ToIni(), &summary, &rings,
                         &ladder);
  }
  if (!status.ok()) return CommandFailed(status);
  std::cout << summary.BriefReport() << "\n";
  if (!summary.IsUsable()) std::cout << summary.message << "\n";
  if (ladder.chosen_rung >= 0) {
    std::cout << "model ladder: rung " << ladder.chosen_rung << " (" << LaserLadderRungName(ladder.chosen_rung)
              << "); held-out chi2 per ring";
    for (int k = 0; k < kNumLaserLadderRungs; ++k) std::cout << (k ? ", " : " ") << ladder.held_out_chi2[k];
    std::cout << " (rungs 0, 1, 2; " << ladder.split << ")\n";
    if (ladder.overruled_rung >= 0) std::cout << "model ladder: " << ladder.overrule_reason << "\n";
  }
  std::cout << "wrote " << out_dir << "\n";
  return 0;
}

int RunSimLaser(int argc, char** argv) {
  SyntheticLaserSessionOptions options;
  SimLaserLobeOptions& rig = options.rig;
  std::string out_dir;
  double distance_mm = rig.board_distance_m * 1e3, beam_radius_mm = rig.beam_radius_m * 1e3;
  double offset_x_mm = 0, offset_y_mm = 0;
  OptionParser parser("sim laser");
  parser.AddPositional("OUT", &out_dir, "new session folder to write");
  parser.AddDouble("tau", &rig.layer_tau, "layer optical thickness (0 = clean glass)");
  parser.AddDouble("albedo", &rig.layer_albedo, "layer single-scattering albedo");
  parser.AddDouble("g", &rig.layer_g, "layer HG g");
  parser.AddDouble("board-distance-mm", &distance_mm, "layer-to-board distance d [mm]");
  parser.AddDouble("beam-radius-mm", &beam_radius_mm, "laser beam radius [mm]");
  parser.AddDouble("beam-offset-x-mm", &offset_x_mm, "beam axis offset from the board centre [mm]");
  parser.AddDouble("beam-offset-y-mm", &offset_y_mm, "beam axis offset from the board centre [mm]");
  parser.AddDouble("full-well-e", &rig.sensor.full_well_e, "sensor full well [electrons]");
  parser.AddDouble("read-noise-e", &rig.sensor.read_noise_e, "sensor read noise [electrons RMS]");
  parser.AddBool("noise", &rig.sensor.enable_noise, "simulate shot and read noise");
  AddSimFrameValueOptions(&parser, &rig.sensor);
  parser.AddInt("photons", &rig.monte_carlo.num_photons, "Monte Carlo photons");
  parser.AddInt("camera-width-px", &rig.camera_width_px, "camera image width");
  parser.AddInt("camera-height-px", &rig.camera_height_px, "camera image height");
  parser.AddInt("frames-per-exposure", &options.session.frames_per_exposure, "frames per bracket exposure");
  parser.AddBool("capture-clean", &options.session.capture_clean, "also capture the clean glass");
  parser.AddBool("capture-flat", &options.session.capture_flat, "also capture the board flat field");
  parser.AddBool("capture-validation", &options.session.capture_validation,
                 "also capture a second contaminated bracket marked validation (fit phase reports how well it predicts it)");
  parser.AddUint64("seed", &rig.seed, "seed of every random choice");
  parser.AddDouble("spike-fill", &rig.spike_fill, "unscattered spike at the shortest exposure / full well");
  std::string exposures;
  parser.AddString("exposures-us", &exposures, "bracket exposures, comma-separated (default 20,200,...,2000000)");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  if (!exposures.empty()) {
    options.session.exposure_times_us.clear();
    std::stringstream list(exposures);
    std::string item;
    while (status.ok() && std::getline(list, item, ',')) {
      char* end = nullptr;
      const double t = std::strtod(item.c_str(), &end);
      if (item.empty() || *end != '\0' || !(t > 0) || !std::isfinite(t)) {
        status = Status::Error("thinslab sim laser: option --exposures-us: '" + item + "' is not a positive number");
      }
      options.session.exposure_times_us.push_back(t);
    }
  }
  rig.board_distance_m = distance_mm * 1e-3;
  rig.beam_radius_m = beam_radius_mm * 1e-3;
  rig.beam_offset_m = Eigen::Vector2d(offset_x_mm, offset_y_mm) * 1e-3;
  NewFolderGuard new_output(out_dir);
  options.progress = CommandProgress();
  if (status.ok()) status = SynthesizeLaserLobeSession(options, out_dir);
  if (!status.ok()) return CommandFailed(status);
  new_output.Keep();
  std::cout << "wrote laser-lobe session " << out_dir << "\n";
  return 0;
}

}  // namespace thinslab
