// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/sim_board_camera.h"

#include <cmath>

#include "thinslab/acquire/session_writer.h"
#include "thinslab/core/math.h"

namespace thinslab {

CameraInfo MakeObliqueBoardCamera(int width_px, int height_px, const Eigen::Vector3d& target_in_sample,
                                  double distance_m, double tilt_deg, double view_width_m, double fill_fraction) {
  CameraInfo cam;
  cam.id = "cam0";
  cam.model = "sim";
  cam.serial = "sim-0";
  cam.width_px = width_px;
  cam.height_px = height_px;
  const double tilt = tilt_deg * kPi / 180;
  const Eigen::Vector3d eye = target_in_sample + distance_m * Eigen::Vector3d(0, -std::sin(tilt), std::cos(tilt));
  cam.cam_from_sample = LookAt(eye, target_in_sample, Eigen::Vector3d(0, 1, 0));
  cam.fx_px = cam.fy_px = fill_fraction * width_px * distance_m / view_width_m;
  cam.cx_px = width_px / 2.0 - 0.5;
  cam.cy_px = height_px / 2.0 - 0.5;
  return cam;
}

SimBoardCamera::SimBoardCamera(const SimBoardCameraOptions& options, IrradianceFn irradiance)
    : options_(options), info_(options.info), irradiance_(std::move(irradiance)),
      exposure_us_(options.initial_exposure_us) {
  options.sensor.DescribeCamera(&info_);
}

Status SimBoardCamera::SetExposure(double requested_us, double* applied_us) {
  if (!(requested_us > 0)) {
    return Status::Error("camera '" + info_.id + "' (sim): exposure must be > 0 us, got " + std::to_string(requested_us));
  }
  exposure_us_ = options_.sensor.AppliedExposureUs(requested_us);
  *applied_us = exposure_us_;
  return Status::Ok();
}

Status SimBoardCamera::Capture(CapturedFrame* frame) {
  frame->raw_dn = ApplySensor(RenderElectrons(), options_.sensor,
                              options_.seed * 1000003ULL + frame_counter_ * 7919ULL + 17);
  frame->exposure_time_us = exposure_us_;
  StampCapture(exposure_us_, &frame_counter_, &clock_ns_, frame);
  return Status::Ok();
}

void SimBoardCamera::StampCapture(double exposure_us, uint64_t* frame_counter, uint64_t* clock_ns,
                                  CapturedFrame* frame) {
  frame->frame_id = (*frame_counter)++;
  frame->device_timestamp_ns = *clock_ns;
  *clock_ns += static_cast<uint64_t>(std::llround(exposure_us * 1e3));
  frame->timestamp_utc = UtcTimestampNow();
}

Image SimBoardCamera::RenderElectrons() const {
  const CameraInfo& cam = info_;
  Image out(cam.width_px, cam.height_px);
  const double r_corner = std::hypot(cam.width_px / 2.0, cam.height_px / 2.0);
  const Rigid3d sample_from_cam = cam.cam_from_sample.Inverse();
  const Eigen::Vector3d eye = sample_from_cam.translation;
  const int s = options_.render_supersample;
  const double scale = options_.board_albedo / kPi * options_.electrons_per_radiance_us *
                       (exposure_us_ + options_.sensor.exposure_offset_us);
  for (int v = 0; v < cam.height_px; ++v) {
    for (int u = 0; u < cam.width_px; ++u) {
      double sum = 0;
      for (int a = 0; a < s; ++a) {
        for (int b = 0; b < s; ++b) {
          // thinslab pixel coordinates -> OpenCV (integer centres): subtract 0.5.
          const double ucv = u + (b + 0.5) / s - 0.5, vcv = v + (a + 0.5) / s - 0.5;
          const Eigen::Vector3d ray_cam((ucv - cam.cx_px) / cam.fx_px, (vcv - cam.cy_px) / cam.fy_px, 1.0);
          const Eigen::Vector3d ray = sample_from_cam.rotation * ray_cam;
          const double t = (options_.board_z_m - eye.z()) / ray.z();
          const Eigen::Vector3d hit = eye + t * ray;
          const double cos_field = 1.0 / ray_cam.norm();
          sum += irradiance_(hit.x(), hit.y()) * Sqr(Sqr(cos_field));
        }
      }
      const double r = std::hypot(u + 0.5 - cam.width_px / 2.0, v + 0.5 - cam.height_px / 2.0) / r_corner;
      out.at(u, v) = static_cast<float>(sum / (s * s) * (1.0 - options_.vignetting * r * r) * scale);
    }
  }
  return out;
}

}  // namespace thinslab
