// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/stability_cases.h"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <sstream>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/session_io.h"

namespace thinslab {

SyntheticShadowSessionOptions SmallShadowMapRig(uint64_t seed) {
  SyntheticShadowSessionOptions sim;
  sim.rig.camera_width_px = 320;
  sim.rig.camera_height_px = 240;
  sim.rig.monte_carlo.num_photons = 50000;
  sim.rig.seed = seed;
  return sim;
}

Image UniformTau(int width, int height, double tau) {
  return Image(width, height, static_cast<float>(tau));
}

Image PatchTau(int width, int height, const double patch_taus[4], double background_tau) {
  Image tau(width, height, static_cast<float>(background_tau));
  // Patches of half the quadrant, centred in it: wide enough that a few pixels of pose error
  // or of scattered light leave their centres untouched.
  const int qw = width / 2, qh = height / 2;
  for (int k = 0; k < 4; ++k) {
    const int x0 = (k % 2) * qw + qw / 4, y0 = (k / 2) * qh + qh / 4;
    for (int y = y0; y < y0 + qh / 2; ++y) {
      for (int x = x0; x < x0 + qw / 2; ++x) tau.at(x, y) = static_cast<float>(patch_taus[k]);
    }
  }
  return tau;
}

Status PerturbCameraPose(const std::string& session_dir, double shift_px, Eigen::Vector3d* board_shift_m) {
  Session session;
  THINSLAB_RETURN_IF_ERROR(ReadSession(session_dir, &session));
  if (session.rig.cameras.empty()) return Status::Error(session_dir + ": rig.cameras: no camera to perturb");
  CameraInfo& camera = session.rig.cameras[0];
  // Depth of the board centre in the camera frame: a translation dx of the camera frame moves
  // its image by fx * dx / depth pixels (pinhole).
  const Eigen::Vector3d board_centre_in_cam = camera.cam_from_sample * Eigen::Vector3d(0, 0, -session.rig.board.distance_m);
  if (!(board_centre_in_cam.z() > 0) || !(camera.fx_px > 0)) {
    return Status::Error(session_dir + ": rig.cameras[0]: the board centre is not in front of the camera");
  }
  const double dx_m = shift_px * board_centre_in_cam.z() / camera.fx_px;
  camera.cam_from_sample.translation.x() += dx_m;
  // The rectifier now reads board point X where the camera saw X + R^T (dx, 0, 0).
  if (board_shift_m != nullptr) *board_shift_m = camera.cam_from_sample.rotation.conjugate() * Eigen::Vector3d(dx_m, 0, 0);
  return WriteSession(session_dir, session);
}

Status RunTauStabilityCase(const TauStabilityCase& test_case, const std::string& work_dir, TauStabilityResult* result) {
  *result = TauStabilityResult();
  const std::string session_dir = JoinPath(work_dir, "session");
  const std::string fit_dir = JoinPath(work_dir, "fit");
  THINSLAB_RETURN_IF_ERROR(SynthesizeShadowMapSession(test_case.sim, test_case.tau_true, session_dir));
  Eigen::Vector3d board_shift_m = Eigen::Vector3d::Zero();
  if (test_case.pose_error_px != 0) {
    THINSLAB_RETURN_IF_ERROR(PerturbCameraPose(session_dir, test_case.pose_error_px, &board_shift_m));
  }
  // The fit is given the true layer albedo and g (as from a laser-lobe fit, Gu Eq. 8): the
  // axes here are the capture's, not the layer model's.
  FitTauRun run = test_case.run;
  run.fit.layer_albedo = test_case.sim.rig.layer_albedo;
  run.fit.layer_g = test_case.sim.rig.layer_g;
  TauComparison comparison;
  bool has_truth = false;
  result->pipeline = FitTauPipeline(session_dir, fit_dir, run, &result->summary, &comparison, &has_truth);
  if (!result->pipeline.ok()) return Status::Ok();

  Image maps;
  THINSLAB_RETURN_IF_ERROR(ReadExr(JoinPath(fit_dir, "tau.exr"), &maps));
  {
    std::string text;
    THINSLAB_RETURN_IF_ERROR(ReadFileToString(JoinPath(fit_dir, "summary.json"), &text));
    const nlohmann::json summary = nlohmann::json::parse(text, nullptr, false);
    if (summary.is_object() && summary.contains("consistency") && summary["consistency"].contains("rms_z")) {
      result->consistency_rms_z = summary["consistency"]["rms_z"].get<double>();
    }
  }
  const int tau_c = maps.ChannelIndex("tau"), plain_c = maps.ChannelIndex("tau_eq7"),
            status_c = maps.ChannelIndex("status"), sigma_c = maps.ChannelIndex("sigma_tau");
  if (tau_c < 0 || plain_c < 0 || status_c < 0 || sigma_c < 0) {
    return Status::Error(fit_dir + "/tau.exr: expected channels tau, tau_eq7, status, sigma_tau");
  }
  const Image& truth = test_case.tau_true;
  if (maps.width() != truth.width() || maps.height() != truth.height()) {
    return Status::Error(fit_dir + "/tau.exr: grid differs from the ground truth texture");
  }
  for (float v : maps.data()) result->non_finite_values += !std::isfinite(v);
  const double tau_max = run.fit.tau_max;
  const double pitch = test_case.sim.rig.pixel_pitch_m;
  const Eigen::Vector2d shift_texels(board_shift_m.x() / pitch, board_shift_m.y() / pitch);
  result->pose_error_board_texels = shift_texels.norm();
  double sum_sq = 0, sum = 0, sum_sq_plain = 0, sum_sq_true = 0, sum_sq_sigma = 0, sum_sq_realigned = 0;
  int64_t realigned = 0;
  for (int y = 0; y < maps.height(); ++y) {
    for (int x = 0; x < maps.width(); ++x) {
      ++result->pixels;
      const float code = maps.at(x, y, status_c);
      const double t_true = truth.at(x, y);
      if (!(code == std::round(code)) || code < 0 || code > static_cast<float>(TauPixelStatus::kMixed)) {
        ++result->invalid_status;
        continue;
      }
      switch (static_cast<TauPixelStatus>(static_cast<int>(code))) {
        case TauPixelStatus::kOk: break;
        case TauPixelStatus::kDark: ++result->dark; continue;
        case TauPixelStatus::kSaturated: ++result->saturated; continue;
        case TauPixelStatus::kOutside: ++result->outside; continue;
        case TauPixelStatus::kClamped:
          ++result->clamped;
          result->clamped_below_tau_max += t_true < tau_max - 0.5;
          continue;
        case TauPixelStatus::kNextToClamped: ++result->next_to_clamped; continue;
        case TauPixelStatus::kMixed: ++result->mixed; continue;
      }
      ++result->ok;
      result->ok_beyond_tau_max += t_true > tau_max;
      const double error = maps.at(x, y, tau_c) - t_true;
      if (!std::isfinite(error)) continue;  // Counted in non_finite_values.
      result->within_1_sigma += std::abs(error) <= maps.at(x, y, sigma_c);
      result->within_2_sigma += std::abs(error) <= 2 * maps.at(x, y, sigma_c);
      sum += error;
      sum_sq += Sqr(error);
      sum_sq_plain += Sqr(maps.at(x, y, plain_c) - t_true);
      sum_sq_true += Sqr(t_true);
      sum_sq_sigma += Sqr(maps.at(x, y, sigma_c));
      const double xs = x + 0.5 + shift_texels.x(), ys = y + 0.5 + shift_texels.y();
      if (xs >= 2 && ys >= 2 && xs <= maps.width() - 2 && ys <= maps.height() - 2) {
        sum_sq_realigned += Sqr(maps.at(x, y, tau_c) - truth.Bilinear(xs, ys));
        ++realigned;
      }
      result->max_abs_error = std::max(result->max_abs_error, std::abs(error));
    }
  }
  if (result->ok > 0) {
    const double n = static_cast<double>(result->ok);
    result->rms_abs_error = std::sqrt(sum_sq / n);
    result->mean_error = sum / n;
    result->rms_abs_error_plain = std::sqrt(sum_sq_plain / n);
    result->rms_true = std::sqrt(sum_sq_true / n);
    result->rms_sigma_tau = std::sqrt(sum_sq_sigma / n);
  }
  if (realigned > 0) result->rms_abs_error_realigned = std::sqrt(sum_sq_realigned / realigned);
  return Status::Ok();
}

SyntheticLaserSessionOptions SmallLaserLobeRig(double tau, double g, uint64_t seed) {
  SyntheticLaserSessionOptions sim;
  sim.rig.layer_tau = tau;
  sim.rig.layer_g = g;
  sim.rig.seed = seed;
  sim.rig.camera_width_px = 480;
  sim.rig.camera_height_px = 360;
  sim.rig.pixel_pitch_m = 0.3e-3;
  sim.rig.monte_carlo.num_photons = 50000;
  sim.session.capture_clean = false;
  return sim;
}

namespace {

// Counts "nan" / "inf" tokens (any case) in a text file.
int64_t CountNonFiniteTokens(const std::string& text) {
  std::string lower(text);
  std::transform(lower.begin(), lower.end(), lower.begin(), [](unsigned char c) { return std::tolower(c); });
  int64_t count = 0;
  for (const char* token : {"nan", "inf"}) {
    for (size_t at = lower.find(token); at != std::string::npos; at = lower.find(token, at + 1)) ++count;
  }
  return count;
}

}  // namespace

Status RunPhaseStabilityCase(const PhaseStabilityCase& test_case, const std::string& work_dir,
                             PhaseStabilityResult* result) {
  *result = PhaseStabilityResult();
  const std::string session_dir = JoinPath(work_dir, "session");
  const std::string fit_dir = JoinPath(work_dir, "fit");
  THINSLAB_RETURN_IF_ERROR(SynthesizeLaserLobeSession(test_case.sim, session_dir));
  PhaseFitOptions options = test_case.fit;
  if (options.tau <= 0) options.tau = test_case.sim.rig.layer_tau > 0 ? test_case.sim.rig.layer_tau : 0.3;
  options.layer_albedo = test_case.sim.rig.layer_albedo;  // Given, as the tau cases' fits are.
  std::vector<LaserRing> rings;
  LaserLobePreparationOptions preparation;
  preparation.supersample = test_case.supersample;
  result->pipeline = FitPhasePipeline(session_dir, fit_dir, options, preparation, false, "# stability case\n",
                                      &result->summary, &rings);
  const PhaseFitSummary& s = result->summary;
  for (double v : {s.g, s.sigma_g, s.beta, s.chi2_reduced, s.rms_normalized_residual, s.detection_significance}) {
    result->summary_finite = result->summary_finite && std::isfinite(v);
  }
  if (!result->pipeline.ok()) return Status::Ok();
  std::string csv, json_text;
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(JoinPath(fit_dir, "rings.csv"), &csv));
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(JoinPath(fit_dir, "summary.json"), &json_text));
  result->non_finite_in_files = CountNonFiniteTokens(csv);
  // nlohmann::json writes a non-finite double as null.
  const nlohmann::json j = nlohmann::json::parse(json_text, nullptr, /*allow_exceptions=*/false);
  if (j.is_discarded()) return Status::Error(fit_dir + "/summary.json: not valid JSON");
  for (const char* key : {"g", "sigma_g", "beta", "chi2_reduced", "rms_normalized_residual", "detection_significance"}) {
    if (!j.contains(key) || !j[key].is_number()) ++result->non_finite_in_files;
  }
  return Status::Ok();
}

}  // namespace thinslab
