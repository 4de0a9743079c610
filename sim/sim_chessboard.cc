// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/sim_chessboard.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <utility>

#include "thinslab/core/camera_model.h"
#include "thinslab/core/math.h"

namespace thinslab {

Status SimChessboardOptions::Check() const {
  if (inner_cols < 2 || inner_rows < 2) {
    return Status::Error("SimChessboardOptions::inner_cols/inner_rows: need >= 2 inner corners each, got " +
                         std::to_string(inner_cols) + "x" + std::to_string(inner_rows));
  }
  if (!(square_m > 0)) return Status::Error("SimChessboardOptions::square_m: must be > 0 m");
  if (!(margin_squares >= 0)) return Status::Error("SimChessboardOptions::margin_squares: must be >= 0");
  if (render_supersample < 1) return Status::Error("SimChessboardOptions::render_supersample: must be >= 1");
  if (!(blur_sigma_px >= 0)) return Status::Error("SimChessboardOptions::blur_sigma_px: must be >= 0 px");
  if (!(electrons_per_radiance > 0)) return Status::Error("SimChessboardOptions::electrons_per_radiance: must be > 0");
  std::string error;
  if (!sensor.Check(&error)) return Status::Error("SimChessboardOptions::sensor: " + error);
  return Status::Ok();
}

Image BlurGaussian(const Image& image, double sigma_px) {
  if (!(sigma_px > 0)) return image;
  const int radius = static_cast<int>(std::ceil(3 * sigma_px));
  std::vector<double> kernel(2 * radius + 1);
  double sum = 0;
  for (int k = -radius; k <= radius; ++k) sum += kernel[k + radius] = std::exp(-0.5 * Sqr(k / sigma_px));
  for (double& k : kernel) k /= sum;
  const int w = image.width(), h = image.height(), nc = image.num_channels();
  Image tmp = image, out = image;
  for (int c = 0; c < nc; ++c) {
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        double acc = 0;
        for (int k = -radius; k <= radius; ++k) acc += kernel[k + radius] * image.at(Clamp(x + k, 0, w - 1), y, c);
        tmp.at(x, y, c) = static_cast<float>(acc);
      }
    }
    for (int y = 0; y < h; ++y) {
      for (int x = 0; x < w; ++x) {
        double acc = 0;
        for (int k = -radius; k <= radius; ++k) acc += kernel[k + radius] * tmp.at(x, Clamp(y + k, 0, h - 1), c);
        out.at(x, y, c) = static_cast<float>(acc);
      }
    }
  }
  return out;
}

namespace {

// Radiance of the board point (x, y) in board metres.
double BoardRadiance(const SimChessboardOptions& o, double x_m, double y_m) {
  const double a = x_m / o.square_m, b = y_m / o.square_m;
  const double m = o.margin_squares;
  if (a < -1 - m || b < -1 - m || a > o.inner_cols + m || b > o.inner_rows + m) return o.background_radiance;
  if (a < -1 || b < -1 || a >= o.inner_cols || b >= o.inner_rows) return o.white_radiance;
  const long ia = static_cast<long>(std::floor(a)), ib = static_cast<long>(std::floor(b));
  return ((ia + ib) % 2 == 0) ? o.black_radiance : o.white_radiance;
}

}  // namespace

