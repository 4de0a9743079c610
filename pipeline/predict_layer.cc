// SPDX-License-Identifier: Apache-2.0
// `thinslab predict` for shadow-map and laser-lobe captures (issue #23 section 4): the shadow a
// `fit tau` map predicts at the capture's board distance, and the lobe a `fit phase` result
// predicts, against the capture's frames (its validation frames when it has them). The capture
// may be another one of the same sample (another board distance, another camera pose): the map
// lives on the sample grid and Eq. 8 on angles, so both carry over.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "thinslab/pipeline/layer_from_phase.h"
#include "thinslab/pipeline/folder_report.h"
#include "thinslab/pipeline/prediction_report.h"
#include "thinslab/calib/board_rectification.h"
#include "thinslab/calib/laser_lobe_preparation.h"
#include "thinslab/calib/shadow_map_preparation.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/version.h"
#include "thinslab/optics/dirty_glass.h"

namespace thinslab {
namespace {

Status NumberField(const nlohmann::json& j, const std::string& path, const std::string& field, double* value) {
  if (!j.contains(field) || !j[field].is_number()) return Status::Error(path + ": " + field + ": missing or not a number");
  *value = j[field].get<double>();
  if (!std::isfinite(*value)) return Status::Error(path + ": " + field + ": not finite");
  return Status::Ok();
}

// The fit's grid from tau.exr's header attributes (docs/format.md 9.2).
Status TauGrid(const Image& tau, const std::string& path, Eigen::Vector2d* region_min_m, double* pitch_m) {
  const std::vector<double>* min = tau.NumericAttribute("region_min_m", 2);
  const std::vector<double>* pitch = tau.NumericAttribute("pixel_pitch_m", 1);
  if (min == nullptr || pitch == nullptr) {
    return Status::Error(path + ": numeric attributes region_min_m [x, y] and pixel_pitch_m missing");
  }
  *region_min_m = Eigen::Vector2d((*min)[0], (*min)[1]);
  *pitch_m = (*pitch)[0];
  if (!region_min_m->allFinite() || !(*pitch_m > 0)) {
    return Status::Error(path + ": region_min_m must be finite and pixel_pitch_m > 0");
  }
  return Status::Ok();
}

// The provenance names the capture, the fit and the command's options.
Provenance PredictProvenance(const PredictRun& run) {
  return {"predict", run.session_dir, run.fit_dir, run.options_ini};
}

// The fields every predict summary.json starts with.
nlohmann::json PredictSummaryHead(const PredictRun& run, const std::string& kind, bool validation, int frames) {
  return {{"format", "thinslab-predict-summary"},
          {"provenance", ProvenanceJson(PredictProvenance(run))},
          {"kind", kind},
          {"session", run.session_dir},
          {"fit", run.fit_dir},
          {"measured_frames", validation ? "validation" : "fitted"},
          {"frames", frames}};
}

// The board-grid prediction `board` (CompareShadowWithMaps's image) imaged in the capture's
// camera: each camera pixel takes the mean transmission ratio of the map pixels its footprint
// covers on the board (kCameraSubsamples^2 sub-pixel rays, as the pixel integrates the board)
// times its own clean signal, against its own averaged frames (nothing resampled).
constexpr int kCameraSubsamples = 4;
std::vector<ShadowPredictionRegion> ImageShadowInCamera(const Image& tau_map, const RectifiedShadowMaps& data,
                                                        const Image& board, Image* camera_image) {
  BoardGrid grid;
  grid.grid_min_m = data.region_min_m;
  grid.pixel_pitch_m = data.pixel_pitch_m;
  grid.width_px = tau_map.width();
  grid.height_px = tau_map.height();
  grid.plane_z_m = -data.board_distance_m;
  const int n2 = kCameraSubsamples * kCameraSubsamples;
  const std::vector<int> cells = MapPixelOfCameraPixels(data.camera, grid, kCameraSubsamples);
  const int w = data.camera.width_px, h = data.camera.height_px;
  const int tau_c = tau_map.ChannelIndex("tau"), plain_c = tau_map.ChannelIndex("tau_eq7"),
            sigma_c = tau_map.ChannelIndex("sigma_tau");
  Image predicted(w, h), plain(w, h), measured = data.camera_shadow, variance(w, h), tau(w, h), sigma_tau(w, h);
  std::vector<uint8_t> valid(static_cast<size_t>(w) * h, 0);
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const size_t k = static_cast<size_t>(v) * w + u;
      const double clean = data.camera_reference.data()[k];
      if (!(clean > 0) || data.camera_shadow_saturated.data()[k] > 0) continue;
      double ratio_sum = 0, plain_sum = 0, tau_sum = 0, sigma_sum = 0;
      bool all_valid = true;
      for (int s = 0; s < n2 && all_valid; ++s) {
        const int cell = cells[k * n2 + s];
        const int cx = cell % grid.width_px, cy = cell / grid.width_px;
        all_valid = cell >= 0 && board.at(cx, cy, 4) > 0 && data.reference.data()[cell] > 0;
        if (!all_valid) break;
        ratio_sum += board.at(cx, cy, 0) / data.reference.data()[cell];
        plain_sum += std::exp(-tau_map.at(cx, cy, plain_c));
        tau_sum += tau_map.at(cx, cy, tau_c);
        sigma_sum += tau_map.at(cx, cy, sigma_c);
      }
      if (!all_valid) continue;
      valid[k] = 1;
      predicted.data()[k] = static_cast<float>(ratio_sum / n2 * clean);
      plain.data()[k] = static_cast<float>(plain_sum / n2 * clean);
      const double ratio = measured.data()[k] / clean;
      variance.data()[k] = static_cast<float>(data.camera_shadow_variance.data()[k] +
                                              ratio * ratio * data.camera_reference_variance.data()[k]);
      tau.data()[k] = static_cast<float>(tau_sum / n2);
      sigma_tau.data()[k] = static_cast<float>(sigma_sum / n2);
    }
  }
  *camera_image =
      Image(w, h, {"predicted", "predicted_plain", "measured", "variance", "valid", "clean", "tau", "sigma_tau"});
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const size_t k = static_cast<size_t>(v) * w + u;
      camera_image->at(u, v, 0) = predicted.data()[k];
      camera_image->at(u, v, 1) = plain.data()[k];
      camera_image->at(u, v, 2) = measured.data()[k];
      camera_image->at(u, v, 3) = variance.data()[k];
      camera_image->at(u, v, 4) = valid[k];
      camera_image->at(u, v, 5) = valid[k] ? data.camera_reference.data()[k] : 0.0f;
      camera_image->at(u, v, 6) = tau.data()[k];
      camera_image->at(u, v, 7) = sigma_tau.data()[k];
    }
  }
  return CompareShadowPrediction(predicted, plain, measured, variance, tau, sigma_tau, valid);
}

}  // namespace

