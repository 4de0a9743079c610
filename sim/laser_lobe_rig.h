// SPDX-License-Identifier: Apache-2.0
// The simulated laser-lobe rig (Gu et al. 2007, Fig. 9b): a collimated beam of radius r_b at
// normal incidence crosses a uniform contaminant layer (tau, g, albedo) and lands on a
// Lambertian board at distance d; the camera views the board obliquely through the sensor
// model. The lobe comes from Monte Carlo transport through the layer with all scattering
// orders (sim/layer_monte_carlo.h), spread over the beam's area: not from Gu Eq. 8, which
// assumes single scattering and a point beam. Also renders the clean glass (the spike only)
// and a flat field of the board.
#pragma once

#include <memory>
#include <string>

#include "thinslab/acquire/laser_lobe_session.h"
#include "thinslab/core/image.h"
#include "thinslab/core/progress.h"
#include "thinslab/core/session.h"
#include "thinslab/sim/layer_monte_carlo.h"
#include "thinslab/sim/sim_board_camera.h"
#include "thinslab/sim/sim_flat_projector.h"

namespace thinslab {

struct SimLaserLobeOptions {
  double layer_tau = 0.3;          // Optical thickness of the uniform layer (unitless).
  double layer_albedo = 0.3;       // Single-scattering albedo omega0.
  double layer_g = 0.8;            // HG g.
  double board_distance_m = 0.02;  // Layer-to-board distance d.
  double beam_radius_m = 0.5e-3;  // 1/e^2 intensity radius of the Gaussian beam.
  Eigen::Vector2d beam_offset_m = Eigen::Vector2d::Zero();  // Beam axis off the board centre.
  double board_albedo = 0.8;
  double board_half_width_m = 0.035;  // Imaged board region: +-half width around the axis.
  double pixel_pitch_m = 0.2e-3;
  int camera_width_px = 1600;
  int camera_height_px = 1200;
  double camera_distance_m = 0.3;
  double camera_tilt_deg = 35;
  double fill_fraction = 0.9;
  double vignetting = 0.15;
  int render_supersample = 2;
  // The unscattered spike's peak at the shortest exposure of the bracket fills this fraction of full
  // well (so longer exposures saturate it).
  double spike_fill = 0.5;
  double shortest_exposure_us = 20;
  // The flat field fills this fraction of full well at 1000x the shortest exposure.
  double flat_fill = 0.5;
  LayerMonteCarloOptions monte_carlo;
  SimSensorOptions sensor;
  uint64_t seed = 1;

  bool Check(std::string* error) const;
};

class SimLaserLobeRig {
 public:
  static Status Create(const SimLaserLobeOptions& options, std::unique_ptr<SimLaserLobeRig>* rig);
  ~SimLaserLobeRig();

  Camera* camera();
  Laser* laser();
  Projector* flat_source();
  SampleChanger sample_changer();
  const RigInfo& rig_info() const { return rig_; }
  // Board irradiance relative to the beam's unscattered irradiance at the current state.
  double BoardIrradiance(double x_m, double y_m) const;

 private:
  class LaserImpl;
  SimLaserLobeRig() = default;

  SimLaserLobeOptions options_;
  RigInfo rig_;
  Eigen::Vector2d grid_min_m_;
  Image scattered_;  // Scattered irradiance of the contaminated layer on the board grid.
  double flat_irradiance_ = 0;
  std::string sample_state_ = "none";
  bool laser_on_ = false;
  bool flat_on_ = false;
  std::unique_ptr<SimBoardCamera> camera_;
  std::unique_ptr<LaserImpl> laser_;
  std::unique_ptr<SimFlatProjector> flat_;
};

struct SyntheticLaserSessionOptions {
  SimLaserLobeOptions rig;
  LaserLobeSessionOptions session;
  std::string name = "sim_laser_lobe";
  // Reports the frames rendered of those planned; returning false cancels (core/progress.h).
  ProgressCallback progress;
};

// Runs the unchanged acquisition script on the simulated rig into a new session folder and
// writes ground_truth/truth.json (tau, g, albedo, beam centre).
Status SynthesizeLaserLobeSession(const SyntheticLaserSessionOptions& options, const std::string& session_dir);

}  // namespace thinslab
