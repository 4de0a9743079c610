// SPDX-License-Identifier: Apache-2.0
// `thinslab sim laser` and `thinslab fit phase`: the laser-lobe measurement of g (Gu et al.
// 2007, Sec. 5.2).
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <sstream>

#include "thinslab/app/calibration_options.h"
#include "thinslab/app/capture_options.h"
#include "thinslab/app/commands.h"
#include "thinslab/fit/laser_lobe_ladder.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/app/prediction_report.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/plot.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/version.h"
#include "thinslab/sim/laser_lobe_rig.h"

namespace thinslab {
namespace {

std::string RingsCsv(const std::vector<LaserRing>& rings) {
  std::ostringstream out;
  out.precision(9);
  out << "r_m,theta_deg,intensity_dn_per_us,sigma,pixels,model\n";
  for (const auto& r : rings) {
    out << r.r_m << "," << r.theta_rad * 180 / kPi << "," << r.intensity << "," << r.sigma << "," << r.pixels << ","
        << r.model << "\n";
  }
  return out.str();
}

Status WriteLobePlot(const std::string& path, const std::vector<LaserRing>& rings, const PhaseFitSummary& s) {
  PlotPanel data, residual;
  PlotSeries points, fit, res;
  points.label = "rings (median +- std. error)";
  points.color_bgr = 0x1f77b4;
  fit.label = "Gu Eq. 8 fit";
  fit.line = true;
  fit.color_bgr = 0xd62728;
  res.color_bgr = 0x1f77b4;
  for (const auto& r : rings) {
    const double theta_deg = r.theta_rad * 180 / kPi;
    points.x.push_back(theta_deg);
    points.y.push_back(r.intensity);
    points.y_error.push_back(r.sigma);
    if (s.IsUsable()) {
      fit.x.push_back(theta_deg);
      fit.y.push_back(r.model);
      res.x.push_back(theta_deg);
      res.y.push_back((r.intensity - r.model) / r.sigma);
    }
  }
  data.series = {points};
  if (s.IsUsable()) data.series.push_back(fit);
  data.log_y = true;
  data.y_label = "board radiance [DN/us], flat-fielded";
  data.height_weight = 3;
  std::vector<PlotPanel> panels = {data};
  if (s.IsUsable()) {
    residual.series = {res};
    residual.y_label = "residual / std. error";
    residual.zero_line = true;
    panels.push_back(residual);
  }
  PlotOptions options;
  char title[200];
  if (s.IsUsable()) {
    std::snprintf(title, sizeof(title), "laser lobe: g = %.3f +- %.3f, tau = %.3g, chi2/dof = %.2f (%s)", s.g,
                  s.sigma_g, s.tau, s.chi2_reduced, s.categories.empty() ? "no category" : s.categories[0].c_str());
  } else {
    std::snprintf(title, sizeof(title), "laser lobe: %s", s.ResultName().c_str());
  }
  options.title = title;
  options.x_label = "theta = atan(r / d) [deg]";
  return WritePlotPng(path, panels, options);
}

std::string SummaryJson(const PhaseFitSummary& s, const LaserLobeImages& images, const CaptureCompleteness& capture,
                        const nlohmann::json& truth, const nlohmann::json& validation) {
  const SessionCalibration& calibration = images.calibration;
  nlohmann::json j;
  j["format"] = "thinslab-fit-summary";
  j["format_version"] = "1.0";
  j["model"] = "gu2007_eq8";
  j["result"] = s.ResultName();
  j["message"] = s.message;
  j["g"] = s.g;
  j["sigma_g"] = s.sigma_g;
  j["sigma_g_covariance"] = s.sigma_g_covariance;
  j["sigma_g_jackknife"] = s.sigma_g_jackknife;
  j["jackknife_method"] = s.jackknife_method;
  j["sigma_g_range"] = s.range_term_available ? nlohmann::json(s.sigma_g_range) : nlohmann::json(nullptr);
  j["sigma_g_multiple"] = s.sigma_g_multiple;
  j["second_order_fraction"] = s.second_order_fraction;
  j["sigma_g_choice"] = s.sigma_g_choice;
  j["beta"] = s.beta;
  j["sigma_log_beta"] = s.sigma_log_beta;
  j["tau"] = s.tau;
  j["sigma_tau"] = s.sigma_tau;
  j["chi2_reduced"] = s.chi2_reduced;
  j["rms_normalized_residual"] = s.rms_normalized_residual;
  j["detection_significance"] = s.detection_significance;
  j["rings"] = s.num_rings;
  j["theta_range_deg"] = {s.theta_min_deg, s.theta_max_deg};
  j["max_theta_deg"] = s.max_theta_deg;
  nlohmann::json trials = nlohmann::json::array();
  for (const auto& [theta, sigma_g] : s.max_theta_trials) {
    trials.push_back({{"max_theta_deg", theta}, {"sigma_g", sigma_g >= 0 ? nlohmann::json(sigma_g) : nlohmann::json(nullptr)}});
  }
  j["max_theta_trials"] = trials;
  j["beam_centre_m"] = {s.beam_centre_m.x(), s.beam_centre_m.y()};
  j["board_distance_m"] = images.board_distance_m;  // The manifest's, or --board-distance-m.
  j["board_pitch_m"] = images.pixel_pitch_m;        // The manifest's, or --board-pitch-m.
  j["ring_estimator"] = "mean, sector-cluster standard error";
  j["noise"] = images.noise.ToJson();
  j["categories"] = s.categories;
  j["warnings"] = s.warnings;
  j["calibration"] = CalibrationSummaryJson(calibration);
  j["capture"] = CaptureSummaryJson(capture);
  j["exposure_check"] = ExposureCheckJson(images.lobe.exposure_check, false);
  j["flat_fielded"] = s.flat_fielded;
  j["clean_subtracted"] = s.clean_subtracted;
  j["timings_s"] = {{"fit", s.total_s}};
  j["validation"] = validation;
  j["thinslab_version"] = THINSLAB_VERSION_STRING;
  j["git_hash"] = THINSLAB_GIT_HASH;
  if (!truth.is_null()) j["ground_truth"] = truth;
  return j.dump(2) + "\n";
}

// Median tau over the ok pixels of a `fit tau` map.
Status MedianTauFromMap(const std::string& path, double* tau) {
  Image map;
  THINSLAB_RETURN_IF_ERROR(ReadExr(path, &map));
  const int c = map.ChannelIndex("tau"), st = map.ChannelIndex("status");
  if (c < 0 || st < 0) return Status::Error(path + ": needs channels 'tau' and 'status' (a `thinslab fit tau` map)");
  std::vector<float> values;
  for (int y = 0; y < map.height(); ++y) {
    for (int x = 0; x < map.width(); ++x) {
      if (map.at(x, y, st) == 0) values.push_back(map.at(x, y, c));
    }
  }
  if (values.empty()) return Status::Error(path + ": no pixel with status 0");
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  *tau = values[values.size() / 2];
  return Status::Ok();
}

}  // namespace

Status FitPhasePipeline(const std::string& session_dir, const std::string& out_dir, const PhaseFitOptions& options,
                        const LaserLobePreparationOptions& preparation, bool allow_incomplete_capture,
                        const std::string& options_ini, PhaseFitSummary* summary, std::vector<LaserRing>* rings,
                        LaserLadderResult* ladder) {
  // Options are checked before any frame is read (the stages check them again).
  std::string error;
  if (!options.Check(&error) || !preparation.Check(&error)) return Status::Error(session_dir + ": " + error);
  // Refused before the work: an output that would replace an input or a folder of the user's.
  StagedDirectory out(out_dir, "fit phase", {{session_dir, {"fit"}}});
  THINSLAB_RETURN_IF_ERROR(out.Init());
  Session session;
  CaptureCompleteness capture;
  THINSLAB_RETURN_IF_ERROR(ReadCaptureForCommand(session_dir, allow_incomplete_capture, &session, &capture));
  LaserLobeImages images;
  THINSLAB_RETURN_IF_ERROR(PrepareLaserLobe(session_dir, session, preparation, &images));
  const std::string exposure_warning = images.lobe.exposure_check.Warning();
  if (!exposure_warning.empty()) std::cerr << "warning: " << session_dir << ": laser frames: " << exposure_warning << "\n";
  THINSLAB_RETURN_IF_ERROR(FitPhase(options, images, rings, summary).WithContext(session_dir));
  for (const std::string& w : summary->warnings) std::cerr << "warning: " << session_dir << ": " << w << "\n";
  // Model ladder rungs 0-2 (issue #8) on the same rings; 2 standard errors as in the dot-scan
  // ladder.
  LaserLadderResult ladder_result;
  const bool has_ladder = rings->size() >= 5;
  if (has_ladder) {
    PhaseFitOptions chosen = options;  // The rings are those of the kept outermost angle.
    chosen.max_theta_auto = false;
    chosen.max_theta_deg = summary->max_theta_deg;
    THINSLAB_RETURN_IF_ERROR(FitLaserLobeLadder(*rings, chosen, 2.0, summary, &ladder_result).WithContext(session_dir));
  }
  if (ladder != nullptr) *ladder = ladder_result;
  // A validation lobe (issue #23 section 4): a second contaminated bracket, never fitted, against
  // Eq. 8 with the fitted beta, g and tau out to the fit's outermost angle.
  nlohmann::json validation;  // null: no validation frames.
  std::string validation_text;
  if (!images.validation_lobe.empty()) {
    validation = {{"frames", images.validation_lobe.num_frames}};
    if (summary->IsUsable()) {
      PhaseFitOptions at_fit = options;
      at_fit.max_theta_auto = false;
      at_fit.max_theta_deg = summary->max_theta_deg;
      LaserLobeImages validation_images = images;
      validation_images.lobe = images.validation_lobe;
      LobePrediction prediction;
      THINSLAB_RETURN_IF_ERROR(PredictLaserLobe(at_fit, summary->beta, summary->g, summary->tau, images.board_distance_m,
                                                validation_images, &prediction)
                                   .WithContext(session_dir + ": validation laser frames"));
      validation.update(LobeBandsJson(prediction));
      validation_text = "validation lobe (" + std::to_string(images.validation_lobe.num_frames) +
                        " frames), predicted by the fitted Eq. 8:\n" + LobeBandsText(prediction);
    } else {
      validation["skipped"] = "the fit did not succeed";
    }
  }
  nlohmann::json truth;
  const std::string truth_path = JoinPath(JoinPath(session_dir, "ground_truth"), "truth.json");
  if (FileExists(truth_path)) {
    std::string text;
    THINSLAB_RETURN_IF_ERROR(ReadFileToString(truth_path, &text));
    truth = nlohmann::json::parse(text, nullptr, false);
    if (truth.is_discarded()) return Status::Error(truth_path + ": not valid JSON");
  }
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "summary.json"), SummaryJson(*summary, images, capture, truth, validation)));
  THINSLAB_RETURN_IF_ERROR(
      WriteFileAtomically(JoinPath(out.path(), "summary.txt"), summary->FullReport() + validation_text));
  if (!validation_text.empty()) std::cout << validation_text;
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "rings.csv"), RingsCsv(*rings)));
  if (has_ladder) {
    THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "ladder.json"), LaserLadderJson(ladder_result)));
  }
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "options.ini"), options_ini));
  THINSLAB_RETURN_IF_ERROR(WriteLobePlot(JoinPath(out.path(), "lobe_plot.png"), *rings, *summary));
  return out.Commit();
}

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
  Status status = parser.Parse(argc, argv);
  if (parser.help_requested()) {
    std::cout << parser.Usage();
    return 0;
  }
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
  if (!status.ok()) {
    std::cerr << "error: " << status.message() << "\n";
    return 1;
  }
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
  Status status = parser.Parse(argc, argv);
  if (status.ok() && !exposures.empty()) {
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
  if (parser.help_requested()) {
    std::cout << parser.Usage();
    return 0;
  }
  rig.board_distance_m = distance_mm * 1e-3;
  rig.beam_radius_m = beam_radius_mm * 1e-3;
  rig.beam_offset_m = Eigen::Vector2d(offset_x_mm, offset_y_mm) * 1e-3;
  NewFolderGuard new_output(out_dir);
  if (status.ok()) status = SynthesizeLaserLobeSession(options, out_dir);
  if (!status.ok()) {
    std::cerr << "error: " << status.message() << "\n";
    return 1;
  }
  new_output.Keep();
  std::cout << "wrote laser-lobe session " << out_dir << "\n";
  return 0;
}

}  // namespace thinslab