LobeCameraError ImageLobeInCamera(const LaserLobeImages& images, const LaserRingGeometry& ring,
                                  const std::function<double(double r_m)>& profile, Image* camera_image) {
  BoardGrid grid;
  grid.grid_min_m = images.grid_min_m;
  grid.pixel_pitch_m = images.pixel_pitch_m;
  grid.width_px = images.outside.width();
  grid.height_px = images.outside.height();
  grid.plane_z_m = -images.board_distance_m;
  const std::vector<int> cells = MapPixelOfCameraPixels(images.camera, grid);
  const int w = images.camera.width_px, h = images.camera.height_px;
  *camera_image = Image(w, h, {"predicted", "measured", "variance", "valid"});
  LobeCameraError error;
  double sum_err2 = 0, sum_meas2 = 0, sum_var = 0;
  for (int v = 0; v < h; ++v) {
    for (int u = 0; u < w; ++u) {
      const size_t k = static_cast<size_t>(v) * w + u;
      Eigen::Vector2d q;  // The board point the pixel's centre sees (the board region only).
      if (cells[k] < 0 || !CameraRayOnPlane(images.camera, Eigen::Vector2d(u + 0.5, v + 0.5), grid.plane_z_m, &q)) continue;
      if (images.lobe.camera_all_saturated.data()[k] > 0) continue;
      if (ring.clean_subtracted && images.clean.camera_all_saturated.data()[k] > 0) continue;
      const double r = (q - ring.beam_centre_m).norm();
      if (r < ring.r_core_m || r >= ring.r_max_m) continue;
      const double flat = ring.flat_fielded ? images.flat.camera_radiance.data()[k] / ring.flat_at_centre : 1.0;
      if (!(flat > 0)) continue;
      double predicted = profile(r) * flat;
      double variance = images.lobe.camera_variance.data()[k];
      if (ring.clean_subtracted) {
        predicted += images.clean.camera_radiance.data()[k];
        variance += images.clean.camera_variance.data()[k];
      }
      const double measured = images.lobe.camera_radiance.data()[k];
      camera_image->at(u, v, 0) = static_cast<float>(predicted);
      camera_image->at(u, v, 1) = static_cast<float>(measured);
      camera_image->at(u, v, 2) = static_cast<float>(variance);
      camera_image->at(u, v, 3) = 1;
      ++error.pixels;
      sum_err2 += Sqr(predicted - measured);
      sum_meas2 += Sqr(measured);
      sum_var += variance;
    }
  }
  if (sum_meas2 > 0) {
    error.relative_rms = std::sqrt(sum_err2 / sum_meas2);
    error.noise_relative_rms = std::sqrt(sum_var / sum_meas2);
  }
  return error;
}

