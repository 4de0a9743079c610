// SPDX-License-Identifier: Apache-2.0
#include "sim/sim_dot_monitor.h"

#include <algorithm>
#include <cmath>

#include "acquire/session_writer.h"
#include "core/camera_model.h"
#include "core/math.h"
#include "drivers/pattern_id.h"
#include "sim/sim_board_camera.h"
#include "sim/sim_chessboard.h"

namespace thinslab {

class SimDotMonitor::SimCamera : public Camera {
 public:
  SimCamera(const SimDotMonitor* rig, CameraInfo info, double exposure_us)
      : rig_(rig), info_(std::move(info)), exposure_us_(exposure_us) {}

  const CameraInfo& info() const override { return info_; }
  Status SetExposure(double requested_us, double* applied_us) override {
    if (!(requested_us > 0) || !std::isfinite(requested_us)) {
      return Status::Error("camera '" + info_.id + "' (sim dot monitor): exposure must be > 0 us, got " +
                           std::to_string(requested_us));
    }
    exposure_us_ = std::max(1.0, std::round(requested_us));  // Whole microseconds, like real sensors.
    *applied_us = exposure_us_;
    return Status::Ok();
  }
  Status Capture(CapturedFrame* frame) override {
    const SimDotMonitorOptions& o = rig_->options();
    frame->raw_dn = ApplySensor(BlurGaussian(rig_->RenderElectrons(), o.blur_sigma_px), o.sensor,
                                o.seed * 1000003ULL + frame_counter_ * 7919ULL + 29);
    frame->exposure_time_us = exposure_us_;
    frame->frame_id = frame_counter_++;
    frame->timestamp_utc = UtcTimestampNow();
    return Status::Ok();
  }
  double exposure_us() const { return exposure_us_; }

