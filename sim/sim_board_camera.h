// SPDX-License-Identifier: Apache-2.0
// A simulated camera looking at a Lambertian board (the plane z = board_z_m of the sample
// frame): perspective pinhole (no distortion), cos^4 fall-off plus extra radial vignetting,
// n x n supersampling per pixel, then the sensor model. The rig supplies the board irradiance
// as a function of the board point, so shadow-map, laser and flat-field rigs share it.
#pragma once

#include <functional>

#include "thinslab/drivers/camera.h"
#include "thinslab/sim/sensor_model.h"

namespace thinslab {

struct SimBoardCameraOptions {
  CameraInfo info;             // Geometry; bit depth, black level, saturation and gain are set from `sensor`.
  double board_z_m = 0;
  double board_albedo = 0.8;
  double vignetting = 0.15;    // Relative loss at the image corner, on top of cos^4.
  int render_supersample = 3;
  // Electrons per unit board radiance per microsecond at the image centre.
  double electrons_per_radiance_us = 1;
  double initial_exposure_us = 1000;
  SimSensorOptions sensor;
  uint64_t seed = 1;
};

// Pose and intrinsics of a camera at `distance_m` from `target_in_sample`, tilted by `tilt_deg`
// from the board normal about the sample x axis, whose image width spans `view_width_m` of the
// board divided by `fill_fraction`.
CameraInfo MakeObliqueBoardCamera(int width_px, int height_px, const Eigen::Vector3d& target_in_sample,
                                  double distance_m, double tilt_deg, double view_width_m, double fill_fraction);

class SimBoardCamera : public Camera {
 public:
  using IrradianceFn = std::function<double(double x_m, double y_m)>;
  SimBoardCamera(const SimBoardCameraOptions& options, IrradianceFn irradiance);

  const CameraInfo& info() const override { return info_; }
  Status SetExposure(double requested_us, double* applied_us) override;
  Status Capture(CapturedFrame* frame) override;

  // Expected electrons at the current exposure (no noise).
  Image RenderElectrons() const;
  // The noise of capture n is seeded from (seed, n). A resumed acquisition sets the count of
  // captures its earlier runs made, so the resumed frames are bit-identical to an
  // uninterrupted run's (thinslab acquire --resume).
  void set_frame_counter(uint64_t captures) { frame_counter_ = captures; }

  // Stamps a simulated capture as a camera does: frame id = captures so far (then counts it),
  // device timestamp = start of the exposure on a clock that starts at 0 when the camera is
  // created and runs for the exposure of every capture.
  static void StampCapture(double exposure_us, uint64_t* frame_counter, uint64_t* clock_ns, CapturedFrame* frame);

 private:
  SimBoardCameraOptions options_;
  CameraInfo info_;
  IrradianceFn irradiance_;
  double exposure_us_;
  uint64_t frame_counter_ = 0;
  uint64_t clock_ns_ = 0;
};

}  // namespace thinslab