Status PredictShadow(const std::string& session_dir, const Session& session, const std::string& fit_dir,
                     const SessionCalibrationOptions& calibration, ShadowPrediction* prediction) {
  const std::string tau_path = JoinPath(fit_dir, "tau.exr"), summary_path = JoinPath(fit_dir, "summary.json");
  Image& tau_map = prediction->tau_map;
  THINSLAB_RETURN_IF_ERROR(ReadExr(tau_path, &tau_map));
  for (const char* channel : {"tau", "tau_eq7", "status", "sigma_tau"}) {
    if (tau_map.ChannelIndex(channel) < 0) return Status::Error(tau_path + ": channel '" + channel + "' missing");
  }
  nlohmann::json fit_summary;
  THINSLAB_RETURN_IF_ERROR(ReadJsonObjectFile(summary_path, "a `thinslab fit tau` output", &fit_summary));
  if (!fit_summary.contains("layer") || !fit_summary["layer"].is_object()) {
    return Status::Error(summary_path + ": layer: missing (a `thinslab fit tau` summary holds the layer it was fitted with)");
  }
  TauFitOptions& layer = prediction->layer;
  const nlohmann::json& layer_json = fit_summary["layer"];
  THINSLAB_RETURN_IF_ERROR(NumberField(layer_json, summary_path + ": layer", "albedo", &layer.layer_albedo));
  THINSLAB_RETURN_IF_ERROR(NumberField(layer_json, summary_path + ": layer", "g", &layer.layer_g));
  if (!layer_json.contains("refine_scattering") || !layer_json["refine_scattering"].is_boolean()) {
    return Status::Error(summary_path + ": layer: refine_scattering: missing or not a boolean");
  }
  layer.refine_scattering = layer_json["refine_scattering"].get<bool>();
  if (fit_summary.contains("model_options")) {  // Fits written before 2026-12-05 use the defaults.
    THINSLAB_RETURN_IF_ERROR(NumberField(fit_summary["model_options"], summary_path + ": model_options", "tau_max", &layer.tau_max));
    THINSLAB_RETURN_IF_ERROR(NumberField(fit_summary["model_options"], summary_path + ": model_options",
                                         "kernel_max_angle_deg", &layer.kernel_max_angle_deg));
  }
  std::string error;
  if (!layer.Check(&error)) return Status::Error(summary_path + ": " + error);

  ShadowMapPreparationOptions preparation;
  preparation.calibration = calibration;
  preparation.keep_camera_frames = true;
  RectifiedShadowMaps& data = prediction->data;
  THINSLAB_RETURN_IF_ERROR(PrepareShadowMaps(session_dir, session, preparation, &data));
  Eigen::Vector2d fit_min;
  double fit_pitch = 0;
  THINSLAB_RETURN_IF_ERROR(TauGrid(tau_map, tau_path, &fit_min, &fit_pitch));
  const std::string manifest = JoinPath(session_dir, kSessionManifestName);
  if (tau_map.width() != data.shadow.width() || tau_map.height() != data.shadow.height() ||
      (fit_min - data.region_min_m).norm() > 1e-9 || std::abs(fit_pitch - data.pixel_pitch_m) > 1e-12) {
    return Status::Error(manifest + ": rig.sample: the capture's grid (region_min_m, region_max_m, pixel_pitch_m) differs "
                         "from the map's in " + tau_path + "; predict needs the sample grid the map was fitted on");
  }
  if (data.reference.empty()) {
    return Status::Error(manifest + ": frames: no usable 'reference' frames; predicting a shadow needs the clean board "
                         "signal I_clean at the capture's board distance");
  }
  const bool validation = prediction->validation = data.num_validation_frames > 0;
  // The prediction inherits the reference's noise (pred = m I_clean; m ~ measured / I_clean).
  Image prediction_variance(data.reference.width(), data.reference.height());
  const Image& measured = validation ? data.validation_shadow : data.shadow;
  for (size_t i = 0; i < prediction_variance.data().size(); ++i) {
    const double r = data.reference.data()[i];
    if (r > 0) prediction_variance.data()[i] = static_cast<float>(std::pow(measured.data()[i] / r, 2) * data.reference_variance.data()[i]);
  }
  Image& shadow = prediction->board;
  prediction->regions =
      CompareShadowWithMaps(layer, tau_map, data, data.reference, prediction_variance, !validation, &shadow);
  shadow.attributes()["units"] = "DN/us on the board grid of docs/format.md 9.1, black level and darks removed";
  Image& camera_shadow = prediction->camera;
  prediction->camera_regions = ImageShadowInCamera(tau_map, data, shadow, &camera_shadow);
  camera_shadow.attributes() = shadow.attributes();
  camera_shadow.attributes()["units"] = "DN/us in the capture's camera pixels, black level and darks removed";
  return Status::Ok();
}