 private:
  const SimDotMonitor* rig_;
  CameraInfo info_;
  double exposure_us_;
  uint64_t frame_counter_ = 0;
};

Status SimDotMonitorOptions::Check() const {
  auto err = [](const std::string& field, const std::string& what) {
    return Status::Error("SimDotMonitorOptions::" + field + ": " + what);
  };
  if (monitor_width_px <= 0 || monitor_height_px <= 0) return err("monitor_width_px/height_px", "must be > 0");
  if (!(monitor_pixel_pitch_m > 0)) return err("monitor_pixel_pitch_m", "must be > 0 m");
  if (!(monitor_distance_m > 0)) return err("monitor_distance_m", "must be > 0 m");
  if (!(dot_radius_px > 0)) return err("dot_radius_px", "must be > 0 px");
  if (!(dot_radiance > 0) || !(black_radiance >= 0)) return err("dot_radiance/black_radiance", "must be > 0 / >= 0");
  if (camera_width_px <= 0 || camera_height_px <= 0) return err("camera_width_px/height_px", "must be > 0");
  if (!(camera_distance_m > 0)) return err("camera_distance_m", "must be > 0 m");
  if (!(std::abs(camera_tilt_deg) < 80)) return err("camera_tilt_deg", "must be within (-80, 80) degrees");
  if (!(camera_view_width_m > 0)) return err("camera_view_width_m", "must be > 0 m");
  if (camera_distortion.size() != 0 && camera_distortion.size() != 4 && camera_distortion.size() != 5) {
    return err("camera_distortion", "needs 0, 4 or 5 coefficients");
  }
  if (!(blur_sigma_px >= 0)) return err("blur_sigma_px", "must be >= 0 px");
  if (render_supersample < 1) return err("render_supersample", "must be >= 1");
  if (!(electrons_per_radiance_us > 0)) return err("electrons_per_radiance_us", "must be > 0");
  if (!(initial_exposure_us > 0)) return err("initial_exposure_us", "must be > 0 us");
  std::string error;
  if (!sensor.Check(&error)) return err("sensor", error);
  return Status::Ok();
}

SimDotMonitor::SimDotMonitor(const SimDotMonitorOptions& options)
    : options_(options), levels_(options.monitor_width_px, options.monitor_height_px) {
  const SimDotMonitorOptions& o = options_;
  monitor_.present = true;
  monitor_.pixel_pitch_m = o.monitor_pixel_pitch_m;
  monitor_.width_px = o.monitor_width_px;
  monitor_.height_px = o.monitor_height_px;
  // Monitor frame (docs/format.md 2.3.6): x along a row, y down the screen, z into the screen.
  // The screen faces +z of the sample frame (towards sample and camera), so monitor z maps to
  // sample -z: a half turn about x, then the in-plane rotation.
  const Eigen::Quaterniond rot =
      Eigen::Quaterniond(Eigen::AngleAxisd(o.monitor_rotation_deg * kPi / 180, Eigen::Vector3d::UnitZ())) *
      Eigen::Quaterniond(Eigen::AngleAxisd(kPi, Eigen::Vector3d::UnitX()));
  const Eigen::Vector3d center_in_monitor(o.monitor_width_px * o.monitor_pixel_pitch_m / 2,
                                          o.monitor_height_px * o.monitor_pixel_pitch_m / 2, 0);
  const Eigen::Vector3d center_in_sample(o.monitor_center_in_sample_m.x(), o.monitor_center_in_sample_m.y(),
                                         -o.monitor_distance_m);
  monitor_.sample_from_monitor.rotation = rot.normalized();
  monitor_.sample_from_monitor.translation = center_in_sample - rot * center_in_monitor;

  CameraInfo cam = MakeObliqueBoardCamera(o.camera_width_px, o.camera_height_px, o.camera_target_in_sample,
                                          o.camera_distance_m, o.camera_tilt_deg, o.camera_view_width_m, 1.0);
  cam.id = "cam0";
  cam.model = "sim";
  cam.serial = "sim-dot-monitor";
  cam.distortion = o.camera_distortion;
  cam.bit_depth = o.sensor.bit_depth;
  cam.black_level_dn = o.sensor.black_level_dn;
  cam.saturation_dn = o.sensor.saturation_dn();
  cam.gain_e_per_dn = o.sensor.gain_e_per_dn();
  camera_ = std::make_unique<SimCamera>(this, cam, o.initial_exposure_us);
}

SimDotMonitor::~SimDotMonitor() = default;

Status SimDotMonitor::Create(const SimDotMonitorOptions& options, std::unique_ptr<SimDotMonitor>* out) {
  THINSLAB_RETURN_IF_ERROR(options.Check());
  out->reset(new SimDotMonitor(options));
  return Status::Ok();
}

Status SimDotMonitor::ShowPattern(const std::string& pattern) {
  PatternSpec spec;
  THINSLAB_RETURN_IF_ERROR(ParsePatternId(pattern, &spec).WithContext("sim dot monitor"));
  Image levels;
  THINSLAB_RETURN_IF_ERROR(
      RasterizePattern(spec, options_.monitor_width_px, options_.monitor_height_px, options_.dot_radius_px, &levels)
          .WithContext("sim dot monitor: pattern '" + pattern + "'"));
  levels_ = std::move(levels);
  shown_pattern_ = pattern;
  shown_dots_.clear();
  if (spec.kind == PatternSpec::Kind::kDots) {
    for (const PatternSpec::Dot& dot : spec.dots) shown_dots_.emplace_back(dot.x_px, dot.y_px);
  }
  return Status::Ok();
}

Camera* SimDotMonitor::camera() { return camera_.get(); }
const CameraInfo& SimDotMonitor::camera_info() const { return camera_->info(); }

RigInfo SimDotMonitor::rig() const {
  RigInfo rig;
  rig.cameras.push_back(camera_->info());
  rig.monitor = monitor_;
  return rig;
}

Eigen::Vector3d SimDotMonitor::DotInSample(const Eigen::Vector2d& dot_px) const {
  return monitor_.sample_from_monitor *
         Eigen::Vector3d(dot_px.x() * monitor_.pixel_pitch_m, dot_px.y() * monitor_.pixel_pitch_m, 0);
}

void SimDotMonitor::BuildScreenMap() const {
  const CameraInfo& cam = camera_->info();
  const Rigid3d sample_from_cam = cam.cam_from_sample.Inverse();
  const Rigid3d monitor_from_sample = monitor_.sample_from_monitor.Inverse();
  // Everything in the monitor frame: the screen is z = 0 there.
  const Eigen::Quaterniond monitor_from_cam_rot = monitor_from_sample.rotation * sample_from_cam.rotation;
  const Eigen::Vector3d eye = monitor_from_sample * sample_from_cam.translation;
  const double inv_pitch = 1.0 / monitor_.pixel_pitch_m;
  // Screen point (monitor px) seen through a camera pixel coordinate; false if the ray misses.
  auto screen = [&](const Eigen::Vector2d& pixel, Eigen::Vector2d* guess, Eigen::Vector2d* m) {
    const Eigen::Vector3d ray_in_cam = PixelToCameraRay(cam, pixel, guess);
    *guess = ray_in_cam.head<2>();
    const Eigen::Vector3d ray = monitor_from_cam_rot * ray_in_cam;
    const double t = -eye.z() / ray.z();
    if (!(t > 0)) return false;
    *m = (eye + t * ray).head<2>() * inv_pitch;
    return true;
  };
  screen_map_.assign(static_cast<size_t>(cam.width_px) * cam.height_px * 6, 0.0);
  for (int v = 0; v < cam.height_px; ++v) {
    Eigen::Vector2d guess((0.5 - cam.cx_px) / cam.fx_px, (v + 0.5 - cam.cy_px) / cam.fy_px);
    for (int u = 0; u < cam.width_px; ++u) {
      double* e = &screen_map_[(static_cast<size_t>(v) * cam.width_px + u) * 6];
      Eigen::Vector2d c, xp, xm, yp, ym;
      const Eigen::Vector2d centre(u + 0.5, v + 0.5);
      const bool ok = screen(centre + Eigen::Vector2d(-0.5, 0), &guess, &xm) && screen(centre, &guess, &c) &&
                      screen(centre + Eigen::Vector2d(0.5, 0), &guess, &xp) &&
                      screen(centre + Eigen::Vector2d(0, -0.5), &guess, &ym) &&
                      screen(centre + Eigen::Vector2d(0, 0.5), &guess, &yp);
      if (!ok) {
        e[0] = -1e30;  // Sees no screen.
        continue;
      }
      e[0] = c.x();
      e[1] = c.y();
      e[2] = xp.x() - xm.x();  // d(screen)/d(u), central difference over one pixel.
      e[3] = xp.y() - xm.y();
      e[4] = yp.x() - ym.x();  // d(screen)/d(v).
      e[5] = yp.y() - ym.y();
    }
  }
}

Image SimDotMonitor::RenderElectrons() const {
  const SimDotMonitorOptions& o = options_;
  const CameraInfo& cam = camera_->info();
  // The camera -> screen map is traced once (5 rays per pixel through the exact inverse
  // distortion) and taken as affine inside a pixel: the neglected second-order term over half a
  // pixel is of order 1e-4 monitor px in this geometry, far below the sensor noise.
  if (screen_map_.empty()) BuildScreenMap();
  const int s = o.render_supersample;
  // A camera pixel seeing radiance L collects electrons_per_radiance_us * L * exposure electrons
  // whatever its distance (radiance invariance); the renderer integrates L over the pixel area.
  const double scale = o.electrons_per_radiance_us * camera_->exposure_us();
  Image out(cam.width_px, cam.height_px);
  for (int v = 0; v < cam.height_px; ++v) {
    for (int u = 0; u < cam.width_px; ++u) {
      const double* e = &screen_map_[(static_cast<size_t>(v) * cam.width_px + u) * 6];
      if (e[0] < -1e29) continue;
      double sum = 0;
      for (int a = 0; a < s; ++a) {
        for (int b = 0; b < s; ++b) {
          const double du = (b + 0.5) / s - 0.5, dv = (a + 0.5) / s - 0.5;
          const double mx = e[0] + du * e[2] + dv * e[4], my = e[1] + du * e[3] + dv * e[5];
          if (mx < 0 || my < 0 || mx >= o.monitor_width_px || my >= o.monitor_height_px) continue;  // Black bezel.
          // Each monitor pixel is a uniform emitter (the pixelated display the real window draws).
          sum += o.black_radiance + o.dot_radiance * levels_.at(static_cast<int>(mx), static_cast<int>(my));
        }
      }
      out.at(u, v) = static_cast<float>(sum / (s * s) * scale);
    }
  }
  return out;
}

}  // namespace thinslab
