// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/round_trip_outputs.h"

#include <cmath>
#include <sstream>

#include "thinslab/core/false_color.h"
#include "thinslab/core/png_io.h"
#include "thinslab/export/blender_scene.h"

namespace thinslab {

Status ResolveRoundTripFit(const std::string& session_dir, const std::string& given, const std::string& folder,
                           const std::string& required_file, const std::string& capture_kind,
                           const std::string& fit_command, std::string* fit_dir) {
  *fit_dir = given.empty() ? JoinPath(JoinPath(session_dir, "fit"), folder) : given;
  if (FileExists(JoinPath(*fit_dir, required_file))) return Status::Ok();
  return Status::Error(*fit_dir + ": no " + required_file + ": the round trip of a " + capture_kind +
                       " capture renders a `thinslab " + fit_command +
                       "` output (run it first or give its folder with --fit)");
}

std::string RoundTripOutDir(const std::string& session_dir, const std::string& given) {
  return given.empty() ? JoinPath(JoinPath(session_dir, "fit"), "roundtrip") : given;
}

Status WriteRoundTripScene(const RenderScene& scene, const std::string& staged_dir, const Provenance& provenance,
                           std::string* scene_dir, std::string* render_prefix) {
  *scene_dir = JoinPath(staged_dir, "scene");
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(*scene_dir));
  THINSLAB_RETURN_IF_ERROR(WriteBlenderScene(scene, *scene_dir, provenance));
  *render_prefix = JoinPath(*scene_dir, "render");
  return Status::Ok();
}

nlohmann::json RoundTripSummaryHead(const std::string& kind, const Provenance& provenance,
                                    const std::string& session_dir, const std::string& fit_dir, int samples) {
  nlohmann::json j;
  j["format"] = "thinslab-roundtrip-summary";
  j["provenance"] = ProvenanceJson(provenance);
  j["kind"] = kind;
  j["session"] = session_dir;
  j["fit"] = fit_dir;
  j["renderer"] = "blender";
  j["samples"] = samples;
  return j;
}

std::string RoundTripFigure(double value, int digits) {
  if (value < 0) return "-";
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << value;
  return s.str();
}

Status SetCaptureCamera(const CameraInfo& camera, int downsample, const std::string& manifest, RenderScene* scene) {
  for (double k : camera.distortion) {
    if (k != 0) {
      return Status::Error(manifest + ": camera " + camera.id +
                           " has lens distortion; Blender renders a pinhole camera, so the round trip needs "
                           "undistorted frames and zero distortion coefficients");
    }
  }
  const int n = downsample;
  const int width = camera.width_px / n, height = camera.height_px / n;
  if (width < 8 || height < 8) {
    return Status::Error("--downsample " + std::to_string(n) + ": leaves " + std::to_string(width) + "x" +
                         std::to_string(height) + " px of camera " + camera.id + "'s " +
                         std::to_string(camera.width_px) + "x" + std::to_string(camera.height_px));
  }
  scene->cam_from_sample = camera.cam_from_sample;
  scene->image_width = width;
  scene->image_height = height;
  scene->intrinsics = PinholeIntrinsics{camera.fx_px / n, camera.fy_px / n, (camera.cx_px + 0.5) / n - 0.5,
                                        (camera.cy_px + 0.5) / n - 0.5};
  return Status::Ok();
}

Status WriteRoundTripPictures(const std::string& dir, const Image& images, const RoundTripChannels& channels,
                              double white, const std::string& suffix) {
  const int w = images.width(), h = images.height();
  Image magnified_difference(w, h), invalid(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      magnified_difference.at(x, y) = 5 * std::abs(images.at(x, y, channels.difference));
      invalid.at(x, y) = images.at(x, y, channels.valid) > 0 ? 0.0f : 1.0f;
    }
  }
  THINSLAB_RETURN_IF_ERROR(
      WritePngAtomically(JoinPath(dir, "roundtrip" + suffix + ".png"),
                         SideBySide({LabelledRadianceTile(images, channels.measured, white, "capture"),
                                     LabelledRadianceTile(images, channels.rendered, white, "Blender"),
                                     LabelledRadianceTile(magnified_difference, 0, white, "|diff| x5"),
                                     LabelledRadianceTile(images, channels.predicted, white, "predict")})));
  FalseColorOptions difference_colors;
  difference_colors.scale_kind = ColorScale::kDiverging;
  difference_colors.min_value = -0.1 * white;
  difference_colors.max_value = 0.1 * white;
  difference_colors.label = "render - capture";
  return WriteFalseColorPng(JoinPath(dir, "difference" + suffix + ".png"), images, channels.difference, &invalid,
                            difference_colors);
}

Status FinishRoundTrip(StagedDirectory* out, const nlohmann::json& summary, const std::string& text,
                       const std::string& options_ini, std::ostream& log) {
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out->path(), "summary.json"), summary.dump(2) + "\n"));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out->path(), "summary.txt"), text));
  if (!options_ini.empty()) {
    THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out->path(), "options.ini"), options_ini));
  }
  THINSLAB_RETURN_IF_ERROR(out->Commit());
  log << text << "wrote " << out->final_path() << "\n";
  return Status::Ok();
}

}  // namespace thinslab