Status PredictShadowFromTau(const PredictRun& run, const Session& session, StagedDirectory* out) {
  ShadowPrediction prediction;
  THINSLAB_RETURN_IF_ERROR(PredictShadow(run.session_dir, session, run.fit_dir, run.calibration, &prediction));
  const RectifiedShadowMaps& data = prediction.data;
  const TauFitOptions& layer = prediction.layer;
  const bool validation = prediction.validation;
  const std::vector<ShadowPredictionRegion>& regions = prediction.regions;
  const std::vector<ShadowPredictionRegion>& camera_regions = prediction.camera_regions;
  const std::string tau_path = JoinPath(run.fit_dir, "tau.exr");
  THINSLAB_RETURN_IF_ERROR(WriteMapExr(JoinPath(out->path(), "shadow.exr"), prediction.board, {"predicted", {"valid"}},
                                       PredictProvenance(run)));
  THINSLAB_RETURN_IF_ERROR(WriteMapExr(JoinPath(out->path(), "shadow_camera.exr"), prediction.camera,
                                       {"predicted", {"valid"}}, PredictProvenance(run)));

  nlohmann::json j =
      PredictSummaryHead(run, "shadow", validation, validation ? data.num_validation_frames : data.num_shadow_frames);
  j["board_distance_m"] = data.board_distance_m;
  j["layer"] = {{"albedo", layer.layer_albedo}, {"g", layer.layer_g}, {"refine_scattering", layer.refine_scattering}};
  j["regions"] = ShadowRegionsJson(regions);
  j["camera_regions"] = ShadowRegionsJson(camera_regions);
  std::ostringstream txt;
  txt << "thinslab predict: the shadow " << tau_path << " predicts at board distance " << data.board_distance_m * 1e3
      << " mm, against the capture's " << (validation ? "validation" : "fitted") << " shadow frames"
      << (validation ? "" : " (if the map was fitted on these frames, it reproduces them by construction)") << ":\n"
      << ShadowRegionsText(regions) << "in the camera's pixels (each the mean over its footprint on the board; this adds what the map's pitch "
         "cannot resolve, also at the fitted geometry):\n"
      << ShadowRegionsText(camera_regions);
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out->path(), "summary.json"), j.dump(2) + "\n"));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out->path(), "summary.txt"), txt.str()));
  THINSLAB_RETURN_IF_ERROR(WriteFolderReport(out->path(), run.out_dir, "thinslab predict: " + run.session_dir));
  THINSLAB_RETURN_IF_ERROR(out->Commit());
  std::cout << txt.str() << "wrote " << run.out_dir << "\n";
  return Status::Ok();
}

Status PredictLobe(const std::string& session_dir, const Session& session, const std::string& fit_dir,
                   const SessionCalibrationOptions& calibration, LobeFitPrediction* out) {
  *out = LobeFitPrediction();
  const std::string summary_path = JoinPath(fit_dir, "summary.json");
  nlohmann::json fit_summary;
  THINSLAB_RETURN_IF_ERROR(ReadJsonObjectFile(summary_path, "a `thinslab fit phase` output", &fit_summary));
  if (!fit_summary.contains("result") || fit_summary["result"] != "success") {
    return Status::Error(summary_path + ": result is not \"success\": the lobe fit gave no Eq. 8 parameters to predict with");
  }
  THINSLAB_RETURN_IF_ERROR(NumberField(fit_summary, summary_path, "beta", &out->beta));
  THINSLAB_RETURN_IF_ERROR(NumberField(fit_summary, summary_path, "g", &out->g));
  THINSLAB_RETURN_IF_ERROR(NumberField(fit_summary, summary_path, "tau", &out->tau));
  THINSLAB_RETURN_IF_ERROR(NumberField(fit_summary, summary_path, "board_distance_m", &out->fit_board_distance_m));
  THINSLAB_RETURN_IF_ERROR(NumberField(fit_summary, summary_path, "max_theta_deg", &out->max_theta_deg));
  if (fit_summary.contains("sigma_g"))
    THINSLAB_RETURN_IF_ERROR(NumberField(fit_summary, summary_path, "sigma_g", &out->sigma_g));
  if (fit_summary.contains("layer_albedo")) {
    THINSLAB_RETURN_IF_ERROR(NumberField(fit_summary, summary_path, "layer_albedo", &out->layer_albedo));
  }
  LaserLobePreparationOptions preparation;
  preparation.calibration = calibration;
  preparation.keep_camera_hdr = true;
  LaserLobeImages& images = out->images;
  THINSLAB_RETURN_IF_ERROR(PrepareLaserLobe(session_dir, session, preparation, &images));
  out->validation = !images.validation_lobe.empty();
  if (out->validation) images.lobe = images.validation_lobe;
  PhaseFitOptions options;
  options.max_theta_auto = false;
  options.max_theta_deg = out->max_theta_deg;
  options.tau = out->tau;
  return PredictLaserLobe(options, out->beta, out->g, out->tau, out->fit_board_distance_m, images, &out->prediction)
      .WithContext(session_dir);
}

