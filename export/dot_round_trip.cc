// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/dot_round_trip.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include "thinslab/calib/frame_noise.h"
#include "thinslab/calib/hdr_merge.h"
#include "thinslab/calib/session_calibration.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/provenance.h"
#include "thinslab/export/blender_render.h"
#include "thinslab/export/round_trip_outputs.h"
#include "thinslab/export/scene_from_fit.h"
#include "thinslab/fit/dmf_prediction.h"
#include "thinslab/pipeline/predict.h"

namespace thinslab {

namespace {

constexpr int kDefaultSamples = 1024;  // ~0.2 relative noise per 2 x 2 block in the lobe (docs/export.md).
constexpr double kLobeFraction = 0.1;  // As `thinslab predict`: pixels at >= 10 % of the lobe's peak.
// Faces of a thin fit (glass_thickness_m 0, Dai's infinitely thin slab) rendered this far apart:
// thin against the monitor's distance, thick against Cycles' ray offsets.
constexpr double kThinSlabMm = 0.01;

// Mean of `image` channel c over the n x n camera pixels of render pixel (x, y).
double BlockMean(const Image& image, int c, int n, int x, int y) {
  double sum = 0;
  for (int dy = 0; dy < n; ++dy) {
    for (int dx = 0; dx < n; ++dx) sum += image.at(x * n + dx, y * n + dy, c);
  }
  return sum / (n * n);
}

nlohmann::json ErrorJson(const DotPredictionError& e) {
  return {{"pixels", e.pixels}, {"relative_rms", e.relative_rms}, {"noise_relative_rms", e.noise_relative_rms}};
}

}  // namespace

Status RenderDotRoundTrip(const RoundTripRun& run, const Session& session, std::ostream& log) {
  const std::string manifest = JoinPath(run.session_dir, kSessionManifestName);
  std::string fit_dir;
  THINSLAB_RETURN_IF_ERROR(
      ResolveRoundTripFit(run.session_dir, run.fit_dir, "dmf", "maps.exr", "dot-scan", "fit dmf", &fit_dir));
  if (session.rig.cameras.empty()) return Status::Error(manifest + ": rig.cameras is empty");
  std::vector<Eigen::Vector2d> dots;
  if (!run.dots.empty()) THINSLAB_RETURN_IF_ERROR(ParseDotList(run.dots, &dots));
  const std::string out_dir = RoundTripOutDir(run.session_dir, run.out_dir);
  StagedDirectory out(out_dir, "roundtrip", {{run.session_dir, {"fit"}}, {fit_dir, {}}});
  THINSLAB_RETURN_IF_ERROR(out.Init());

  DmfFitOnDisk fit;
  THINSLAB_RETURN_IF_ERROR(ReadDmfFit(fit_dir, &fit));
  CameraInfo camera = session.rig.cameras[0];
  SessionCalibration calibration;
  THINSLAB_RETURN_IF_ERROR(LoadSessionCalibration(run.session_dir, run.calibration, &camera, &calibration));
  if (dots.empty()) THINSLAB_RETURN_IF_ERROR(ValidationDots(run.session_dir, session, camera, &dots));
  FrameNoiseModel noise;
  THINSLAB_RETURN_IF_ERROR(ResolveFrameNoise(run.session_dir, session, camera, &noise));

  // The exported slab under the capture's camera and monitor. A thin fit keeps thin faces: the
  // export's 1 mm default would shift every ray sideways by up to a few tenths of a millimetre.
  ExportOptions export_options;
  export_options.slab_thickness_mm = std::max(fit.glass_thickness_m * 1e3, kThinSlabMm);
  RenderScene scene;
  THINSLAB_RETURN_IF_ERROR(SceneFromFit(fit_dir, export_options, &scene));
  if (!scene.slab) return Status::Error(fit_dir + ": not a dual-microfacet fit");
  const int n = run.downsample;
  THINSLAB_RETURN_IF_ERROR(SetCaptureCamera(camera, n, manifest, &scene));
  const int width = scene.image_width, height = scene.image_height;
  DotMonitor monitor;
  monitor.radiance = fit.dot_radiance;
  const Eigen::Vector3d grid_centre(scene.grid.centre_m().x(), scene.grid.centre_m().y(), 0);
  for (const Eigen::Vector2d& dot_px : dots) {
    DotMonitor::Dot dot;
    dot.centre_m = fit.sample_from_monitor *
                   Eigen::Vector3d(dot_px.x() * fit.monitor_pixel_pitch_m, dot_px.y() * fit.monitor_pixel_pitch_m, 0);
    dot.normal = fit.sample_from_monitor.rotation * Eigen::Vector3d::UnitZ();
    if (dot.normal.dot(grid_centre - dot.centre_m) < 0) dot.normal = -dot.normal;
    dot.radius_m = fit.dot_radius_m;
    monitor.dots.push_back(dot);
  }
  scene.dot_monitor = monitor;
  scene.notes.push_back("round trip of " + run.session_dir + ": the capture's camera at 1/" + std::to_string(n) +
                        " resolution, the monitor's dots one at a time at the fit's median dot radiance");

  const int samples = run.samples > 0 ? run.samples : kDefaultSamples;
  const Provenance provenance{"roundtrip", run.session_dir, fit_dir, run.options_ini};
  std::string scene_dir, prefix;
  THINSLAB_RETURN_IF_ERROR(WriteRoundTripScene(scene, out.path(), provenance, &scene_dir, &prefix));
  const int passes = 2 * static_cast<int>(dots.size());
  log << "roundtrip: rendering " << dots.size() << " dots, " << width << "x" << height << " px at " << samples
      << " samples, " << passes << " passes, with " << run.blender
      << " (log: " << JoinPath(JoinPath(out_dir, "scene"), "blender.log") << ")\n";
  THINSLAB_RETURN_IF_ERROR(
      RenderBlenderPasses(run.blender, scene_dir, prefix, passes, samples, "roundtrip: Blender render", run.progress));

  nlohmann::json entries = nlohmann::json::array();
  std::ostringstream txt;
  txt << "thinslab roundtrip: " << fit_dir << " exported as a " << scene.slab->distribution
      << " slab and rendered by Blender (Cycles, " << samples << " samples) under the dot-scan rig of "
      << run.session_dir << ", " << width << "x" << height << " px (" << n << "x" << n
      << " camera pixels each), against the capture's frames of each dot and thinslab predict (Dai Eq. 12), in the "
         "lobe (pixels at >= 10 % of its peak):\n";
  for (size_t k = 0; k < dots.size(); ++k) {
    const std::string dot_name = "(" + std::to_string(dots[k].x()) + ", " + std::to_string(dots[k].y()) + ")";
    HdrImage hdr;
    bool measured = false;
    THINSLAB_RETURN_IF_ERROR(
        MergeDotFrames(run.session_dir, session, camera, calibration, noise, dots[k], &hdr, &measured));
    if (!measured) {
      return Status::Error(manifest + ": no frame of dot " + dot_name +
                           " (--dots): the round trip compares the render with the capture's frames of the dot");
    }
    const Image predicted_full = PredictDotImage(fit, camera, dots[k]);
    Image render_1, render_2;
    const std::string render_prefix = prefix + "_dot" + std::to_string(k);
    THINSLAB_RETURN_IF_ERROR(ReadBlenderRender(render_prefix + "_1.exr", width, height, "", &render_1));
    THINSLAB_RETURN_IF_ERROR(ReadBlenderRender(render_prefix + "_2.exr", width, height, "", &render_2));

    // At the render's resolution: a block counts when the fit predicts every pixel of it.
    Image images(width, height,
                 {"rendered", "predicted", "measured", "variance", "render_variance", "valid", "difference"});
    Image rendered(width, height, {"predicted", "valid"}), predicted(width, height, {"predicted", "valid"});
    Image measured_blocks(width, height), variance(width, height), both_variance(width, height),
        render_variance(width, height);
    double white = 0;
    for (int y = 0; y < height; ++y) {
      for (int x = 0; x < width; ++x) {
        bool valid = true;
        for (int dy = 0; dy < n && valid; ++dy) {
          for (int dx = 0; dx < n && valid; ++dx) valid = predicted_full.at(x * n + dx, y * n + dy, 1) > 0;
        }
        if (!valid) continue;
        const double r = 0.5 * (render_1.at(x, y) + render_2.at(x, y));
        const double r_var = 0.25 * Sqr(render_1.at(x, y) - render_2.at(x, y));
        const double m = BlockMean(hdr.radiance, 0, n, x, y);
        const double v = BlockMean(hdr.variance, 0, n, x, y) / (n * n);  // Of a mean of n^2 pixels.
        const double p = BlockMean(predicted_full, 0, n, x, y);
        rendered.at(x, y, 0) = static_cast<float>(r);
        predicted.at(x, y, 0) = static_cast<float>(p);
        rendered.at(x, y, 1) = predicted.at(x, y, 1) = 1;
        measured_blocks.at(x, y) = static_cast<float>(m);
        variance.at(x, y) = static_cast<float>(v);
        render_variance.at(x, y) = static_cast<float>(r_var);
        both_variance.at(x, y) = static_cast<float>(v + r_var);
        const float row[] = {static_cast<float>(r),    static_cast<float>(p),     static_cast<float>(m),
                             static_cast<float>(v),    static_cast<float>(r_var), 1.0f,
                             static_cast<float>(r - m)};
        for (int c = 0; c < 7; ++c) images.at(x, y, c) = row[c];
        white = std::max(white, m);
      }
    }
    if (!(white > 0)) {
      return Status::Error(manifest + ": dot " + dot_name +
                           ": no camera pixel that sees a fitted map point sees its light; nothing to compare");
    }
    const DotPredictionError render_vs_capture =
        ComparePrediction(rendered, measured_blocks, both_variance, kLobeFraction);
    const DotPredictionError predict_vs_capture =
        ComparePrediction(predicted, measured_blocks, variance, kLobeFraction);
    const DotPredictionError render_vs_predict =
        ComparePrediction(rendered, predicted.Channel(0), render_variance, kLobeFraction);
    const std::string file = "dot_" + std::to_string(k) + ".exr";
    images.attributes()["units"] = "DN/us, black level and darks removed, averaged over downsample^2 camera pixels";
    THINSLAB_RETURN_IF_ERROR(WriteMapExr(JoinPath(out.path(), file), images, {"rendered", {"valid"}}, provenance));
    THINSLAB_RETURN_IF_ERROR(
        WriteRoundTripPictures(out.path(), images, {2, 0, 1, 6, 5}, white, "_dot" + std::to_string(k)));
    entries.push_back({{"dot_px", {dots[k].x(), dots[k].y()}},
                       {"file", file},
                       {"render_vs_capture", ErrorJson(render_vs_capture)},
                       {"predict_vs_capture", ErrorJson(predict_vs_capture)},
                       {"render_vs_predict", ErrorJson(render_vs_predict)}});
    txt << "  dot " << dot_name << " (" << render_vs_capture.pixels << " px): Blender vs capture "
        << RoundTripFigure(render_vs_capture.relative_rms) << ", predict vs capture "
        << RoundTripFigure(predict_vs_capture.relative_rms) << ", Blender vs predict "
        << RoundTripFigure(render_vs_predict.relative_rms) << " (noise: capture + render "
        << RoundTripFigure(render_vs_capture.noise_relative_rms) << ", capture "
        << RoundTripFigure(predict_vs_capture.noise_relative_rms) << ", render "
        << RoundTripFigure(render_vs_predict.noise_relative_rms) << ")\n";
  }

  nlohmann::json j = RoundTripSummaryHead("dot_scan", provenance, run.session_dir, fit_dir, samples);
  j["downsample"] = n;
  j["image"] = {{"width", width}, {"height", height}};
  j["slab"] = {
      {"distribution", scene.slab->distribution}, {"eta", scene.slab->eta}, {"thickness_m", scene.slab->thickness_m}};
  j["dot_radiance_dn_per_us"] = fit.dot_radiance;
  j["dot_radius_m"] = fit.dot_radius_m;
  j["lobe_fraction"] = kLobeFraction;
  j["dots"] = entries;
  j["notes"] = scene.notes;
  return FinishRoundTrip(&out, j, txt.str(), run.options_ini, log);
}

}  // namespace thinslab
