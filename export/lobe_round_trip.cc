// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/lobe_round_trip.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/false_color.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/png_io.h"
#include "thinslab/core/provenance.h"
#include "thinslab/export/blender_render.h"
#include "thinslab/export/round_trip_outputs.h"
#include "thinslab/optics/dirty_glass.h"
#include "thinslab/pipeline/prediction_report.h"

namespace thinslab {

namespace {

constexpr int kLobePasses = 2;         // Two seeds: the render's own noise.
constexpr int kDefaultSamples = 8192;  // Per probe pixel: ~1 % noise per ring over 25 rings (docs/export.md).
constexpr int kProbePixels = 16;       // The probe image spans 4 beam radii: 1/4 radius per pixel.

// The rings' light groups of one render: ring k's value = sum over the probe image of (the beam's
// Gaussian profile x radiance) / the ring's area (render_scene.h LaserProbe).
Status ReadProbeRings(const std::string& path, const LaserProbe& probe, std::vector<double>* rings) {
  const int n = probe.image_px;
  std::vector<double> weight(static_cast<size_t>(n) * n);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      const double u = ((x + 0.5) / n - 0.5) * probe.view_size_m, v = ((y + 0.5) / n - 0.5) * probe.view_size_m;
      weight[static_cast<size_t>(y) * n + x] = std::exp(-2 * (u * u + v * v) / Sqr(probe.beam_radius_m));
    }
  }
  rings->assign(probe.ring_inner_m.size(), 0.0);
  for (size_t k = 0; k < rings->size(); ++k) {
    Image pass;
    THINSLAB_RETURN_IF_ERROR(ReadBlenderRender(path, n, n, "ViewLayer.Combined_ring" + std::to_string(k) + ".", &pass));
    double sum = 0;
    for (int y = 0; y < n; ++y) {
      for (int x = 0; x < n; ++x) sum += weight[static_cast<size_t>(y) * n + x] * pass.at(x, y);
    }
    (*rings)[k] = sum / (kPi * (Sqr(probe.ring_outer_m[k]) - Sqr(probe.ring_inner_m[k])));
  }
  return Status::Ok();
}

// Linear in r between the rings' mean radii, held at the ends.
double InterpolateRings(const std::vector<LaserRing>& rings, const std::vector<double>& values, double r) {
  if (r <= rings.front().r_m) return values.front();
  for (size_t k = 1; k < rings.size(); ++k) {
    if (r < rings[k].r_m) {
      const double t = (r - rings[k - 1].r_m) / (rings[k].r_m - rings[k - 1].r_m);
      return (1 - t) * values[k - 1] + t * values[k];
    }
  }
  return values.back();
}

double LeastSquaresScale(const std::vector<double>& model, const std::vector<double>& data) {
  double pm = 0, pp = 0;
  for (size_t k = 0; k < model.size(); ++k) {
    pm += model[k] * data[k];
    pp += model[k] * model[k];
  }
  return pp > 0 ? pm / pp : 0;
}

}  // namespace

