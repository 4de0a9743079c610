// SPDX-License-Identifier: Apache-2.0
#include "thinslab/pipeline/tau_pipeline.h"

#include <algorithm>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "thinslab/calib/shadow_map_preparation.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/false_color.h"
#include "thinslab/core/file.h"
#include "thinslab/core/memory.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/version.h"
#include "thinslab/fit/tau_memory.h"
#include "thinslab/pipeline/calibration_summary.h"
#include "thinslab/pipeline/capture_reading.h"
#include "thinslab/pipeline/folder_report.h"
#include "thinslab/pipeline/layer_from_phase.h"
#include "thinslab/pipeline/prediction_report.h"

namespace thinslab {
namespace {

std::string SummaryJson(const TauFitSummary& s, const RectifiedShadowMaps& data, const CaptureCompleteness& capture,
                        const TauFitOptions& fit, const PhaseLayerChoice* phase, double color_max,
                        const nlohmann::json& validation, const nlohmann::json& consistency,
                        const nlohmann::json& memory, const Provenance& provenance) {
  nlohmann::json j;
  j["format"] = "thinslab-fit-summary";
  j["provenance"] = ProvenanceJson(provenance);
  j["format_version"] = "1.0";
  j["falsecolor_range"] = {0.0, color_max};
  j["result"] = s.IsUsable() ? "success" : "failure";
  j["message"] = s.message;
  j["grid"] = {s.width, s.height};
  j["pixels"] = {{"total", s.pixels_total}, {"fitted", s.pixels_fitted}, {"dark", s.pixels_dark},
                 {"saturated", s.pixels_saturated}, {"outside", s.pixels_outside}, {"clamped", s.pixels_clamped},
                 {"next_to_clamped", s.pixels_next_to_clamped}, {"dark_noise", s.pixels_dark_noise},
                 {"mixed", s.pixels_mixed}};
  j["resolution"] = {{"map_pitch_m", s.pixel_pitch_m},
                     {"camera_footprint_m", {{"median", s.camera_footprint_median_m},
                                             {"min", s.camera_footprint_min_m},
                                             {"max", s.camera_footprint_max_m}}},
                     {"camera_pixels_per_map_pixel", s.camera_pixels_per_map_pixel},
                     {"max_mixed_tau_step", fit.max_mixed_tau_step}};
  j["sigma_tau_parts_median"] = {{"noise", s.median_sigma_noise},
                                 {"reference", s.median_sigma_reference},
                                 {"multiple_scattering", s.median_sigma_model},
                                 {"resolution", s.median_sigma_resolution}};
  j["consistency"] = consistency;
  j["memory"] = memory;
  j["warnings"] = s.warnings;
  j["reference"] = {{"mode", fit.reference},
                    {"pixels_judged_clean", s.pixels_judged_clean >= 0 ? nlohmann::json(s.pixels_judged_clean)
                                                                       : nlohmann::json(nullptr)}};
  j["outer_iterations"] = s.outer_iterations;
  j["final_max_update_tau"] = s.final_max_update_tau;
  j["mean_scattered_fraction"] = s.mean_scattered_fraction;
  j["calibration"] = CalibrationSummaryJson(data.calibration);
  j["capture"] = CaptureSummaryJson(capture);
  j["layer"] = {{"albedo", fit.layer_albedo}, {"g", fit.layer_g}, {"refine_scattering", fit.refine_scattering},
                {"source", phase != nullptr ? phase->summary_path : std::string("options")}};
  if (phase != nullptr) j["layer"]["phase_ladder_rung"] = phase->rung;
  j["frames"] = {{"shadow", data.num_shadow_frames}, {"reference", data.num_reference_frames},
                 {"dark", data.num_dark_frames}};
  j["noise"] = data.noise.ToJson();
  j["timings_s"] = {{"plain", s.plain_s}, {"refine", s.refine_s}, {"fit_total", s.total_s}};
  // What predict reads back to recompute the model (fit/tau_prediction.h).
  j["model_options"] = {{"tau_max", fit.tau_max}, {"kernel_max_angle_deg", fit.kernel_max_angle_deg}};
  j["validation"] = validation;
  return j.dump(2) + "\n";
}

}  // namespace

Status FitTauPipeline(const std::string& session_dir, const std::string& out_dir, const FitTauRun& run,
                      TauFitSummary* summary, TauComparison* comparison, bool* has_truth) {
  *has_truth = false;
  // Options are checked before any frame is read (the stages check them again).
  std::string options_error;
  if (!run.fit.Check(&options_error)) return Status::Error(session_dir + ": " + options_error);
  // Refused before the work: an output that would replace an input or a folder of the user's.
  StagedDirectory out(out_dir, "fit tau", {{session_dir, {"fit"}}, {run.phase_dir, {}}});
  THINSLAB_RETURN_IF_ERROR(out.Init());
  Session session;
  CaptureCompleteness capture;
  THINSLAB_RETURN_IF_ERROR(ReadCaptureForCommand(session_dir, run.allow_incomplete_capture, &session, &capture));
  ShadowMapPreparationOptions prep_options;
  prep_options.supersample = run.supersample;
  prep_options.board_distance_m = run.board_distance_m;
  prep_options.calibration = run.calibration;
  prep_options.load_flat_field = run.fit.reference == "flat";
  prep_options.split_halves = run.split_half_check;
  TauFitOptions fit = run.fit;
  PhaseLayerChoice phase;
  if (!run.phase_dir.empty()) {
    THINSLAB_RETURN_IF_ERROR(ReadPhaseLayerChoice(run.phase_dir, &phase));
    ApplyPhaseLayerChoice(phase, &fit);
  }
  // Issue #29: the map's memory need against the budget and the machine, before any frame is read.
  const std::string manifest = JoinPath(session_dir, kSessionManifestName);
  int grid_width = 0, grid_height = 0;
  THINSLAB_RETURN_IF_ERROR(ShadowMapGridSize(session, manifest, &grid_width, &grid_height));
  if (session.rig.cameras.empty()) return Status::Error(manifest + ": rig.cameras is empty");
  const CameraInfo& camera = session.rig.cameras[0];
  const double board_distance = run.board_distance_m > 0 ? run.board_distance_m : session.rig.board.distance_m;
  const TauFitMemoryEstimate need =
      EstimateTauFitMemory(grid_width, grid_height, static_cast<int64_t>(camera.width_px) * camera.height_px,
                           board_distance, session.rig.sample.pixel_pitch_m, fit, run.split_half_check);
  const std::string what = manifest + ": the " + std::to_string(grid_width) + " x " + std::to_string(grid_height) +
                           " map (rig.sample) from a " + std::to_string(camera.width_px) + " x " +
                           std::to_string(camera.height_px) + " camera";
  if (run.max_memory_bytes > 0 && need.total_bytes() > run.max_memory_bytes) {
    char budget[48];
    std::snprintf(budget, sizeof(budget), "%.2f GiB", run.max_memory_bytes / (1024.0 * 1024 * 1024));
    return Status::Error(what + " needs about " + need.Text() + ", more than --max-memory " + budget +
                         ": give a larger --max-memory (0: no budget), --split-half-check false, or a coarser "
                         "rig.sample.pixel_pitch_m (fit tau keeps every map point in memory)");
  }
  THINSLAB_RETURN_IF_ERROR(CheckMemoryNeed(need.total_bytes(), what));
  RectifiedShadowMaps data;
  THINSLAB_RETURN_IF_ERROR(PrepareShadowMaps(session_dir, session, prep_options, &data));
  int64_t in_view = 0, saturated = 0;
  for (size_t i = 0; i < data.outside.data().size(); ++i) {
    if (data.outside.data()[i] > 0) continue;
    ++in_view;
    if (data.saturated.data()[i] > 0) ++saturated;
  }
  if (in_view == 0) {
    return Status::Error(JoinPath(session_dir, kSessionManifestName) +
                         ": rig.cameras[0].cam_from_sample: the camera does not see the board region");
  }
  if (saturated * 2 > in_view) {
    std::ostringstream msg;
    msg << session_dir << ": frames: the shadow or reference frames are saturated over "
        << (100 * saturated / in_view) << "% of the board region; lower exposure_time_us";
    return Status::Error(msg.str());
  }
  TauMaps maps;
  THINSLAB_RETURN_IF_ERROR(FitTau(fit, data, &maps, summary).WithContext(session_dir));
  // Split-half consistency (issue #24): the noise part of sigma_tau is what two fits of disjoint
  // halves of the frames must agree within.
  nlohmann::json consistency;
  if (!run.split_half_check) {
    consistency = {{"skipped", "--split-half-check false"}};
  } else if (data.halves.size() != 2) {
    consistency = {{"skipped", std::to_string(data.num_shadow_frames) +
                                   " shadow frame(s): the check needs at least 2 (capture frames_per_state >= 2)"}};
  } else {
    std::vector<TauMaps> half_maps(2);
    std::string failed;
    TauFitOptions half_fit = fit;
    half_fit.trace = PixelTrace();  // --pixel follows the fit of all frames only.
    bool cancelled = false;
    for (int k = 0; k < 2 && failed.empty(); ++k) {
      if (fit.progress) {
        half_fit.progress = [&fit, &cancelled, k](ProgressUpdate update) {
          update.stage += k == 0 ? " (split half: even frames)" : " (split half: odd frames)";
          cancelled = cancelled || !fit.progress(update);
          return !cancelled;
        };
      }
      // The half's frames take the place of all frames in `data` for its fit and are put back
      // after it: swapped, not copied (a copy of `data` was 40 bytes per map point at the peak).
      RectifiedShadowMaps::Half& frames = data.halves[k];
      auto swap_half = [&data, &frames]() {
        std::swap(data.shadow, frames.shadow);
        std::swap(data.shadow_variance, frames.shadow_variance);
        std::swap(data.reference, frames.reference);
        std::swap(data.reference_variance, frames.reference_variance);
      };
      swap_half();
      TauFitSummary half_summary;
      const Status fitted = FitTau(half_fit, data, &half_maps[k], &half_summary);
      swap_half();
      half_maps[k].reference = Image();  // Only tau and its noise part are compared.
      if (cancelled) return fitted.ok() ? Status::Error(session_dir + ": fit tau cancelled") : fitted;
      if (!fitted.ok()) failed = (k == 0 ? "even frames: " : "odd frames: ") + fitted.message();
    }
    if (!failed.empty()) {
      consistency = {{"skipped", "a half did not fit: " + failed}};
    } else {
      SplitHalfConsistency c = CompareSplitHalves(half_maps[0].tau, half_maps[0].sigma_tau_noise, half_maps[1].tau,
                                                  half_maps[1].sigma_tau_noise);
      c.shared_reference = data.halves_share_reference;
      consistency = nlohmann::json::parse(c.ToJson());
      if (c.pixels >= 100 && (c.rms_z > 1.5 || c.rms_z < 1 / 1.5)) {
        std::ostringstream msg;
        msg.precision(3);
        msg << "split-half consistency: the fits of the even and the odd frames differ by " << c.rms_z
            << " times what the noise part of sigma_tau says (RMS over " << c.pixels
            << " pixels; 1 expected): the frames' noise model is off (gain, read noise; docs/format.md 4.1) or the "
               "light changed between frames";
        summary->warnings.push_back(msg.str());
      }
    }
  }
  std::vector<RectifiedShadowMaps::Half>().swap(data.halves);  // Not needed after the check.
  for (const std::string& w : summary->warnings) std::cerr << "warning: " << session_dir << ": " << w << "\n";
  // Validation shadow frames (issue #23 section 4): the same light state as the fitted ones, so
  // the prediction is the fitted shadow the map reproduces, with that shadow's noise (the
  // reference cancels); the comparison shows repeatability (a moved sample, drifting light) and
  // whether the noise model holds. `thinslab predict` predicts other board distances.
  nlohmann::json validation;  // null: no validation frames.
  std::string validation_text;
  if (data.num_validation_frames > 0) {
    const std::vector<ShadowPredictionRegion> regions =
        CompareShadowWithMaps(fit, maps.tau, data, maps.reference, data.shadow_variance, false, nullptr);
    validation = {{"frames", data.num_validation_frames},
                  {"board_distance_m", data.board_distance_m},
                  {"regions", ShadowRegionsJson(regions)}};
    validation_text = "validation shadow (" + std::to_string(data.num_validation_frames) + " frames), predicted from the map:\n" +
                      ShadowRegionsText(regions);
  }

  const nlohmann::json memory = {{"estimated_bytes", need.total_bytes()},
                                 {"budget_bytes", run.max_memory_bytes},
                                 {"peak_resident_bytes", PeakResidentMemoryMiB() * 1024 * 1024}};
  const SampleInfo& sample = session.rig.sample;
  Image& tau = maps.tau;
  const Provenance provenance{"fit tau", session_dir, "", run.options_ini};
  SetWorldToCamera(data.camera.cam_from_sample, &tau);
  tau.numeric_attributes()["region_min_m"] = {sample.region_min_m.x(), sample.region_min_m.y()};
  tau.numeric_attributes()["region_max_m"] = {sample.region_max_m.x(), sample.region_max_m.y()};
  tau.numeric_attributes()["pixel_pitch_m"] = {data.pixel_pitch_m};
  tau.attributes()["model"] = fit.refine_scattering ? "gu2007_eq5_eq6_refined" : "gu2007_eq7";
  THINSLAB_RETURN_IF_ERROR(WriteMapExr(JoinPath(out.path(), "tau.exr"), tau, {"tau", {"status"}}, provenance));

  const Image status = tau.Channel(2);
  FalseColorOptions status_legend;
  status_legend.scale_kind = ColorScale::kCategorical;
  status_legend.label = "status";
  status_legend.category_names = TauPixelStatusNames();
  status_legend.pixel_pitch_m = data.pixel_pitch_m;
  THINSLAB_RETURN_IF_ERROR(
      WriteFalseColorPng(JoinPath(out.path(), "status_falsecolor.png"), status, 0, nullptr, status_legend));
  FalseColorOptions color;
  color.pixel_pitch_m = data.pixel_pitch_m;
  color.label = "tau";
  color.max_value = 1.5;
  const Image tau_only = tau.Channel(0);
  for (float v : tau_only.data()) color.max_value = std::max(color.max_value, static_cast<double>(v));
  color.max_value = std::min(color.max_value, fit.tau_max);
  THINSLAB_RETURN_IF_ERROR(WriteFalseColorPng(JoinPath(out.path(), "tau_falsecolor.png"), tau, 0, &status, color));
  color.label = "tau Eq.7";
  THINSLAB_RETURN_IF_ERROR(WriteFalseColorPng(JoinPath(out.path(), "tau_plain_falsecolor.png"), tau, 1, &status, color));
  THINSLAB_RETURN_IF_ERROR(
      WriteFileAtomically(JoinPath(out.path(), "summary.json"),
                          SummaryJson(*summary, data, capture, fit, run.phase_dir.empty() ? nullptr : &phase,
                                      color.max_value, validation, consistency, memory, provenance)));
  THINSLAB_RETURN_IF_ERROR(
      WriteFileAtomically(JoinPath(out.path(), "summary.txt"), summary->FullReport() + validation_text));
  if (!validation_text.empty()) std::cout << validation_text;
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "options.ini"), run.options_ini));

  const std::string truth_path = JoinPath(JoinPath(session_dir, "ground_truth"), "tau.exr");
  // The comparison with a simulated capture's ground truth is optional: when it cannot be made
  // (a truth of another grid, an unreadable file), the fit is still written, with a warning.
  auto compare_with_truth = [&]() -> Status {
    Image truth;
    THINSLAB_RETURN_IF_ERROR(ReadExr(truth_path, &truth));
    THINSLAB_RETURN_IF_ERROR(CompareTauWithTruth(tau, truth, 0.05, 1.5, comparison).WithContext(truth_path));
    *has_truth = true;
    THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "comparison.json"), comparison->ToJson()));
    color.label = "tau true";
    THINSLAB_RETURN_IF_ERROR(WriteFalseColorPng(JoinPath(out.path(), "truth_falsecolor.png"), truth, 0, nullptr, color));
    Image error(tau.width(), tau.height(), {"error"});
    const int tc = truth.ChannelIndex("tau") >= 0 ? truth.ChannelIndex("tau") : 0;
    for (int y = 0; y < tau.height(); ++y) {
      for (int x = 0; x < tau.width(); ++x) error.at(x, y) = tau.at(x, y, 0) - truth.at(x, y, tc);
    }
    FalseColorOptions err_color;  // Signed: a diverging scale, white at 0.
    err_color.scale_kind = ColorScale::kDiverging;
    err_color.label = "tau err";
    err_color.max_value = 0.1;
    err_color.pixel_pitch_m = data.pixel_pitch_m;
    THINSLAB_RETURN_IF_ERROR(WriteFalseColorPng(JoinPath(out.path(), "error_falsecolor.png"), error, 0, &status, err_color));
    return Status::Ok();
  };
  if (FileExists(truth_path)) {
    const Status compared = compare_with_truth();
    if (!compared.ok()) {
      *has_truth = false;
      for (const char* name : {"comparison.json", "truth_falsecolor.png", "error_falsecolor.png"}) {
        std::remove(JoinPath(out.path(), name).c_str());
      }
      std::cerr << "warning: the fit is written without the ground-truth comparison: " << compared.message() << "\n";
    }
  }
  THINSLAB_RETURN_IF_ERROR(WriteFolderReport(out.path(), out_dir, "thinslab fit tau: " + session_dir));
  return out.Commit();
}

}  // namespace thinslab
