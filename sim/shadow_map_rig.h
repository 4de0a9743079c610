// SPDX-License-Identifier: Apache-2.0
// The simulated shadow-map rig (Gu et al. 2007, Fig. 9a): collimated projector with spatial
// falloff -> glass pane with a contaminant layer tau(x, y) on its far side -> Lambertian
// board at distance D -> camera viewing the board obliquely (pinhole, vignetting) -> sensor.
// Board irradiance = reduced light (Gu Eq. 5) + light scattered by every layer point, whose
// angular distribution comes from Monte Carlo through the layer with all scattering orders
// (sim/layer_monte_carlo.h): more complete than the single-scattering model fits use.
// The rig implements the driver interfaces, so acquire/ runs unchanged on it.
#pragma once

#include <memory>
#include <string>

#include "thinslab/acquire/shadow_map_session.h"
#include "thinslab/core/image.h"
#include "thinslab/core/session.h"
#include "thinslab/drivers/camera.h"
#include "thinslab/drivers/display.h"
#include "thinslab/sim/layer_monte_carlo.h"
#include "thinslab/sim/sensor_model.h"
#include "thinslab/sim/sim_board_camera.h"
#include "thinslab/sim/sim_flat_projector.h"

namespace thinslab {

struct SimShadowMapOptions {
  double board_distance_m = 1e-3;  // Layer-to-board distance D.
  double layer_albedo = 0.3;       // Single-scattering albedo omega0 of the contaminant.
  double layer_g = 0.8;            // HG g of the contaminant.
  double board_albedo = 0.8;
  double pixel_pitch_m = 80e-6;    // Pitch of the tau texture on the sample.
  // Projector falloff: E0 = 1 - falloff * (r / r_corner)^2 over the region.
  double projector_falloff = 0.2;
  // Camera: looks at the board centre from camera_distance_m, tilted by camera_tilt_deg from
  // the board normal about the sample x axis; focal length chosen so the region plus margin
  // fills fill_fraction of the image width.
  int camera_width_px = 1600;
  int camera_height_px = 1200;
  double camera_distance_m = 0.12;
  double camera_tilt_deg = 35;
  double fill_fraction = 0.9;
  double vignetting = 0.15;  // Relative loss at the image corner, on top of cos^4.
  int render_supersample = 3;
  double exposure_time_us = 20000;
  // Reference (clean) board radiance at the image centre fills this fraction of full well.
  double reference_fill = 0.75;
  int margin_px = 12;  // Board grid margin around the region (texture pitch).
  LayerMonteCarloOptions monte_carlo;
  SimSensorOptions sensor;
  uint64_t seed = 1;

  bool Check(std::string* error) const;
};

class SimShadowMapRig {
 public:
  // `tau` is the contaminant texture over the region centred on the origin, at pixel_pitch_m.
  static Status Create(const SimShadowMapOptions& options, const Image& tau,
                       std::unique_ptr<SimShadowMapRig>* rig);

  ~SimShadowMapRig();
  Camera* camera();
  Projector* projector();
  SampleChanger sample_changer();
  // Rig description for the manifest.
  const RigInfo& rig_info() const { return rig_; }
  // Noise-free board irradiance (relative to the projector peak) at a board point (sample
  // frame x, y) for a sample state.
  double BoardIrradiance(const std::string& sample_state, double x_m, double y_m) const;

 private:
  SimShadowMapRig() = default;

  SimShadowMapOptions options_;
  RigInfo rig_;
  Eigen::Vector2d grid_min_m_;
  // Board irradiance split into the unscattered part (piecewise constant per texel: the
  // texture's value is the layer over the texel's whole area) and the smooth scattered part.
  Image e0_, board_clean_, board_direct_, board_scattered_;
  std::string sample_state_ = "clean";
  bool projector_on_ = false;
  std::unique_ptr<SimBoardCamera> camera_;
  std::unique_ptr<SimFlatProjector> projector_;
};

}  // namespace thinslab
