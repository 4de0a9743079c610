// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/dmf_prediction.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "thinslab/core/camera_model.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/fit/dmf_ndf_grid.h"
#include "thinslab/fit/dmf_point_fit.h"

namespace thinslab {

namespace {

// What a fit written before a field existed is told.
constexpr char kFitAgain[] = "fitted before `thinslab predict` existed? fit again";

// A numeric header attribute of `count` values (core/exr_io.h reads format 1.0's JSON text too).
Status NumericAttribute(const Image& image, const std::string& file, const std::string& key, size_t count,
                        std::vector<double>* values) {
  return RequireNumericAttribute(image, file, key, count, values, kFitAgain);
}

Status Number(const nlohmann::json& j, const std::string& file, const std::string& field, double* out) {
  if (!j.is_number() || !std::isfinite(j.get<double>())) {
    return Status::Error(file + ": " + field + " is missing or not a finite number (" + kFitAgain + ")");
  }
  *out = j.get<double>();
  return Status::Ok();
}

}  // namespace

Status ReadDmfFit(const std::string& fit_dir, DmfFitOnDisk* fit) {
  const std::string summary_file = JoinPath(fit_dir, "summary.json"), maps_file = JoinPath(fit_dir, "maps.exr"),
                    atlas_file = JoinPath(fit_dir, "ndf_atlas.exr");
  std::string text;
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(summary_file, &text));
  const nlohmann::json summary = nlohmann::json::parse(text, nullptr, false);
  if (summary.is_discarded() || summary.value("model", "") != "dai2009_dual_microfacet") {
    return Status::Error(summary_file + ": not the summary of `thinslab fit dmf` (model dai2009_dual_microfacet)");
  }
  const nlohmann::json monitor = summary.value("monitor", nlohmann::json::object());
  const nlohmann::json pose = monitor.value("sample_from_monitor", nlohmann::json::object());
  const nlohmann::json rotation = pose.value("rotation_wxyz", nlohmann::json()),
                       translation = pose.value("translation_m", nlohmann::json());
  if (!rotation.is_array() || rotation.size() != 4 || !translation.is_array() || translation.size() != 3) {
    return Status::Error(summary_file + ": monitor.sample_from_monitor is missing (fitted before `thinslab predict` "
                                        "existed? fit again)");
  }
  double w, x, y, z, tx, ty, tz, radius, median_radiance;
  THINSLAB_RETURN_IF_ERROR(Number(rotation[0], summary_file, "monitor.sample_from_monitor.rotation_wxyz", &w));
  THINSLAB_RETURN_IF_ERROR(Number(rotation[1], summary_file, "monitor.sample_from_monitor.rotation_wxyz", &x));
  THINSLAB_RETURN_IF_ERROR(Number(rotation[2], summary_file, "monitor.sample_from_monitor.rotation_wxyz", &y));
  THINSLAB_RETURN_IF_ERROR(Number(rotation[3], summary_file, "monitor.sample_from_monitor.rotation_wxyz", &z));
  THINSLAB_RETURN_IF_ERROR(Number(translation[0], summary_file, "monitor.sample_from_monitor.translation_m", &tx));
  THINSLAB_RETURN_IF_ERROR(Number(translation[1], summary_file, "monitor.sample_from_monitor.translation_m", &ty));
  THINSLAB_RETURN_IF_ERROR(Number(translation[2], summary_file, "monitor.sample_from_monitor.translation_m", &tz));
  fit->sample_from_monitor.rotation = Eigen::Quaterniond(w, x, y, z).normalized();
  fit->sample_from_monitor.translation = Eigen::Vector3d(tx, ty, tz);
  THINSLAB_RETURN_IF_ERROR(
      Number(monitor.value("pixel_pitch_m", nlohmann::json()), summary_file, "monitor.pixel_pitch_m",
             &fit->monitor_pixel_pitch_m));
  THINSLAB_RETURN_IF_ERROR(Number(monitor.value("median_dot_radiance_dn_per_us", nlohmann::json()), summary_file,
                                  "monitor.median_dot_radiance_dn_per_us", &median_radiance));
  THINSLAB_RETURN_IF_ERROR(Number(summary.value("dot_radius", nlohmann::json::object()).value("monitor_px", nlohmann::json()),
                                  summary_file, "dot_radius.monitor_px", &radius));
  THINSLAB_RETURN_IF_ERROR(Number(summary.value("glass_thickness_m", nlohmann::json()), summary_file,
                                  "glass_thickness_m", &fit->glass_thickness_m));
  if (!(fit->monitor_pixel_pitch_m > 0) || !(median_radiance > 0) || !(radius > 0) || !(fit->glass_thickness_m >= 0)) {
    return Status::Error(summary_file + ": monitor pitch, median dot radiance and dot radius must be > 0, thickness >= 0");
  }
  fit->dot_radiance = median_radiance;
  fit->dot_radius_m = radius * fit->monitor_pixel_pitch_m;
  fit->dot_intensity = median_radiance * kPi * Sqr(fit->dot_radius_m);

