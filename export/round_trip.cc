// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/round_trip.h"

#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/false_color.h"
#include "thinslab/core/file.h"
#include "thinslab/core/png_io.h"
#include "thinslab/core/provenance.h"
#include "thinslab/core/session_io.h"
#include "thinslab/export/blender_render.h"
#include "thinslab/export/dot_round_trip.h"
#include "thinslab/export/lobe_round_trip.h"
#include "thinslab/export/round_trip_outputs.h"
#include "thinslab/export/scene_from_fit.h"
#include "thinslab/pipeline/capture_reading.h"
#include "thinslab/pipeline/prediction_report.h"

namespace thinslab {

namespace {

// The capture's camera image averaged over n x n blocks: a block is valid when all its pixels are.
struct BlockImages {
  Image measured, clean, predicted, variance, tau, sigma_tau;
  std::vector<uint8_t> valid;
};
BlockImages AverageBlocks(const Image& camera, int n, int width, int height) {
  const int measured_c = camera.ChannelIndex("measured"), clean_c = camera.ChannelIndex("clean"),
            predicted_c = camera.ChannelIndex("predicted"), variance_c = camera.ChannelIndex("variance"),
            valid_c = camera.ChannelIndex("valid"), tau_c = camera.ChannelIndex("tau"),
            sigma_c = camera.ChannelIndex("sigma_tau");
  BlockImages b{Image(width, height),
                Image(width, height),
                Image(width, height),
                Image(width, height),
                Image(width, height),
                Image(width, height),
                std::vector<uint8_t>(static_cast<size_t>(width) * height, 0)};
  const double n2 = static_cast<double>(n) * n;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      double m = 0, c = 0, p = 0, v = 0, t = 0, s = 0;
      bool valid = true;
      for (int dy = 0; dy < n && valid; ++dy) {
        for (int dx = 0; dx < n && valid; ++dx) {
          const int u = x * n + dx, w = y * n + dy;
          valid = camera.at(u, w, valid_c) > 0;
          m += camera.at(u, w, measured_c);
          c += camera.at(u, w, clean_c);
          p += camera.at(u, w, predicted_c);
          v += camera.at(u, w, variance_c);
          t += camera.at(u, w, tau_c);
          s += camera.at(u, w, sigma_c);
        }
      }
      if (!valid) continue;
      b.valid[static_cast<size_t>(y) * width + x] = 1;
      b.measured.at(x, y) = static_cast<float>(m / n2);
      b.clean.at(x, y) = static_cast<float>(c / n2);
      b.predicted.at(x, y) = static_cast<float>(p / n2);
      b.variance.at(x, y) = static_cast<float>(v / (n2 * n2));  // Of a mean of n^2 (independent) pixels.
      b.tau.at(x, y) = static_cast<float>(t / n2);
      b.sigma_tau.at(x, y) = static_cast<float>(s / n2);
    }
  }
  return b;
}

nlohmann::json RoundTripRegionsJson(const std::vector<ShadowPredictionRegion>& render_vs_capture,
                                    const std::vector<ShadowPredictionRegion>& render_vs_predict) {
  nlohmann::json regions = nlohmann::json::array();
  for (size_t k = 0; k < render_vs_capture.size(); ++k) {
    const ShadowPredictionRegion& r = render_vs_capture[k];
    const ShadowPredictionRegion& p = render_vs_predict[k];
    regions.push_back({{"region", r.name},
                       {"tau_min", r.tau_min},
                       {"tau_max", r.tau_max},
                       {"pixels", r.pixels},
                       {"render_vs_capture_relative_rms", r.relative_rms},
                       {"predict_vs_capture_relative_rms", r.alternative_relative_rms},
                       {"render_vs_predict_relative_rms", p.relative_rms},
                       {"noise_relative_rms", r.noise_relative_rms},
                       {"render_noise_relative_rms", p.noise_relative_rms},
                       {"sigma_tau_relative_rms", r.sigma_tau_relative_rms}});
  }
  return regions;
}

}  // namespace

Status RoundTripRun::Check() const {
  if (!(samples >= 0 && samples <= 65536))
    return Status::Error("--samples: must be 0 (the capture kind's default) to 65536");
  if (!(downsample >= 1 && downsample <= 64)) return Status::Error("--downsample: must be 1 to 64");
  if (blender.empty()) return Status::Error("--blender: empty");
  return Status::Ok();
}

namespace {

// The render's passes: reference, shadow 1 and 2 (export/blender_scene's --passes).
constexpr int kRenderPasses = 3;
constexpr int kDefaultShadowSamples = 32;

}  // namespace

