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
//
// With a sample attached (SetSample, sim/slab_sample.h) and a sample state other than "none"
// (SetSampleState / sample_changer(), which the acquisition script drives), the camera sees
// the monitor THROUGH the sample (docs/models/dot_scan_rig.md): a camera ray meeting z = 0 at
// a point x on the sample sees
//   sum over the shown point sources q of (rho_d + k_s rho(x, i_q, o)) L_q A_q cos_e cos_i / r^2
// (dots are point sources of their rasterised emitting area A_q = pitch^2 sum of levels,
// L_q = dot_radiance, cos_e = cos_i = d / r for the parallel screen), plus, on smooth regions,
// the monitor seen straight through attenuated by k_s times the flat-slab transmittance.
// Outside the sample rectangle the camera sees the monitor directly. Non-dot patterns ("flat")
// and the black level are integrated by a coarse quadrature of the screen (blocks of
// monitor pixels as point sources).
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "thinslab/acquire/shadow_map_session.h"
#include "thinslab/core/image.h"
#include "thinslab/core/session.h"
#include "thinslab/drivers/camera.h"
#include "thinslab/drivers/display.h"
#include "thinslab/drivers/display_gamma.h"
#include "thinslab/sim/screen_footprint.h"
#include "thinslab/sim/sensor_model.h"
#include "thinslab/sim/sim_display_transfer.h"
#include "thinslab/sim/slab_sample.h"

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
  // The display between the requested linear level of a pattern pixel and the light it emits
  // (sim/sim_display_transfer.h): a pixel asked for level l emits
  //   black_radiance + dot_radiance * display_transfer.LightForLevel(l, gamma_table).
  // The library default is an ideal linear display with an identity table, which is what the
  // synthetic dot-scan sessions' ground truth ("dot_radiance x rasterised dot area") assumes;
  // `thinslab acquire --camera sim` gives its display a gamma 2.2, 8-bit curve (docs/cli.md).
  SimDisplayTransfer display_transfer;
  GammaTable gamma_table = IdentityGammaTable();  // The table the driver applies (--gamma-table).
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
  // black_radiance + dot_radiance * display_transfer.LightForLevel(l, gamma_table) (l itself
  // for the default linear display). Unknown ids give an error naming the id.
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

  // The sample that sample states other than "none" put in the light path (nullptr: none; the
  // camera then always sees the monitor directly). Its tables must have been traced for this
  // rig's camera (SlabSample::Create with CameraCentreInSample()).
  void SetSample(std::shared_ptr<const SlabSample> sample);
  const SlabSample* sample() const { return sample_.get(); }
  // "none" takes the sample out of the path, any other state puts it in.
  Status SetSampleState(const std::string& state);
  bool sample_in_path() const { return sample_in_path_ && sample_ != nullptr; }
  // The SampleChanger for the acquisition scripts (calls SetSampleState).
  SampleChanger sample_changer();
  // Camera centre (eye) in the sample frame.
  Eigen::Vector3d CameraCentreInSample() const;
  // Emitted flux factor of the point sources of the shown pattern (sample-frame position p_q and
  // L_q A_q [radiance x m^2]): one per dot for dot patterns, screen blocks otherwise; empty for
  // black. The black level is not included.
  struct PointSource {
    Eigen::Vector3d position_in_sample;
    double radiance_area;
  };
  const std::vector<PointSource>& point_sources() const { return sources_; }

  ~SimDotMonitor() override;

 private:
  class SimCamera;
  explicit SimDotMonitor(const SimDotMonitorOptions& options);

  SimDotMonitorOptions options_;
  MonitorInfo monitor_;
  std::unique_ptr<SimCamera> camera_;
  std::string shown_pattern_;
  Image levels_;  // Emitted light in [0, 1] per monitor pixel: the pattern's levels through the display.
  // Per camera pixel: screen point (monitor px) seen by its centre and the 2x2 Jacobian
  // d(screen)/d(pixel); built on the first render (the geometry is fixed).
  void BuildScreenMap() const;
  // Rasterised levels -> emitted light (display_transfer, gamma_table), in place.
  void ApplyDisplay(Image* levels) const;
  mutable std::vector<double> screen_map_;
  std::vector<Eigen::Vector2d> shown_dots_;

  // Sample in the path.
  std::shared_ptr<const SlabSample> sample_;
  bool sample_in_path_ = false;
  std::vector<PointSource> sources_;
  // Bounding box of the lit monitor pixels of the shown pattern (monitor px; empty if min > max).
  Eigen::Vector2d lit_min_px_ = Eigen::Vector2d(1, 1), lit_max_px_ = Eigen::Vector2d(0, 0);
  // Per camera pixel, built on the first render through the sample: the weight of each of the
  // s x s sub-samples' direct view of the screen (1 off the sample, k_s T on smooth regions,
  // 0 on rough ones) and the scattering components (one per region the pixel covers).
  struct ScatterComponent {
    int pixel;                     // v * width + u.
    int region;                    // Region index.
    float weight;                  // Fraction of the pixel's sub-samples in the region.
    Eigen::Vector3d x_in_sample;   // Mean sample point of those sub-samples (z = 0).
    Eigen::Vector3d view;          // Unit direction from x_in_sample to the camera centre.
    double black_level_radiance;   // Radiance from the screen's black level (per unit black_radiance).
  };
  void BuildSampleMap() const;
  Image RenderElectronsThroughSample() const;
  double ScatteredRadiance(const ScatterComponent& c, const std::vector<PointSource>& sources) const;
  // Mean radiance the screen sends into sub-pixel (a, b) of s x s of the pixel whose screen_map_
  // entry (6 doubles) is given.
  double DirectRadiance(const double* screen_map_entry, int s, int a, int b) const;
  ScreenFootprintMean SubPixelFootprintMean(const double* screen_map_entry, int s, int a, int b) const;
  // DirectRadiance of sub-pixel (a, b) of `pixel` whose footprint (screen_map_ entry e) misses
  // every lit monitor pixel: the black level alone, bit for bit DirectRadiance's value, from the
  // footprint's share on the screen cached per sub-pixel (a displayed pattern does not change
  // it). Each frame of a glowing display otherwise clipped every pixel's footprint against the
  // screen again: 54 % of a 20 x 20 dot scan's time.
  bool MissesLitPixels(const double* screen_map_entry) const;
  double BlackLevelRadiance(size_t pixel, int s, int a, int b) const;
  std::vector<PointSource> BlockSources(const Image* levels, double radiance) const;
  mutable const SlabSample* sample_map_for_ = nullptr;
  mutable std::vector<float> direct_weights_;      // width * height * s * s.
  mutable std::vector<uint8_t> pixel_direct_;      // 1 if any sub-sample sees the screen directly.
  mutable std::vector<ScatterComponent> components_;
  mutable std::vector<double> screen_inside_;  // width * height * s * s: MeanOverFootprint's `inside`.
};

}  // namespace thinslab
