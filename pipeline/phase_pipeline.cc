// SPDX-License-Identifier: Apache-2.0
// The laser-lobe fit of g (Gu et al. 2007, Sec. 5.2, Eq. 8) from a capture folder.
#include "thinslab/pipeline/phase_pipeline.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/plot.h"
#include "thinslab/core/provenance.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/version.h"
#include "thinslab/pipeline/folder_report.h"
#include "thinslab/pipeline/calibration_summary.h"
#include "thinslab/pipeline/capture_reading.h"
#include "thinslab/pipeline/prediction_report.h"

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
                        const nlohmann::json& truth, const nlohmann::json& validation, double layer_albedo,
                        const Provenance& provenance) {
  const SessionCalibration& calibration = images.calibration;
  nlohmann::json j;
  j["format"] = "thinslab-fit-summary";
  j["provenance"] = ProvenanceJson(provenance);
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
  j["predicted_second_order_fraction"] = s.predicted_second_order_fraction;
  j["sigma_g_predicted_second_order"] = s.sigma_g_predicted_second_order;
  j["sigma_g_choice"] = s.sigma_g_choice;
  j["beta"] = s.beta;
  j["sigma_log_beta"] = s.sigma_log_beta;
  j["tau"] = s.tau;
  j["sigma_tau"] = s.sigma_tau;
  j["layer_albedo"] =
      layer_albedo;  // Given (--albedo), not measured: sigma_g's second-order term and the render use it.
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

}  // namespace

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
  THINSLAB_RETURN_IF_ERROR(
      WriteFileAtomically(JoinPath(out.path(), "summary.json"),
                          SummaryJson(*summary, images, capture, truth, validation, options.layer_albedo,
                                      {"fit phase", session_dir, "", options_ini})));
  THINSLAB_RETURN_IF_ERROR(
      WriteFileAtomically(JoinPath(out.path(), "summary.txt"), summary->FullReport() + validation_text));
  if (!validation_text.empty()) std::cout << validation_text;
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "rings.csv"), RingsCsv(*rings)));
  if (has_ladder) {
    THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "ladder.json"), LaserLadderJson(ladder_result)));
  }
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "options.ini"), options_ini));
  THINSLAB_RETURN_IF_ERROR(WriteLobePlot(JoinPath(out.path(), "lobe_plot.png"), *rings, *summary));
  THINSLAB_RETURN_IF_ERROR(WriteFolderReport(out.path(), out_dir, "thinslab fit phase: " + session_dir));
  return out.Commit();
}

}  // namespace thinslab