Status RenderLobeRoundTrip(const RoundTripRun& run, const Session& session, std::ostream& log) {
  const std::string manifest = JoinPath(run.session_dir, kSessionManifestName);
  std::string fit_dir;
  THINSLAB_RETURN_IF_ERROR(
      ResolveRoundTripFit(run.session_dir, run.fit_dir, "phase", "summary.json", "laser-lobe", "fit phase", &fit_dir));
  const Eigen::Vector3d beam = session.rig.laser.direction_in_sample.normalized();
  if (!session.rig.laser.present || !(beam.z() < -std::cos(kPi / 180))) {
    return Status::Error(manifest +
                         ": rig.laser.direction_in_sample must point along -z within 1 degree (the beam at normal "
                         "incidence, as Gu Eq. 8 and the rendered rig assume)");
  }
  const std::string out_dir = RoundTripOutDir(run.session_dir, run.out_dir);
  StagedDirectory out(out_dir, "roundtrip", {{run.session_dir, {"fit"}}, {fit_dir, {}}});
  THINSLAB_RETURN_IF_ERROR(out.Init());

  LobeFitPrediction fit;
  THINSLAB_RETURN_IF_ERROR(PredictLobe(run.session_dir, session, fit_dir, run.calibration, &fit));
  const LaserLobeImages& images = fit.images;
  const LobePrediction& prediction = fit.prediction;
  const std::vector<LaserRing>& rings = prediction.rings;
  const double d = images.board_distance_m;

  // The exported layer under the capture's rig, seen by reciprocity (render_scene.h LaserProbe).
  std::vector<std::string> notes;
  double albedo = fit.layer_albedo;
  if (!(albedo >= 0 && albedo <= 1)) {
    albedo = PhaseFitOptions().layer_albedo;
    notes.push_back("the fit recorded no layer albedo (a summary older than 2026-12-08): rendered with " +
                    RoundTripFigure(albedo, 2) + ", fit phase's default");
  }
  LaserProbe probe;
  probe.board_distance_m = d;
  probe.beam_radius_m = images.beam_radius_m > 0 ? images.beam_radius_m : images.pixel_pitch_m;
  if (!(images.beam_radius_m > 0)) {
    notes.push_back("rig.laser.beam_radius_m is not given: rendered with a beam of one board pixel's radius");
  }
  probe.beam_centre_m = prediction.geometry.beam_centre_m;
  probe.view_size_m = 4 * probe.beam_radius_m;
  probe.image_px = kProbePixels;
  const double ring_w = PhaseFitOptions().ring_width_px * images.pixel_pitch_m;
  for (const LaserRing& ring : rings) {
    const double inner =
        prediction.geometry.r_core_m + ring_w * std::floor((ring.r_m - prediction.geometry.r_core_m) / ring_w);
    probe.ring_inner_m.push_back(inner);
    probe.ring_outer_m.push_back(inner + ring_w);
  }
  RenderScene scene;
  const double half = prediction.geometry.r_max_m + 0.002;
  scene.grid.width = scene.grid.height = 1;
  scene.grid.pitch_m = 2 * half;
  scene.grid.min_m = probe.beam_centre_m - Eigen::Vector2d(half, half);
  ScatteringLayer layer;
  layer.uniform_tau = fit.tau;
  layer.g = fit.g;
  layer.albedo = albedo;
  scene.layer = layer;
  scene.laser_probe = probe;
  scene.source = fit_dir;
  scene.notes = notes;
  scene.notes.push_back("round trip of " + run.session_dir + ": the laser rig by reciprocity, each measured ring a " +
                        "Lambertian emitter in its own light group, an orthographic camera along the beam");

  const int samples = run.samples > 0 ? run.samples : kDefaultSamples;
  const Provenance provenance{"roundtrip", run.session_dir, fit_dir, run.options_ini};
  std::string scene_dir, prefix;
  THINSLAB_RETURN_IF_ERROR(WriteRoundTripScene(scene, out.path(), provenance, &scene_dir, &prefix));
  log << "roundtrip: rendering " << rings.size() << " rings of the lobe (" << kProbePixels << "x" << kProbePixels
      << " px along the beam) at " << samples << " samples, 2 passes, with " << run.blender
      << " (log: " << JoinPath(JoinPath(out_dir, "scene"), "blender.log") << ")\n";
  THINSLAB_RETURN_IF_ERROR(RenderBlenderPasses(run.blender, scene_dir, prefix, kLobePasses, samples,
                                               "roundtrip: Blender render", run.progress));
  std::vector<double> seed_1, seed_2;
  THINSLAB_RETURN_IF_ERROR(ReadProbeRings(prefix + "_lobe_1.exr", probe, &seed_1));
  THINSLAB_RETURN_IF_ERROR(ReadProbeRings(prefix + "_lobe_2.exr", probe, &seed_2));

  // One free scale for each model: the rendered rings' and Eq. 8's shapes are compared.
  const size_t n = rings.size();
  std::vector<double> measured(n), sigma(n), raw(n), model(n);
  for (size_t k = 0; k < n; ++k) {
    measured[k] = rings[k].intensity;
    sigma[k] = rings[k].sigma;
    raw[k] = 0.5 * (seed_1[k] + seed_2[k]);
    model[k] = rings[k].model;
  }
  const double render_scale = LeastSquaresScale(raw, measured);
  const double model_scale = LeastSquaresScale(model, measured);
  if (!(render_scale > 0)) {
    return Status::Error(JoinPath(JoinPath(out_dir, "scene"), "render_lobe_1.exr") +
                         ": Blender rendered no light on the rings (is the layer's tau > 0?)");
  }
  std::vector<double> rendered(n), render_sigma(n), predicted(n);
  for (size_t k = 0; k < n; ++k) {
    rendered[k] = render_scale * raw[k];
    render_sigma[k] = render_scale * 0.5 * std::abs(seed_1[k] - seed_2[k]);  // sd of the mean of 2 seeds.
    predicted[k] = model_scale * model[k];
  }
  // What the fit's own sigma_g allows: Eq. 8's shape at g +- sigma_g against that at g (each at
  // its best scale), per ring the larger difference.
  std::vector<double> sigma_g_shift(n, 0.0);
  for (double sign : {-1.0, 1.0}) {
    const double g = std::clamp(fit.g + sign * fit.sigma_g, -0.99, 0.99);
    std::vector<double> shifted(n);
    for (size_t k = 0; k < n; ++k) shifted[k] = LaserLobeProfile(std::cos(rings[k].theta_rad), g, fit.tau);
    const double s = LeastSquaresScale(shifted, predicted);
    for (size_t k = 0; k < n; ++k)
      sigma_g_shift[k] = std::max(sigma_g_shift[k], std::abs(s * shifted[k] - predicted[k]));
  }

  nlohmann::json bands = nlohmann::json::array();
  std::ostringstream txt;
  txt << "thinslab roundtrip: " << fit_dir << " (g " << fit.g << " +- " << fit.sigma_g << ", tau " << fit.tau
      << ", albedo " << albedo << ") rendered by Blender (Cycles, " << samples << " samples) under the laser rig of "
      << run.session_dir << ", against the capture's " << (fit.validation ? "validation" : "fitted")
      << " lobe and thinslab predict (Eq. 8), each at its best scale:\n";
  const double edges_deg[] = {0, 15, 30, 45, 60, 90};
  for (int b = 0; b <= 5; ++b) {
    const double lo = b < 5 ? edges_deg[b] : 0, hi = b < 5 ? edges_deg[b + 1] : 90;
    double m2 = 0, p2 = 0, rc = 0, pc = 0, rp = 0, noise = 0, render_noise = 0, shift = 0;
    int count = 0;
    for (size_t k = 0; k < n; ++k) {
      const double theta = rings[k].theta_rad * 180 / kPi;
      if (theta < lo || theta >= hi) continue;
      ++count;
      m2 += Sqr(measured[k]);
      p2 += Sqr(predicted[k]);
      rc += Sqr(rendered[k] - measured[k]);
      pc += Sqr(predicted[k] - measured[k]);
      rp += Sqr(rendered[k] - predicted[k]);
      noise += Sqr(sigma[k]);
      render_noise += Sqr(render_sigma[k]);
      shift += Sqr(sigma_g_shift[k]);
    }
    if (count == 0 || !(m2 > 0)) continue;
    const std::string name = b < 5 ? RoundTripFigure(lo, 0) + "-" + RoundTripFigure(hi, 0) + " deg" : "all";
    bands.push_back({{"band", name},
                     {"theta_min_deg", lo},
                     {"theta_max_deg", hi},
                     {"rings", count},
                     {"render_vs_capture_relative_rms", std::sqrt(rc / m2)},
                     {"predict_vs_capture_relative_rms", std::sqrt(pc / m2)},
                     {"render_vs_predict_relative_rms", std::sqrt(rp / p2)},
                     {"noise_relative_rms", std::sqrt(noise / m2)},
                     {"render_noise_relative_rms", std::sqrt(render_noise / m2)},
                     {"sigma_g_relative_rms", std::sqrt(shift / m2)}});
    txt << "  " << name << " (" << count << " rings): Blender vs capture " << RoundTripFigure(std::sqrt(rc / m2))
        << ", predict vs capture " << RoundTripFigure(std::sqrt(pc / m2)) << ", Blender vs predict "
        << RoundTripFigure(std::sqrt(rp / p2)) << " (noise: capture " << RoundTripFigure(std::sqrt(noise / m2))
        << ", render " << RoundTripFigure(std::sqrt(render_noise / m2)) << "; sigma_g "
        << RoundTripFigure(std::sqrt(shift / m2)) << ")\n";
  }

  std::ostringstream csv;
  csv << "r_m,theta_deg,measured_dn_per_us,sigma,rendered,render_sigma,predicted,ring_inner_m,ring_outer_m\n";
  csv.precision(9);
  for (size_t k = 0; k < n; ++k) {
    csv << rings[k].r_m << "," << rings[k].theta_rad * 180 / kPi << "," << measured[k] << "," << sigma[k] << ","
        << rendered[k] << "," << render_sigma[k] << "," << predicted[k] << "," << probe.ring_inner_m[k] << ","
        << probe.ring_outer_m[k] << "\n";
  }

  // Both profiles imaged in the capture's camera (the pixels between the core and the outermost
  // angle), with the measured lobe.
  Image render_camera, predict_camera;
  const LobeCameraError render_error = ImageLobeInCamera(
      images, prediction.geometry, [&](double r) { return InterpolateRings(rings, rendered, r); }, &render_camera);
  const LobeCameraError predict_error = ImageLobeInCamera(
      images, prediction.geometry,
      [&](double r) {
        return model_scale * prediction.scale * LaserLobeProfile(std::cos(std::atan(r / d)), fit.g, fit.tau);
      },
      &predict_camera);
  const int w = render_camera.width(), h = render_camera.height();
  Image camera_images(w, h, {"rendered", "predicted", "measured", "variance", "valid", "difference"});
  double white = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      if (render_camera.at(x, y, 3) == 0) continue;
      camera_images.at(x, y, 0) = render_camera.at(x, y, 0);
      camera_images.at(x, y, 1) = predict_camera.at(x, y, 0);
      camera_images.at(x, y, 2) = render_camera.at(x, y, 1);
      camera_images.at(x, y, 3) = render_camera.at(x, y, 2);
      camera_images.at(x, y, 4) = 1;
      camera_images.at(x, y, 5) = render_camera.at(x, y, 0) - render_camera.at(x, y, 1);
      white = std::max(white, static_cast<double>(render_camera.at(x, y, 1)));
    }
  }
  if (!(white > 0) || render_error.pixels == 0) {
    return Status::Error(manifest + ": no camera pixel sees the lobe between its core and the fit's outermost angle");
  }
  camera_images.attributes()["units"] = "DN/us in the capture's camera pixels (the HDR merge's radiance)";
  THINSLAB_RETURN_IF_ERROR(
      WriteMapExr(JoinPath(out.path(), "roundtrip.exr"), camera_images, {"rendered", {"valid"}}, provenance));
  THINSLAB_RETURN_IF_ERROR(WriteRoundTripPictures(out.path(), camera_images, {2, 0, 1, 5, 4}, white));
  txt << "  in the camera's pixels (" << render_error.pixels << " px): Blender vs capture "
      << RoundTripFigure(render_error.relative_rms) << ", predict vs capture "
      << RoundTripFigure(predict_error.relative_rms) << " (noise " << RoundTripFigure(render_error.noise_relative_rms)
      << ")\n";

  nlohmann::json j = RoundTripSummaryHead("laser_lobe", provenance, run.session_dir, fit_dir, samples);
  j["probe"] = {{"image_px", probe.image_px},
                {"view_size_m", probe.view_size_m},
                {"beam_radius_m", probe.beam_radius_m},
                {"beam_centre_m", {probe.beam_centre_m.x(), probe.beam_centre_m.y()}},
                {"rings", n}};
  j["board_distance_m"] = d;
  j["layer"] = {{"g", fit.g}, {"sigma_g", fit.sigma_g}, {"tau", fit.tau}, {"albedo", albedo}};
  j["render_scale"] = render_scale;
  j["predict_scale_ratio"] = model_scale;
  j["measured_frames"] = fit.validation ? "validation" : "fitted";
  j["bands"] = bands;
  j["camera"] = {{"pixels", render_error.pixels},
                 {"render_vs_capture_relative_rms", render_error.relative_rms},
                 {"predict_vs_capture_relative_rms", predict_error.relative_rms},
                 {"noise_relative_rms", render_error.noise_relative_rms}};
  j["notes"] = scene.notes;
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "lobe_rings.csv"), csv.str()));
  return FinishRoundTrip(&out, j, txt.str(), run.options_ini, log);
}

}  // namespace thinslab