  Image maps;
  THINSLAB_RETURN_IF_ERROR(ReadExr(maps_file, &maps));
  std::vector<double> grid_min, pitch, eta;
  THINSLAB_RETURN_IF_ERROR(NumericAttribute(maps, maps_file, "grid_min_m", 2, &grid_min));
  THINSLAB_RETURN_IF_ERROR(NumericAttribute(maps, maps_file, "pixel_pitch_m", 1, &pitch));
  THINSLAB_RETURN_IF_ERROR(NumericAttribute(maps, maps_file, "eta", 1, &eta));
  fit->grid_min_m = Eigen::Vector2d(grid_min[0], grid_min[1]);
  fit->pitch_m = pitch[0];
  fit->maps.eta = eta[0];
  if (!(fit->pitch_m > 0) || !(fit->maps.eta > 1)) return Status::Error(maps_file + ": needs pixel_pitch_m > 0, eta > 1");
  int c_alpha, c_smith, c_k_s, c_rho_d, c_status;
  THINSLAB_RETURN_IF_ERROR(RequireChannel(maps, maps_file, "top_face_weight", &c_alpha));
  THINSLAB_RETURN_IF_ERROR(RequireChannel(maps, maps_file, "smith_alpha", &c_smith));
  THINSLAB_RETURN_IF_ERROR(RequireChannel(maps, maps_file, "k_s", &c_k_s));
  THINSLAB_RETURN_IF_ERROR(RequireChannel(maps, maps_file, "rho_d", &c_rho_d));
  THINSLAB_RETURN_IF_ERROR(RequireChannel(maps, maps_file, "status", &c_status));

  Image atlas;
  THINSLAB_RETURN_IF_ERROR(ReadExr(atlas_file, &atlas));
  std::vector<double> resolution, stride;
  THINSLAB_RETURN_IF_ERROR(NumericAttribute(atlas, atlas_file, "ndf_resolution", 1, &resolution));
  THINSLAB_RETURN_IF_ERROR(NumericAttribute(atlas, atlas_file, "atlas_stride", 1, &stride));
  int c_d;
  THINSLAB_RETURN_IF_ERROR(RequireChannel(atlas, atlas_file, "D", &c_d));
  if (resolution[0] != std::floor(resolution[0]) || stride[0] != std::floor(stride[0]) || resolution[0] < 2 ||
      resolution[0] > 4096 || stride[0] < 1 || stride[0] > 65536) {
    return Status::Error(atlas_file + ": ndf_resolution and atlas_stride must be integers >= 2 and >= 1");
  }
  const int n = static_cast<int>(resolution[0]), s = static_cast<int>(stride[0]);
  const int tiles_x = (maps.width() + s - 1) / s, tiles_y = (maps.height() + s - 1) / s;
  if (atlas.width() != tiles_x * n || atlas.height() != tiles_y * n) {
    return Status::Error(atlas_file + ": " + std::to_string(atlas.width()) + "x" + std::to_string(atlas.height()) +
                         " does not hold the " + std::to_string(tiles_x) + "x" + std::to_string(tiles_y) +
                         " tiles of N = " + std::to_string(n) + " that maps.exr's grid and the stride give");
  }
  fit->atlas_stride = s;
  DmfMaps& m = fit->maps;
  m.width = maps.width();
  m.height = maps.height();
  m.ndf_resolution = n;
  m.fits.assign(static_cast<size_t>(m.width) * m.height, DmfPointFit());
  for (int row = 0; row < m.height; ++row) {
    for (int col = 0; col < m.width; ++col) {
      DmfPointFit& f = m.fits[static_cast<size_t>(row) * m.width + col];
      f.status = static_cast<DmfStatus>(static_cast<int>(maps.at(col, row, c_status)));
      f.alpha = maps.at(col, row, c_alpha);
      f.smith_alpha = maps.at(col, row, c_smith);
      f.k_s = maps.at(col, row, c_k_s);
      f.rho_d = maps.at(col, row, c_rho_d);
      if (f.status != DmfStatus::kOk && f.status != DmfStatus::kInterpolated) continue;
      // The atlas tile of the point, or of the nearest point the stride kept.
      const int tile_x = std::min(tiles_x - 1, (col + s / 2) / s), tile_y = std::min(tiles_y - 1, (row + s / 2) / s);
      f.log_ndf.resize(static_cast<size_t>(n) * n);
      bool any = false;
      for (int cell = 0; cell < n * n; ++cell) {
        const float d = atlas.at(tile_x * n + cell % n, tile_y * n + cell / n, c_d);
        any = any || d > 0;
        f.log_ndf[cell] = d > 0 ? std::log(d) : -80.0;
      }
      if (!any) f.log_ndf.clear();
    }
  }
  return Status::Ok();
}

