// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/shadow_map_rig.h"

#include <algorithm>
#include <cmath>
#include <sstream>

#include "thinslab/acquire/session_writer.h"
#include "thinslab/core/math.h"
#include "thinslab/core/memory.h"
#include "thinslab/sim/sensor_model.h"
#include "thinslab/optics/dirty_glass.h"
#include "thinslab/optics/shadow_map_model.h"

namespace thinslab {

bool SimShadowMapOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(board_distance_m > 0 && board_distance_m <= kMaxBoardDistanceM)) {
    msg << "SimShadowMapOptions::board_distance_m = " << board_distance_m << ". Violated constraint: (0, "
        << kMaxBoardDistanceM << "] m (--board-distance-mm)";
  } else if (!(layer_albedo >= 0 && layer_albedo <= 1)) {
    msg << "SimShadowMapOptions::layer_albedo = " << layer_albedo << ". Violated constraint: [0, 1]";
  } else if (!(layer_g > -1 && layer_g < 1)) {
    msg << "SimShadowMapOptions::layer_g = " << layer_g << ". Violated constraint: (-1, 1)";
  } else if (!(pixel_pitch_m > 0)) {
    msg << "SimShadowMapOptions::pixel_pitch_m = " << pixel_pitch_m << ". Violated constraint: > 0";
  } else if (!(projector_falloff >= 0 && projector_falloff < 1)) {
    msg << "SimShadowMapOptions::projector_falloff = " << projector_falloff << ". Violated constraint: [0, 1)";
  } else if (const Status memory = CheckMemoryNeed(SimCameraMemoryBytes(std::max(camera_width_px, 0), std::max(camera_height_px, 0)),
                                                   "--camera-width-px/--camera-height-px: the simulated camera");
             !memory.ok()) {
    msg << memory.message();
  } else if (camera_width_px < 16 || camera_height_px < 16 || camera_width_px > kMaxSimCameraSidePx ||
             camera_height_px > kMaxSimCameraSidePx) {
    msg << "SimShadowMapOptions::camera_width_px/camera_height_px = " << camera_width_px << "x"
        << camera_height_px << ". Violated constraint: 16.." << kMaxSimCameraSidePx;
  } else if (monte_carlo.num_photons < 1) {
    msg << "SimShadowMapOptions::monte_carlo.num_photons = " << monte_carlo.num_photons
        << ". Violated constraint: >= 1 (--photons)";
  } else if (!(camera_tilt_deg >= 0 && camera_tilt_deg < 80)) {
    msg << "SimShadowMapOptions::camera_tilt_deg = " << camera_tilt_deg << ". Violated constraint: [0, 80)";
  } else if (!(reference_fill > 0 && reference_fill <= 2)) {
    msg << "SimShadowMapOptions::reference_fill = " << reference_fill << ". Violated constraint: (0, 2]";
  } else if (render_supersample < 1) {
    msg << "SimShadowMapOptions::render_supersample = " << render_supersample << ". Violated constraint: >= 1";
  } else if (!sensor.Check(error)) {
    return false;
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

Status SimShadowMapRig::Create(const SimShadowMapOptions& options, const Image& tau,
                               std::unique_ptr<SimShadowMapRig>* out) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  if (tau.empty() || tau.num_channels() != 1) {
    return Status::Error("SimShadowMapRig: tau texture must be a non-empty single-channel image");
  }
  float max_tau = 0;
  for (float v : tau.data()) {
    if (!std::isfinite(v) || v < 0) {
      return Status::Error("SimShadowMapRig: tau texture has a negative or non-finite value");
    }
    max_tau = std::max(max_tau, v);
  }
  std::unique_ptr<SimShadowMapRig> rig(new SimShadowMapRig());
  rig->options_ = options;
  const double p = options.pixel_pitch_m;
  const int m = options.margin_px;
  const Eigen::Vector2d half(tau.width() * p / 2, tau.height() * p / 2);
  rig->grid_min_m_ = -half - Eigen::Vector2d(m * p, m * p);
  const int gw = tau.width() + 2 * m, gh = tau.height() + 2 * m;

  // Incident irradiance E0 (projector falloff) and the padded layer.
  Image tau_grid(gw, gh), e0(gw, gh);
  const double r_corner = half.norm();
  for (int y = 0; y < gh; ++y) {
    for (int x = 0; x < gw; ++x) {
      const double sx = rig->grid_min_m_.x() + (x + 0.5) * p, sy = rig->grid_min_m_.y() + (y + 0.5) * p;
      e0.at(x, y) = static_cast<float>(1.0 - options.projector_falloff * (Sqr(sx) + Sqr(sy)) / Sqr(r_corner));
      const int tx = x - m, ty = y - m;
      if (tx >= 0 && ty >= 0 && tx < tau.width() && ty < tau.height()) tau_grid.at(x, y) = tau.at(tx, ty);
    }
  }

  // Exit lobes per tau node: Gu Eq. 6 is exact for the first scattering order of this
  // geometry; Monte Carlo adds all higher orders. Nodes at half the fit's spacing.
  std::vector<double> nodes;
  for (double t : ScatterKernelBank::DefaultNodes(0.5)) {
    nodes.push_back(t);
    if (t >= max_tau) break;
  }
  if (nodes.size() < 2) nodes.push_back(nodes.back() + 0.05);
  std::vector<LayerExitDistribution> multiple(nodes.size());
  for (size_t j = 0; j < nodes.size(); ++j) {
    LayerMonteCarloOptions mc = options.monte_carlo;
    mc.albedo = options.layer_albedo;
    mc.g = options.layer_g;
    mc.seed = options.seed * 7 + j;
    multiple[j] = SimulateLayer(nodes[j], mc);
  }
  const double albedo = options.layer_albedo, g = options.layer_g;
  auto radiance_per_tau = [&](double t, double mu) {
    size_t j = 0;
    while (j < nodes.size() && std::abs(nodes[j] - t) > 1e-9) ++j;
    CHECK_LT(j, nodes.size());
    if (t < 1e-9) return albedo * HenyeyGreenstein(mu, g) / mu;  // Limit of Eq. 6 / tau.
    return (LayerSingleScatterRadiance(t, mu, albedo, g) + multiple[j].MultipleAt(mu)) / t;
  };
  BoardGeometry geometry;
  geometry.distance_m = options.board_distance_m;
  geometry.pixel_pitch_m = p;
  geometry.max_angle_deg = 85;
  geometry.max_radius_px = static_cast<int>(std::ceil(std::hypot(gw, gh)));
  const ScatterKernelBank bank(nodes, radiance_per_tau, geometry);
  const Image scattered = bank.Scattered(e0, tau_grid);

  rig->e0_ = e0;
  rig->board_clean_ = e0;
  rig->board_direct_ = Image(gw, gh);
  for (int y = 0; y < gh; ++y) {
    for (int x = 0; x < gw; ++x) {
      rig->board_direct_.at(x, y) = e0.at(x, y) * std::exp(-tau_grid.at(x, y));  // Gu Eq. 5.
    }
  }
  rig->board_scattered_ = scattered;

  // Camera geometry.
  SimBoardCameraOptions cam_options;
  cam_options.info = MakeObliqueBoardCamera(options.camera_width_px, options.camera_height_px,
                                            Eigen::Vector3d(0, 0, -options.board_distance_m),
                                            options.camera_distance_m, options.camera_tilt_deg, gw * p,
                                            options.fill_fraction);
  cam_options.info.serial = "sim-shadow-0";
  cam_options.board_z_m = -options.board_distance_m;
  cam_options.board_albedo = options.board_albedo;
  cam_options.vignetting = options.vignetting;
  cam_options.render_supersample = options.render_supersample;
  // The clean board at the image centre fills reference_fill of the full well at the nominal
  // exposure.
  cam_options.electrons_per_radiance_us = options.reference_fill * options.sensor.full_well_e /
                                          (options.board_albedo / kPi) / options.exposure_time_us;
  cam_options.initial_exposure_us = options.exposure_time_us;
  cam_options.sensor = options.sensor;
  cam_options.seed = options.seed;
  SimShadowMapRig* raw = rig.get();
  rig->camera_.reset(new SimBoardCamera(cam_options, [raw](double x, double y) {
    return raw->projector_on_ ? raw->BoardIrradiance(raw->sample_state_, x, y) : 0.0;
  }));
  const CameraInfo& cam = rig->camera_->info();
  rig->rig_.cameras = {cam};
  rig->rig_.sample.region_min_m = -half;
  rig->rig_.sample.region_max_m = half;
  rig->rig_.sample.pixel_pitch_m = p;
  rig->rig_.sample.glass_thickness_m = 3e-3;
  rig->rig_.sample.glass_ior = 1.52;
  rig->rig_.sample.contaminant_side = "board";
  rig->rig_.board.present = true;
  rig->rig_.board.distance_m = options.board_distance_m;
  rig->rig_.board.albedo = options.board_albedo;
  rig->rig_.projector.present = true;
  rig->rig_.projector.kind = "collimated";
  rig->rig_.projector.direction_in_sample = Eigen::Vector3d(0, 0, -1);

  rig->projector_.reset(new SimFlatProjector("projector", [raw](bool on) { raw->projector_on_ = on; }));
  *out = std::move(rig);
  return Status::Ok();
}

