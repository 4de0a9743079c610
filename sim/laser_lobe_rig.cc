// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/laser_lobe_rig.h"

#include <nlohmann/json.hpp>

#include <cmath>
#include <sstream>

#include "thinslab/acquire/session_writer.h"
#include "thinslab/core/file.h"
#include "thinslab/sim/sim_session.h"
#include "thinslab/core/math.h"
#include "thinslab/core/memory.h"
#include "thinslab/sim/sensor_model.h"
#include "thinslab/optics/dirty_glass.h"
#include "thinslab/optics/shadow_map_model.h"

namespace thinslab {

bool SimLaserLobeOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(layer_tau >= 0)) {
    msg << "SimLaserLobeOptions::layer_tau = " << layer_tau << ". Violated constraint: >= 0";
  } else if (!(layer_albedo >= 0 && layer_albedo <= 1)) {
    msg << "SimLaserLobeOptions::layer_albedo = " << layer_albedo << ". Violated constraint: [0, 1]";
  } else if (!(layer_g > -1 && layer_g < 1)) {
    msg << "SimLaserLobeOptions::layer_g = " << layer_g << ". Violated constraint: (-1, 1)";
  } else if (!(board_distance_m > 0 && board_distance_m <= kMaxBoardDistanceM)) {
    msg << "SimLaserLobeOptions::board_distance_m = " << board_distance_m << ". Violated constraint: (0, "
        << kMaxBoardDistanceM << "] m (--board-distance-mm)";
  } else if (!(beam_radius_m > 0)) {
    msg << "SimLaserLobeOptions::beam_radius_m = " << beam_radius_m << ". Violated constraint: > 0";
  } else if (monte_carlo.num_photons < 1) {
    msg << "SimLaserLobeOptions::monte_carlo.num_photons = " << monte_carlo.num_photons
        << ". Violated constraint: >= 1 (--photons)";
  } else if (const Status memory = CheckMemoryNeed(SimCameraMemoryBytes(std::max(camera_width_px, 0), std::max(camera_height_px, 0)),
                                                   "--camera-width-px/--camera-height-px: the simulated camera");
             !memory.ok()) {
    msg << memory.message();
  } else if (camera_width_px < 16 || camera_height_px < 16 || camera_width_px > kMaxSimCameraSidePx ||
             camera_height_px > kMaxSimCameraSidePx) {
    msg << "SimLaserLobeOptions::camera_width_px/camera_height_px = " << camera_width_px << "x" << camera_height_px
        << ". Violated constraint: 16.." << kMaxSimCameraSidePx << " (--camera-width-px, --camera-height-px)";
  } else if (!(pixel_pitch_m > 0 && board_half_width_m > 10 * pixel_pitch_m)) {
    msg << "SimLaserLobeOptions::board_half_width_m = " << board_half_width_m << ", pixel_pitch_m = "
        << pixel_pitch_m << ". Violated constraint: pitch > 0 and half width > 10 pitches";
  } else if (!(beam_offset_m.cwiseAbs().maxCoeff() < 0.5 * board_half_width_m)) {
    msg << "SimLaserLobeOptions::beam_offset_m exceeds half of board_half_width_m";
  } else if (!(spike_fill > 0) || !(flat_fill > 0) || !(shortest_exposure_us > 0)) {
    msg << "SimLaserLobeOptions::spike_fill, flat_fill, shortest_exposure_us must be > 0";
  } else if (!sensor.Check(error)) {
    return false;
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

class SimLaserLobeRig::LaserImpl : public Laser {
 public:
  explicit LaserImpl(SimLaserLobeRig* rig) : rig_(rig) {}
  Status SetEmission(bool on) override {
    rig_->laser_on_ = on;
    return Status::Ok();
  }

 private:
  SimLaserLobeRig* rig_;
};

SimLaserLobeRig::~SimLaserLobeRig() = default;
Camera* SimLaserLobeRig::camera() { return camera_.get(); }
Laser* SimLaserLobeRig::laser() { return laser_.get(); }
Projector* SimLaserLobeRig::flat_source() { return flat_.get(); }

SampleChanger SimLaserLobeRig::sample_changer() {
  return [this](const std::string& state) {
    if (state != "clean" && state != "contaminated" && state != "none") {
      return Status::Error("sample stage (sim): unknown sample state '" + state + "'");
    }
    sample_state_ = state;
    return Status::Ok();
  };
}

namespace {

// Irradiance of a Gaussian beam of 1/e^2 radius w at squared distance r2 from its axis,
// 2 exp(-2 r^2 / w^2): the power pi w^2 of a uniform disc of radius w at irradiance 1, so the lobe
// keeps the brightness the earlier disc beam gave it.
double GaussianBeam(double r2, double w) { return 2 * std::exp(-2 * r2 / (w * w)); }

}  // namespace

double SimLaserLobeRig::BoardIrradiance(double x_m, double y_m) const {
  double e = flat_on_ ? flat_irradiance_ : 0.0;
  if (!laser_on_ || sample_state_ == "none") return e;
  const bool contaminated = sample_state_ == "contaminated";
  // Unscattered beam (Gu Eq. 5): a Gaussian beam whose 1/e^2 intensity radius is beam_radius_m
  // (as rig.laser.beam_radius_m is documented, docs/format.md).
  const Eigen::Vector2d d = Eigen::Vector2d(x_m, y_m) - options_.beam_offset_m;
  e += (contaminated ? std::exp(-options_.layer_tau) : 1.0) * GaussianBeam(d.squaredNorm(), options_.beam_radius_m);
  if (contaminated) {
    const double gx = (x_m - grid_min_m_.x()) / options_.pixel_pitch_m;
    const double gy = (y_m - grid_min_m_.y()) / options_.pixel_pitch_m;
    if (gx >= 0 && gy >= 0 && gx < scattered_.width() && gy < scattered_.height()) e += scattered_.Bilinear(gx, gy);
  }
  return e;
}

Status SimLaserLobeRig::Create(const SimLaserLobeOptions& options, std::unique_ptr<SimLaserLobeRig>* out) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  std::unique_ptr<SimLaserLobeRig> rig(new SimLaserLobeRig());
  rig->options_ = options;
  const double p = options.pixel_pitch_m;
  // The simulation grid extends 20 % beyond the imaged region so the camera's margin sees
  // scattered light too.
  const int half_px = static_cast<int>(std::ceil(1.2 * options.board_half_width_m / p));
  const int n = 2 * half_px + 1;
  rig->grid_min_m_ = Eigen::Vector2d(-(half_px + 0.5) * p, -(half_px + 0.5) * p);

  // Beam footprint: the beam's mean irradiance over each grid pixel (8 x 8 sub-samples).
  Image beam(n, n);
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      double sum = 0;
      for (int a = 0; a < 8; ++a) {
        for (int b = 0; b < 8; ++b) {
          const Eigen::Vector2d q(rig->grid_min_m_.x() + (x + (b + 0.5) / 8) * p,
                                  rig->grid_min_m_.y() + (y + (a + 0.5) / 8) * p);
          sum += GaussianBeam((q - options.beam_offset_m).squaredNorm(), options.beam_radius_m);
        }
      }
      beam.at(x, y) = static_cast<float>(sum / 64);
    }
  }
  // Exit lobe of the layer: Gu Eq. 6 (exact for the first order here) + Monte Carlo for all
  // higher orders, spread over the board by the pixel-integrated kernel, summed over the beam.
  LayerMonteCarloOptions mc = options.monte_carlo;
  mc.albedo = options.layer_albedo;
  mc.g = options.layer_g;
  mc.seed = options.seed * 13 + 5;
  const LayerExitDistribution multiple = SimulateLayer(options.layer_tau, mc);
  BoardGeometry geometry;
  geometry.distance_m = options.board_distance_m;
  geometry.pixel_pitch_m = p;
  geometry.max_angle_deg = 85;
  geometry.max_radius_px = static_cast<int>(std::ceil(std::sqrt(2.0) * n));
  const double tau = options.layer_tau, albedo = options.layer_albedo, g = options.layer_g;
  const Image kernel = BuildBoardKernel(
      [&](double mu) { return LayerSingleScatterRadiance(tau, mu, albedo, g) + multiple.MultipleAt(mu); }, geometry);
  rig->scattered_ = tau > 0 ? ConvolveZeroPadded(beam, kernel) : Image(n, n);

  SimBoardCameraOptions cam_options;
  cam_options.info = MakeObliqueBoardCamera(options.camera_width_px, options.camera_height_px,
                                            Eigen::Vector3d(0, 0, -options.board_distance_m),
                                            options.camera_distance_m, options.camera_tilt_deg,
                                            2 * options.board_half_width_m, options.fill_fraction);
  cam_options.info.serial = "sim-laser-0";
  cam_options.board_z_m = -options.board_distance_m;
  cam_options.board_albedo = options.board_albedo;
  cam_options.vignetting = options.vignetting;
  cam_options.render_supersample = options.render_supersample;
  // The unscattered clean beam's peak (irradiance 2, GaussianBeam) fills spike_fill at the
  // shortest exposure.
  cam_options.electrons_per_radiance_us = options.spike_fill * options.sensor.full_well_e /
                                          (2 * options.board_albedo / kPi) / options.shortest_exposure_us;
  cam_options.initial_exposure_us = options.shortest_exposure_us;
  cam_options.sensor = options.sensor;
  cam_options.seed = options.seed;
  rig->flat_irradiance_ = 2 * options.flat_fill / options.spike_fill / 1000.0;
  SimLaserLobeRig* raw = rig.get();
  rig->camera_.reset(new SimBoardCamera(cam_options, [raw](double x, double y) { return raw->BoardIrradiance(x, y); }));
  rig->laser_.reset(new LaserImpl(raw));
  rig->flat_.reset(new SimFlatProjector("flat-field source", [raw](bool on) { raw->flat_on_ = on; }));

  rig->rig_.cameras = {rig->camera_->info()};
  rig->rig_.sample.region_min_m = Eigen::Vector2d(-options.board_half_width_m, -options.board_half_width_m);
  rig->rig_.sample.region_max_m = Eigen::Vector2d(options.board_half_width_m, options.board_half_width_m);
  rig->rig_.sample.pixel_pitch_m = p;
  rig->rig_.sample.glass_thickness_m = 3e-3;
  rig->rig_.sample.glass_ior = 1.52;
  rig->rig_.sample.contaminant_side = "board";
  rig->rig_.board.present = true;
  rig->rig_.board.distance_m = options.board_distance_m;
  rig->rig_.board.albedo = options.board_albedo;
  rig->rig_.laser.present = true;
  rig->rig_.laser.origin_in_sample = Eigen::Vector3d(options.beam_offset_m.x(), options.beam_offset_m.y(), 0.5);
  rig->rig_.laser.direction_in_sample = Eigen::Vector3d(0, 0, -1);
  rig->rig_.laser.beam_radius_m = options.beam_radius_m;
  rig->rig_.laser.wavelength_m = 532e-9;
  *out = std::move(rig);
  return Status::Ok();
}