Status RenderRoundTrip(const RoundTripRun& run, std::ostream& log) {
  THINSLAB_RETURN_IF_ERROR(run.Check());
  if (run.session_dir.empty()) return Status::Error("thinslab roundtrip: CAPTURE is required");
  Session session;
  THINSLAB_RETURN_IF_ERROR(ReadCaptureForCommand(run.session_dir, run.allow_incomplete_capture, &session));
  const std::string manifest = JoinPath(run.session_dir, kSessionManifestName);
  if (session.kind == "laser_lobe") return RenderLobeRoundTrip(run, session, log);
  if (session.kind == "dot_scan") return RenderDotRoundTrip(run, session, log);
  if (!run.dots.empty()) return Status::Error("--dots: applies to dot-scan captures");
  if (session.kind != "shadow_map") {
    return Status::Error(manifest + ": kind \"" + session.kind +
                         "\": the render round trip covers shadow-map, laser-lobe and dot-scan captures");
  }
  const int samples = run.samples > 0 ? run.samples : kDefaultShadowSamples;
  std::string fit_dir;
  THINSLAB_RETURN_IF_ERROR(
      ResolveRoundTripFit(run.session_dir, run.fit_dir, "tau", "tau.exr", "shadow-map", "fit tau", &fit_dir));
  const std::string out_dir = RoundTripOutDir(run.session_dir, run.out_dir);
  StagedDirectory out(out_dir, "roundtrip", {{run.session_dir, {"fit"}}, {fit_dir, {}}});
  THINSLAB_RETURN_IF_ERROR(out.Init());

  // What thinslab's own model predicts in the capture's camera, with the capture's frames.
  ShadowPrediction prediction;
  THINSLAB_RETURN_IF_ERROR(PredictShadow(run.session_dir, session, fit_dir, run.calibration, &prediction));
  const CameraInfo& camera = prediction.data.camera;
  // The fitted layer under the capture's rig, seen by the capture's camera at 1/n resolution
  // (an n x n block of camera pixels is one rendered pixel: centres map as (c + 0.5) / n - 0.5).
  ExportOptions export_options;
  RenderScene scene;
  THINSLAB_RETURN_IF_ERROR(SceneFromFit(fit_dir, export_options, &scene));
  if (!scene.layer) return Status::Error(fit_dir + ": not a scattering layer");
  scene.layer->g = prediction.layer.layer_g;
  scene.layer->albedo = prediction.layer.refine_scattering ? prediction.layer.layer_albedo : 0.0;
  const int n = run.downsample;
  THINSLAB_RETURN_IF_ERROR(SetCaptureCamera(camera, n, manifest, &scene));
  const int width = scene.image_width, height = scene.image_height;
  ShadowRig rig;
  rig.board_distance_m = prediction.data.board_distance_m;
  rig.board_albedo = session.rig.board.albedo > 0 ? session.rig.board.albedo : 0.8;
  rig.light_propagation = session.rig.projector.direction_in_sample.normalized();
  if (!(rig.light_propagation.z() < 0)) {
    return Status::Error(manifest +
                         ": rig.projector.direction_in_sample must point from the projector to the board "
                         "(negative z)");
  }
  scene.shadow_rig = rig;
  scene.notes.push_back("round trip of " + run.session_dir + ": the capture's camera at 1/" + std::to_string(n) +
                        " resolution, the board at " + std::to_string(rig.board_distance_m * 1e3) +
                        " mm lit by a collimated light; the layer is seen by light only");

  const Provenance provenance{"roundtrip", run.session_dir, fit_dir, run.options_ini};
  std::string scene_dir, prefix;
  THINSLAB_RETURN_IF_ERROR(WriteRoundTripScene(scene, out.path(), provenance, &scene_dir, &prefix));
  log << "roundtrip: rendering " << width << "x" << height << " px at " << samples << " samples, 3 passes, with "
      << run.blender << " (log: " << JoinPath(JoinPath(out_dir, "scene"), "blender.log") << ")\n";
  THINSLAB_RETURN_IF_ERROR(RenderBlenderPasses(run.blender, scene_dir, prefix, kRenderPasses, samples,
                                               "roundtrip: Blender render", run.progress));
  Image reference, shadow_1, shadow_2;
  THINSLAB_RETURN_IF_ERROR(ReadBlenderRender(prefix + "_reference.exr", width, height, "", &reference));
  THINSLAB_RETURN_IF_ERROR(ReadBlenderRender(prefix + "_shadow_1.exr", width, height, "", &shadow_1));
  THINSLAB_RETURN_IF_ERROR(ReadBlenderRender(prefix + "_shadow_2.exr", width, height, "", &shadow_2));

  // The rendered shadow in the capture's units: ratio to the rendered reference times the
  // block's clean signal. Its noise from the two seeds: var(mean of 2) = (s1 - s2)^2 / 4.
  BlockImages b = AverageBlocks(prediction.camera, n, width, height);
  Image rendered(width, height), render_variance(width, height), capture_and_render_variance(width, height);
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const size_t k = static_cast<size_t>(y) * width + x;
      const double ref = reference.at(x, y);
      if (!(ref > 0)) b.valid[k] = 0;
      if (!b.valid[k]) continue;
      const double clean = b.clean.at(x, y);
      const double s1 = shadow_1.at(x, y) / ref, s2 = shadow_2.at(x, y) / ref;
      rendered.at(x, y) = static_cast<float>(0.5 * (s1 + s2) * clean);
      render_variance.at(x, y) = static_cast<float>(0.25 * (s1 - s2) * (s1 - s2) * clean * clean);
      capture_and_render_variance.at(x, y) = b.variance.at(x, y) + render_variance.at(x, y);
    }
  }
  const std::vector<ShadowPredictionRegion> render_vs_capture = CompareShadowPrediction(
      rendered, b.predicted, b.measured, capture_and_render_variance, b.tau, b.sigma_tau, b.valid);
  const std::vector<ShadowPredictionRegion> render_vs_predict =
      CompareShadowPrediction(rendered, Image(), b.predicted, render_variance, b.tau, b.sigma_tau, b.valid);

  Image images(
      width, height,
      {"rendered", "predicted", "measured", "variance", "render_variance", "valid", "tau", "difference", "clean"});
  double white = 0;
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      const size_t k = static_cast<size_t>(y) * width + x;
      if (!b.valid[k]) continue;
      images.at(x, y, 0) = rendered.at(x, y);
      images.at(x, y, 1) = b.predicted.at(x, y);
      images.at(x, y, 2) = b.measured.at(x, y);
      images.at(x, y, 3) = b.variance.at(x, y);
      images.at(x, y, 4) = render_variance.at(x, y);
      images.at(x, y, 5) = 1;
      images.at(x, y, 6) = b.tau.at(x, y);
      images.at(x, y, 7) = rendered.at(x, y) - b.measured.at(x, y);
      images.at(x, y, 8) = b.clean.at(x, y);
      white = std::max(white, static_cast<double>(b.clean.at(x, y)));
    }
  }
  images.attributes()["units"] = "DN/us in the capture's camera pixels averaged over downsample^2 blocks";
  THINSLAB_RETURN_IF_ERROR(
      WriteMapExr(JoinPath(out.path(), "roundtrip.exr"), images, {"rendered", {"valid"}}, provenance));
  if (!(white > 0)) {
    return Status::Error(manifest + ": no camera pixel sees the fitted map with a clean signal; nothing to compare");
  }
  // On one grey scale, white the brightest clean signal.
  THINSLAB_RETURN_IF_ERROR(WriteRoundTripPictures(out.path(), images, {2, 0, 1, 7, 5}, white));

  nlohmann::json j = RoundTripSummaryHead("shadow_map", provenance, run.session_dir, fit_dir, samples);
  j["downsample"] = n;
  j["image"] = {{"width", width}, {"height", height}};
  j["board_distance_m"] = rig.board_distance_m;
  j["layer"] = {{"g", scene.layer->g}, {"albedo", scene.layer->albedo}};
  j["measured_frames"] = prediction.validation ? "validation" : "fitted";
  j["regions"] = RoundTripRegionsJson(render_vs_capture, render_vs_predict);
  j["notes"] = scene.notes;
  std::ostringstream txt;
  txt << "thinslab roundtrip: " << fit_dir << " rendered by Blender (Cycles, " << samples
      << " samples) under the rig of " << run.session_dir << ", " << width << "x" << height << " px (" << n << "x" << n
      << " camera pixels each), against the capture's " << (prediction.validation ? "validation" : "fitted")
      << " shadow frames and thinslab predict:\n";
  for (size_t k = 0; k < render_vs_capture.size(); ++k) {
    const ShadowPredictionRegion& r = render_vs_capture[k];
    txt << "  " << r.name << " (" << r.pixels << " px): Blender vs capture " << RoundTripFigure(r.relative_rms)
        << ", predict vs capture " << RoundTripFigure(r.alternative_relative_rms) << ", Blender vs predict "
        << RoundTripFigure(render_vs_predict[k].relative_rms) << " (noise: capture + render "
        << RoundTripFigure(r.noise_relative_rms) << ", render "
        << RoundTripFigure(render_vs_predict[k].noise_relative_rms) << ")\n";
  }
  return FinishRoundTrip(&out, j, txt.str(), run.options_ini, log);
}

}  // namespace thinslab