SimShadowMapRig::~SimShadowMapRig() = default;
Camera* SimShadowMapRig::camera() { return camera_.get(); }
Projector* SimShadowMapRig::projector() { return projector_.get(); }

SampleChanger SimShadowMapRig::sample_changer() {
  return [this](const std::string& state) {
    if (state != "clean" && state != "contaminated") {
      return Status::Error("sample stage (sim): unknown sample state '" + state + "'");
    }
    sample_state_ = state;
    return Status::Ok();
  };
}

double SimShadowMapRig::BoardIrradiance(const std::string& sample_state, double x_m, double y_m) const {
  const double p = options_.pixel_pitch_m;
  const double gx = (x_m - grid_min_m_.x()) / p, gy = (y_m - grid_min_m_.y()) / p;
  if (gx < 0 || gy < 0 || gx >= board_clean_.width() || gy >= board_clean_.height()) {
    // Outside the grid the pane is clean: the projector's falloff alone.
    const double r_region = std::hypot(rig_.sample.region_max_m.x(), rig_.sample.region_max_m.y());
    return 1.0 - options_.projector_falloff * (Sqr(x_m) + Sqr(y_m)) / Sqr(r_region);
  }
  if (sample_state != "contaminated") return board_clean_.Bilinear(gx, gy);
  // Unscattered light keeps the texel's sharp edges; scattered light is smooth.
  return board_direct_.at(static_cast<int>(gx), static_cast<int>(gy)) + board_scattered_.Bilinear(gx, gy);
}

}  // namespace thinslab