Status SynthesizeLaserLobeSession(const SyntheticLaserSessionOptions& options, const std::string& session_dir) {
  std::unique_ptr<SimLaserLobeRig> rig;
  THINSLAB_RETURN_IF_ERROR(SimLaserLobeRig::Create(options.rig, &rig));
  SessionWriter writer;
  THINSLAB_RETURN_IF_ERROR(OpenSimulatedSession(session_dir, options.name, "laser_lobe", rig->rig_info(), &writer));
  LaserLobeSessionOptions session = options.session;
  session.sync = SyncForSensor(session.sync, options.rig.sensor);
  THINSLAB_RETURN_IF_ERROR(RunReportedSimulation(
      "sim laser: frames rendered",
      static_cast<int64_t>(PlanLaserLobeSession(session, rig->flat_source()->refresh_period_s()).size()),
      options.progress, session_dir, &writer, [&]() {
        return RunLaserLobeSession(session, rig->camera(), rig->laser(), rig->flat_source(), rig->sample_changer(),
                                   &writer);
      }));
  const std::string truth_dir = JoinPath(session_dir, "ground_truth");
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(truth_dir));
  nlohmann::json j;
  j["layer_tau"] = options.rig.layer_tau;
  j["layer_albedo"] = options.rig.layer_albedo;
  j["layer_g"] = options.rig.layer_g;
  j["board_distance_m"] = options.rig.board_distance_m;
  j["beam_radius_m"] = options.rig.beam_radius_m;
  j["beam_centre_m"] = {options.rig.beam_offset_m.x(), options.rig.beam_offset_m.y()};
  j["seed"] = options.rig.seed;
  return WriteFileAtomically(JoinPath(truth_dir, "truth.json"), j.dump(2) + "\n");
}

}  // namespace thinslab