Image PredictDotImage(const DmfFitOnDisk& fit, const CameraInfo& camera, const Eigen::Vector2d& dot_px) {
  Image out(camera.width_px, camera.height_px, {"predicted", "valid"});
  const DmfNdfGrid grid(fit.maps.ndf_resolution);
  const Rigid3d sample_from_cam = camera.cam_from_sample.Inverse();
  const Eigen::Vector3d eye = sample_from_cam.translation;
  const Eigen::Vector3d dot = fit.sample_from_monitor * Eigen::Vector3d(dot_px.x() * fit.monitor_pixel_pitch_m,
                                                                        dot_px.y() * fit.monitor_pixel_pitch_m, 0);
  for (int v = 0; v < camera.height_px; ++v) {
    for (int u = 0; u < camera.width_px; ++u) {
      const Eigen::Vector3d ray = sample_from_cam.rotation * PixelToCameraRay(camera, Eigen::Vector2d(u + 0.5, v + 0.5));
      if (!(std::abs(ray.z()) > 1e-12)) continue;
      const double t = -eye.z() / ray.z();
      if (!(t > 0)) continue;
      const Eigen::Vector3d x = eye + t * ray;
      const int col = static_cast<int>(std::floor((x.x() - fit.grid_min_m.x()) / fit.pitch_m));
      const int row = static_cast<int>(std::floor((x.y() - fit.grid_min_m.y()) / fit.pitch_m));
      if (col < 0 || row < 0 || col >= fit.maps.width || row >= fit.maps.height) continue;
      const DmfPointFit& f = fit.maps.fits[static_cast<size_t>(row) * fit.maps.width + col];
      if (f.log_ndf.empty()) continue;
      const Eigen::Vector3d entry = SlabLightEntryPoint(x, eye, fit.glass_thickness_m, fit.maps.eta);
      const Eigen::Vector3d to_dot = dot - entry;
      const double r2 = to_dot.squaredNorm();
      const Eigen::Vector3d i = to_dot / std::sqrt(r2);
      const double cos2 = Sqr(i.z());  // cos_e cos_i: monitor parallel to the sample, as in Eq. 12.
      const double r = PredictDualMicrofacet(f, grid, fit.maps.eta, SampleToOptical(i),
                                             SampleToOptical((eye - x).normalized()));
      out.at(u, v, 0) = static_cast<float>(r * fit.dot_intensity * cos2 / r2);
      out.at(u, v, 1) = 1;
    }
  }
  return out;
}

DotPredictionError ComparePrediction(const Image& prediction, const Image& radiance, const Image& variance,
                                     double lobe_fraction) {
  DotPredictionError e;
  double peak = 0;
  for (int v = 0; v < prediction.height(); ++v) {
    for (int u = 0; u < prediction.width(); ++u) {
      if (prediction.at(u, v, 1) > 0) peak = std::max(peak, static_cast<double>(radiance.at(u, v)));
    }
  }
  if (!(peak > 0)) return e;
  double num = 0, den = 0, noise = 0;
  for (int v = 0; v < prediction.height(); ++v) {
    for (int u = 0; u < prediction.width(); ++u) {
      const double measured = radiance.at(u, v);
      if (!(prediction.at(u, v, 1) > 0) || measured < lobe_fraction * peak) continue;
      num += Sqr(prediction.at(u, v, 0) - measured);
      den += Sqr(measured);
      noise += std::max(0.0f, variance.at(u, v));
      ++e.pixels;
    }
  }
  if (den > 0) {
    e.relative_rms = std::sqrt(num / den);
    e.noise_relative_rms = std::sqrt(noise / den);
  }
  return e;
}

}  // namespace thinslab