Status RenderChessboardView(const SimChessboardOptions& options, const CameraInfo& camera, uint64_t seed,
                            Image* raw_dn) {
  THINSLAB_RETURN_IF_ERROR(options.Check());
  if (camera.width_px <= 0 || camera.height_px <= 0 || !(camera.fx_px > 0) || !(camera.fy_px > 0)) {
    return Status::Error("RenderChessboardView: camera '" + camera.id + "' needs positive size and focal lengths");
  }
  const int s = options.render_supersample;
  const Rigid3d board_from_cam = camera.cam_from_sample.Inverse();
  const Eigen::Vector3d eye = board_from_cam.translation;
  const int w = camera.width_px, h = camera.height_px;
  // Board points seen through the pixel corners, traced through the exact inverse distortion;
  // inside a pixel the map is interpolated bilinearly (its neglected curvature is of order
  // 1e-4 px here). Rows v and v + 1 of corners are kept.
  std::vector<Eigen::Vector2d> top(w + 1), bottom(w + 1);
  std::vector<char> top_ok(w + 1), bottom_ok(w + 1);
  auto trace_row = [&](int v, std::vector<Eigen::Vector2d>* row, std::vector<char>* ok) {
    Eigen::Vector2d guess((0.5 - camera.cx_px) / camera.fx_px, (v + 0.5 - camera.cy_px) / camera.fy_px);
    for (int u = 0; u <= w; ++u) {
      const Eigen::Vector3d ray_in_cam = PixelToCameraRay(camera, Eigen::Vector2d(u, v), &guess);
      guess = ray_in_cam.head<2>();
      const Eigen::Vector3d ray = board_from_cam.rotation * ray_in_cam;
      const double t = -eye.z() / ray.z();
      (*ok)[u] = t > 0;
      (*row)[u] = (eye + t * ray).head<2>();
    }
  };
  trace_row(0, &top, &top_ok);
  Image electrons(w, h);
  for (int v = 0; v < h; ++v) {
    trace_row(v + 1, &bottom, &bottom_ok);
    for (int u = 0; u < w; ++u) {
      double sum = 0;
      if (!(top_ok[u] && top_ok[u + 1] && bottom_ok[u] && bottom_ok[u + 1])) {
        sum = s * s * options.background_radiance;  // The board plane is behind the camera here.
      } else {
        for (int a = 0; a < s; ++a) {
          const double fy = (a + 0.5) / s;
          const Eigen::Vector2d left = (1 - fy) * top[u] + fy * bottom[u];
          const Eigen::Vector2d right = (1 - fy) * top[u + 1] + fy * bottom[u + 1];
          for (int b = 0; b < s; ++b) {
            const double fx = (b + 0.5) / s;
            const Eigen::Vector2d hit = (1 - fx) * left + fx * right;
            sum += BoardRadiance(options, hit.x(), hit.y());
          }
        }
      }
      electrons.at(u, v) = static_cast<float>(sum / (s * s) * options.electrons_per_radiance);
    }
    std::swap(top, bottom);
    std::swap(top_ok, bottom_ok);
  }
  *raw_dn = ApplySensor(BlurGaussian(electrons, options.blur_sigma_px), options.sensor, seed);
  return Status::Ok();
}

Status MakeChessboardViewPoses(const SimChessboardOptions& options, const CameraInfo& camera, int count,
                               double max_tilt_deg, uint64_t seed, std::vector<Rigid3d>* cam_from_board) {
  THINSLAB_RETURN_IF_ERROR(options.Check());
  cam_from_board->clear();
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const double sq = options.square_m;
  const Eigen::Vector3d center((options.inner_cols - 1) * sq / 2, (options.inner_rows - 1) * sq / 2, 0);
  const double board_width_m = (options.inner_cols + 1 + 2 * options.margin_squares) * sq;
  // Outer corners of the printed squares plus half a square: all must be inside the image.
  const double lo = -1.5 * sq, hi_x = (options.inner_cols + 0.5) * sq, hi_y = (options.inner_rows + 0.5) * sq;
  const Eigen::Vector3d outline[4] = {{lo, lo, 0}, {hi_x, lo, 0}, {lo, hi_y, 0}, {hi_x, hi_y, 0}};
  for (int view = 0; view < count; ++view) {
    bool ok = false;
    for (int attempt = 0; attempt < 500 && !ok; ++attempt) {
      const double tilt_x = unit(rng) * max_tilt_deg * kPi / 180, tilt_y = unit(rng) * max_tilt_deg * kPi / 180;
      const double fill = 0.55 + 0.25 * (unit(rng) + 1) / 2;
      const double distance = camera.fx_px * board_width_m / (fill * camera.width_px);
      const Eigen::Vector3d dir = (Eigen::AngleAxisd(tilt_y, Eigen::Vector3d::UnitY()) *
                                   Eigen::AngleAxisd(tilt_x, Eigen::Vector3d::UnitX()) * Eigen::Vector3d::UnitZ());
      // Spread the board over the frame (corners included) so distortion is observed everywhere.
      const Eigen::Vector3d target = center + Eigen::Vector3d(3 * unit(rng), 2.5 * unit(rng), 0) * sq;
      const double roll = unit(rng) * 0.3;
      CameraInfo cam = camera;
      cam.cam_from_sample = LookAt(center + distance * dir, target, Eigen::Vector3d(std::sin(roll), -std::cos(roll), 0));
      ok = true;
      for (const Eigen::Vector3d& corner : outline) {
        Eigen::Vector2d px;
        if (!ProjectSamplePoint(cam, corner, &px) || px.x() < 2 || px.y() < 2 || px.x() > camera.width_px - 2 ||
            px.y() > camera.height_px - 2) {
          ok = false;
        }
      }
      if (ok) cam_from_board->push_back(cam.cam_from_sample);
    }
    if (!ok) {
      return Status::Error("MakeChessboardViewPoses: no pose keeps the " + std::to_string(options.inner_cols) + "x" +
                           std::to_string(options.inner_rows) + " board inside the " +
                           std::to_string(camera.width_px) + "x" + std::to_string(camera.height_px) + " image");
    }
  }
  return Status::Ok();
}

}  // namespace thinslab