Status PredictLobeFromPhase(const PredictRun& run, const Session& session, StagedDirectory* out) {
  LobeFitPrediction fit;
  THINSLAB_RETURN_IF_ERROR(PredictLobe(run.session_dir, session, run.fit_dir, run.calibration, &fit));
  const LaserLobeImages& images = fit.images;
  const LobePrediction& prediction = fit.prediction;
  const bool validation = fit.validation;
  const double g = fit.g, tau = fit.tau, beta = fit.beta, fit_distance = fit.fit_board_distance_m,
               max_theta_deg = fit.max_theta_deg;
  std::ostringstream csv;
  csv << "r_m,theta_deg,measured_dn_per_us,sigma,predicted_dn_per_us,pixels\n";
  csv.precision(9);
  for (const LaserRing& ring : prediction.rings) {
    csv << ring.r_m << "," << ring.theta_rad * 180 / kPi << "," << ring.intensity << "," << ring.sigma << ","
        << ring.model << "," << ring.pixels << "\n";
  }
  nlohmann::json j = PredictSummaryHead(run, "lobe", validation, images.lobe.num_frames);
  j["fit_board_distance_m"] = fit_distance;
  j["model"] = {{"beta", beta}, {"g", g}, {"tau", tau}, {"max_theta_deg", max_theta_deg}};
  j["lobe"] = LobeBandsJson(prediction);
  Image camera_image;
  const LobeCameraError camera = ImageLobeInCamera(
      images, prediction.geometry,
      [&](double r_m) {
        return prediction.scale * LaserLobeProfile(std::cos(std::atan(r_m / images.board_distance_m)), g, tau);
      },
      &camera_image);
  j["lobe_camera"] = {{"pixels", camera.pixels},
                      {"relative_rms", camera.relative_rms},
                      {"noise_relative_rms", camera.noise_relative_rms}};
  camera_image.attributes()["units"] = "DN/us in the capture's camera pixels (the HDR merge's radiance)";
  THINSLAB_RETURN_IF_ERROR(WriteMapExr(JoinPath(out->path(), "lobe_camera.exr"), camera_image, {"predicted", {"valid"}},
                                       PredictProvenance(run)));
  std::ostringstream txt;
  txt << "thinslab predict: the lobe Eq. 8 predicts with g " << g << " (fitted at board distance " << fit_distance * 1e3
      << " mm) at " << images.board_distance_m * 1e3 << " mm, against the capture's "
      << (validation ? "validation" : "fitted") << " laser frames:\n"
      << LobeBandsText(prediction);
  char camera_line[200];
  std::snprintf(camera_line, sizeof(camera_line),
                "in the camera's pixels (core to outermost angle): relative RMS %.4f (noise alone %.4f) over %lld px\n",
                camera.relative_rms, camera.noise_relative_rms, static_cast<long long>(camera.pixels));
  txt << camera_line;
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out->path(), "lobe_rings.csv"), csv.str()));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out->path(), "summary.json"), j.dump(2) + "\n"));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out->path(), "summary.txt"), txt.str()));
  THINSLAB_RETURN_IF_ERROR(WriteFolderReport(out->path(), run.out_dir, "thinslab predict: " + run.session_dir));
  THINSLAB_RETURN_IF_ERROR(out->Commit());
  std::cout << txt.str() << "wrote " << run.out_dir << "\n";
  return Status::Ok();
}

}  // namespace thinslab
