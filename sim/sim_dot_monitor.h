// SPDX-License-Identifier: Apache-2.0
// A simulated CRT/monitor dot rig (Dai et al. 2009, Section 4.1): a monitor plane parallel to
// the sample at distance d behind it (z = -d in the sample frame, screen facing +z), seen
// directly (no sample in the path) by a camera about 1 m away and ~45 degrees from the sample
// normal. The monitor shows dots on black; the camera renders them with perspective, Brown-
// Conrady distortion, n x n supersampling per camera pixel (area integration), a Gaussian lens
// blur and the sensor model (shot/read noise, quantisation, saturation).
//
// The monitor implements Projector (pattern ids as drivers/pattern_id.h: "" black, "flat",
// "dot:<x_px>,<y_px>", "dots:<x0>,<y0>,<dx>,<dy>,<nx>,<ny>", monitor pixel centres at +0.5) and
// owns a Camera that sees it, so `thinslab acquire dot-scan --camera sim` drives both through the
// ordinary device interfaces. Ground truth (3D dot positions in the sample frame, dot radiance)
// is exposed for tests.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "core/image.h"
#include "core/session.h"
#include "drivers/camera.h"
#include "drivers/display.h"
#include "sim/sensor_model.h"

namespace thinslab {

struct SimDotMonitorOptions {
  // Monitor (MonitorInfo): pixel grid and its placement.
  int monitor_width_px = 400;
  int monitor_height_px = 400;
  double monitor_pixel_pitch_m = 0.25e-3;
  double monitor_distance_m = 0.04;  // d: the screen is the plane z = -d of the sample frame.
  // Sample-frame (x, y) of the screen centre. Dai et al. shift the dot range away from the camera
  // by about d tan(theta); the default camera sits on the -y side, so the default shift is +y.
  Eigen::Vector2d monitor_center_in_sample_m = Eigen::Vector2d(0, 0.04);
  double monitor_rotation_deg = 0;  // In-plane rotation of the screen about the sample z axis.
  double dot_radius_px = 2.0;       // Radius of a displayed dot, monitor pixels.
  double dot_radiance = 1.0;        // Emitted radiance of a lit pixel ("relative radiance" units).
  double black_radiance = 0.0;      // CRT black level (radiance of an unlit pixel).
  double refresh_period_s = 1.0 / 85;

  // Camera: looks at `camera_target_in_sample` from `camera_distance_m`, tilted `camera_tilt_deg`
  // from the sample normal towards -y; the image width spans `camera_view_width_m` at the target.
  int camera_width_px = 800;
  int camera_height_px = 600;
  double camera_distance_m = 1.0;
  double camera_tilt_deg = 45;
  Eigen::Vector3d camera_target_in_sample = Eigen::Vector3d(0, 0, 0);
  double camera_view_width_m = 0.14;
  std::vector<double> camera_distortion = {-0.05, 0.02, 0, 0, 0};  // OpenCV k1, k2, p1, p2, k3.
  double blur_sigma_px = 0.5;  // Gaussian optical blur, camera pixels (0 = none).
  int render_supersample = 4;  // n x n sub-samples per camera pixel.
  // Expected photo-electrons per microsecond for a camera pixel fully covered by a surface of
  // radiance 1 (no vignetting in this rig: the camera's flat field is a radiometric concern).
  double electrons_per_radiance_us = 20;
  double initial_exposure_us = 1000;
  SimSensorOptions sensor;
  uint64_t seed = 1;

  // Errors name the field and the constraint.
  Status Check() const;
};

class SimDotMonitor : public Projector {
 public:
  // Validates `options` (Check()) and builds the rig.
  static Status Create(const SimDotMonitorOptions& options, std::unique_ptr<SimDotMonitor>* out);

  // Projector: any id ParsePatternId accepts ("" black, "flat", "flat:<level>", "dot:<x>,<y>",
  // "dots:..."), rasterised by RasterizePattern; a pixel at level l emits
  // black_radiance + l * dot_radiance. Unknown ids give an error naming the id.
  Status ShowPattern(const std::string& pattern) override;
  double refresh_period_s() const override { return options_.refresh_period_s; }

  // The camera that sees the monitor (owned by this object, valid for its lifetime).
  Camera* camera();

  // Geometry as it would be recorded in a manifest: the true camera (intrinsics, distortion,
  // cam_from_sample) and monitor (sample_from_monitor, pitch, size).
  const CameraInfo& camera_info() const;
  const MonitorInfo& monitor_info() const { return monitor_; }
  RigInfo rig() const;

  // Ground truth: sample-frame position of monitor pixel coordinate `dot_px` (centres at +0.5).
  Eigen::Vector3d DotInSample(const Eigen::Vector2d& dot_px) const;
  // Dots of the pattern currently shown (monitor px; empty for black or flat).
  const std::vector<Eigen::Vector2d>& shown_dots() const { return shown_dots_; }
  const std::string& shown_pattern() const { return shown_pattern_; }
  const SimDotMonitorOptions& options() const { return options_; }

  // Noise-free expected electrons for the shown pattern at the camera's current exposure.
  Image RenderElectrons() const;

  ~SimDotMonitor() override;

 private:
  class SimCamera;
  explicit SimDotMonitor(const SimDotMonitorOptions& options);

  SimDotMonitorOptions options_;
  MonitorInfo monitor_;
  std::unique_ptr<SimCamera> camera_;
  std::string shown_pattern_;
  Image levels_;  // Linear emitted level in [0, 1] per monitor pixel (drivers/pattern_id.h).
  // Per camera pixel: screen point (monitor px) seen by its centre and the 2x2 Jacobian
  // d(screen)/d(pixel); built on the first render (the geometry is fixed).
  void BuildScreenMap() const;
  mutable std::vector<double> screen_map_;
  std::vector<Eigen::Vector2d> shown_dots_;
};

}  // namespace thinslab
