// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/sim_dot_monitor.h"

#include <algorithm>
#include <cmath>
#include <map>

#include "thinslab/core/camera_model.h"
#include "thinslab/core/math.h"
#include "thinslab/core/memory.h"
#include "thinslab/drivers/pattern_id.h"
#include "thinslab/sim/sim_board_camera.h"
#include "thinslab/sim/sim_chessboard.h"

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
    exposure_us_ = rig_->options().sensor.AppliedExposureUs(requested_us);
    *applied_us = exposure_us_;
    return Status::Ok();
  }
  Status Capture(CapturedFrame* frame) override {
    const SimDotMonitorOptions& o = rig_->options();
    frame->raw_dn = ApplySensor(BlurGaussian(rig_->RenderElectrons(), o.blur_sigma_px), o.sensor,
                                o.seed * 1000003ULL + frame_counter_ * 7919ULL + 29);
    frame->exposure_time_us = exposure_us_;
    SimBoardCamera::StampCapture(exposure_us_, &frame_counter_, &clock_ns_, frame);
    return Status::Ok();
  }
  // What the light is integrated over (SimSensorOptions::IntegratedExposureUs: the applied
  // exposure plus the unreported offset).
  double integrated_exposure_us() const { return exposure_us_ + rig_->options().sensor.exposure_offset_us; }

 private:
  const SimDotMonitor* rig_;
  CameraInfo info_;
  double exposure_us_;
  uint64_t frame_counter_ = 0;
  uint64_t clock_ns_ = 0;
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
  if (camera_width_px > 0 && camera_height_px > 0) {
    THINSLAB_RETURN_IF_ERROR(CheckMemoryNeed(
        SimCameraMemoryBytes(camera_width_px, camera_height_px),
        "SimDotMonitorOptions::camera_width_px/height_px (--camera-width-px/--camera-height-px): the simulated camera"));
  }
  if (camera_width_px <= 0 || camera_height_px <= 0 || camera_width_px > kMaxSimCameraSidePx ||
      camera_height_px > kMaxSimCameraSidePx) {
    return err("camera_width_px/height_px", std::to_string(camera_width_px) + "x" + std::to_string(camera_height_px) +
                                                ": each must be in 1.." + std::to_string(kMaxSimCameraSidePx) +
                                                " (--camera-width-px, --camera-height-px)");
  }
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
  const Status transfer = display_transfer.Check();
  if (!transfer.ok()) return err("display_transfer", transfer.message());
  const auto& table = gamma_table.drive_to_light;
  if (table.size() < 2 || table.front() != std::make_pair(0.0, 0.0) || table.back() != std::make_pair(1.0, 1.0)) {
    return err("gamma_table", "must run from (0, 0) to (1, 1) (drivers/display_gamma.h)");
  }
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
  monitor_.dot_radius_px = o.dot_radius_px;
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
  o.sensor.DescribeCamera(&cam);
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
  ApplyDisplay(&levels);
  levels_ = std::move(levels);
  shown_pattern_ = pattern;
  shown_dots_.clear();
  if (spec.kind == PatternSpec::Kind::kDots) {
    for (const PatternSpec::Dot& dot : spec.dots) shown_dots_.emplace_back(dot.x_px, dot.y_px);
  }
  // Lit bounding box and the point sources of the pattern (for rendering through the sample).
  lit_min_px_ = Eigen::Vector2d(1e30, 1e30);
  lit_max_px_ = Eigen::Vector2d(-1e30, -1e30);
  for (int y = 0; y < levels_.height(); ++y) {
    for (int x = 0; x < levels_.width(); ++x) {
      if (levels_.at(x, y) <= 0) continue;
      lit_min_px_ = lit_min_px_.cwiseMin(Eigen::Vector2d(x, y));
      lit_max_px_ = lit_max_px_.cwiseMax(Eigen::Vector2d(x + 1, y + 1));
    }
  }
  sources_.clear();
  const double pitch2 = monitor_.pixel_pitch_m * monitor_.pixel_pitch_m;
  if (spec.kind == PatternSpec::Kind::kDots) {
    // Each dot: a point source at its centre whose area is its rasterised coverage (the stamp
    // of drivers/pattern_id.cc reaches at most ceil(r) + 1 px from the centre).
    const int half = static_cast<int>(std::ceil(options_.dot_radius_px)) + 1;
    for (const Eigen::Vector2d& dot : shown_dots_) {
      double sum = 0;
      const int cx = static_cast<int>(std::floor(dot.x())), cy = static_cast<int>(std::floor(dot.y()));
      for (int y = std::max(0, cy - half); y <= std::min(levels_.height() - 1, cy + half); ++y) {
        for (int x = std::max(0, cx - half); x <= std::min(levels_.width() - 1, cx + half); ++x) {
          sum += levels_.at(x, y);
        }
      }
      if (sum > 0) sources_.push_back({DotInSample(dot), options_.dot_radiance * sum * pitch2});
    }
  } else if (spec.kind != PatternSpec::Kind::kBlack) {
    sources_ = BlockSources(&levels_, options_.dot_radiance);
  }
  return Status::Ok();
}

void SimDotMonitor::ApplyDisplay(Image* levels) const {
  const SimDisplayTransfer& t = options_.display_transfer;
  const auto& table = options_.gamma_table.drive_to_light;
  const bool identity_table = table.size() == 2;  // Check(): then it is {(0, 0), (1, 1)}.
  if (t.IsIdentity() && identity_table) return;   // The ideal display: levels are the light.
  // Patterns hold few distinct levels (one for flats, a stamp's worth for dots): cache them.
  std::map<float, float> light;
  for (float& v : levels->data()) {
    if (v <= 0) continue;  // Drive 0 emits nothing beyond black_radiance for any curve.
    auto it = light.find(v);
    if (it == light.end()) {
      it = light.emplace(v, static_cast<float>(t.LightForLevel(v, options_.gamma_table))).first;
    }
    v = it->second;
  }
}

std::vector<SimDotMonitor::PointSource> SimDotMonitor::BlockSources(const Image* levels, double radiance) const {
  // Coarse quadrature of the screen: blocks of b x b monitor pixels (about 32 x 32 blocks), each
  // a point source at its centre carrying the block's emitted radiance x area.
  const int w = options_.monitor_width_px, h = options_.monitor_height_px;
  const int b = std::max(1, (std::max(w, h) + 31) / 32);
  const double pitch2 = monitor_.pixel_pitch_m * monitor_.pixel_pitch_m;
  std::vector<PointSource> out;
  for (int y0 = 0; y0 < h; y0 += b) {
    for (int x0 = 0; x0 < w; x0 += b) {
      double sum = 0;
      const int x1 = std::min(w, x0 + b), y1 = std::min(h, y0 + b);
      for (int y = y0; y < y1; ++y) {
        for (int x = x0; x < x1; ++x) sum += levels ? levels->at(x, y) : 1.0;
      }
      if (sum > 0) out.push_back({DotInSample(Eigen::Vector2d(0.5 * (x0 + x1), 0.5 * (y0 + y1))), radiance * sum * pitch2});
    }
  }
  return out;
}

void SimDotMonitor::SetSample(std::shared_ptr<const SlabSample> sample) {
  sample_ = std::move(sample);
  sample_map_for_ = nullptr;
  components_.clear();
  direct_weights_.clear();
  pixel_direct_.clear();
}

Status SimDotMonitor::SetSampleState(const std::string& state) {
  if (state.empty()) return Status::Error("sim dot monitor: empty sample state");
  sample_in_path_ = state != "none";
  return Status::Ok();
}

SampleChanger SimDotMonitor::sample_changer() {
  return [this](const std::string& state) { return SetSampleState(state); };
}

Eigen::Vector3d SimDotMonitor::CameraCentreInSample() const {
  return camera_->info().cam_from_sample.Inverse().translation;
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

ScreenFootprintMean SimDotMonitor::SubPixelFootprintMean(const double* e, int s, int a, int b) const {
  // Sub-pixel (a, b) of s x s: its footprint on the screen under the pixel's affine map. Each
  // monitor pixel is a uniform emitter (the pixelated display the real window draws), the bezel
  // is black, and the footprint's mean radiance is integrated exactly (sim/screen_footprint.h).
  const double du = (b + 0.5) / s - 0.5, dv = (a + 0.5) / s - 0.5;
  const Eigen::Vector2d centre(e[0] + du * e[2] + dv * e[4], e[1] + du * e[3] + dv * e[5]);
  return MeanOverFootprint(levels_, centre, Eigen::Vector2d(e[2], e[3]) / s, Eigen::Vector2d(e[4], e[5]) / s);
}

double SimDotMonitor::DirectRadiance(const double* screen_map_entry, int s, int a, int b) const {
  const ScreenFootprintMean mean = SubPixelFootprintMean(screen_map_entry, s, a, b);
  return options_.black_radiance * mean.inside + options_.dot_radiance * mean.level;
}

bool SimDotMonitor::MissesLitPixels(const double* e) const {
  if (lit_min_px_.x() > lit_max_px_.x()) return true;
  // The pixel's footprint's half extents plus one monitor pixel: no sub-pixel footprint's
  // bounding box reaches a lit pixel (MeanOverFootprint's sum stays exactly 0).
  const double hx = 0.5 * (std::abs(e[2]) + std::abs(e[4])) + 1, hy = 0.5 * (std::abs(e[3]) + std::abs(e[5])) + 1;
  return e[0] + hx < lit_min_px_.x() || e[0] - hx > lit_max_px_.x() || e[1] + hy < lit_min_px_.y() ||
         e[1] - hy > lit_max_px_.y();
}

double SimDotMonitor::BlackLevelRadiance(size_t pixel, int s, int a, int b) const {
  const size_t ss = static_cast<size_t>(s) * s;
  if (screen_inside_.empty()) {
    const size_t num_pixels = screen_map_.size() / 6;
    screen_inside_.assign(num_pixels * ss, 0.0);
    for (size_t p = 0; p < num_pixels; ++p) {
      const double* e = &screen_map_[p * 6];
      if (e[0] < -1e29) continue;
      for (int i = 0; i < s; ++i) {
        for (int j = 0; j < s; ++j) screen_inside_[p * ss + i * s + j] = SubPixelFootprintMean(e, s, i, j).inside;
      }
    }
  }
  // DirectRadiance adds dot_radiance * 0 here, which leaves the sum unchanged.
  return options_.black_radiance * screen_inside_[pixel * ss + a * s + b];
}

Image SimDotMonitor::RenderElectrons() const {
  if (sample_in_path()) return RenderElectronsThroughSample();
  const SimDotMonitorOptions& o = options_;
  const CameraInfo& cam = camera_->info();
  // The camera -> screen map is traced once (5 rays per pixel through the exact inverse
  // distortion) and taken as affine inside a pixel: the neglected second-order term over half a
  // pixel is of order 1e-4 monitor px in this geometry, far below the sensor noise.
  if (screen_map_.empty()) BuildScreenMap();
  const int s = o.render_supersample;
  // A camera pixel seeing radiance L collects electrons_per_radiance_us * L * exposure electrons
  // whatever its distance (radiance invariance); the renderer integrates L over the pixel area.
  const double scale = o.electrons_per_radiance_us * camera_->integrated_exposure_us();
  Image out(cam.width_px, cam.height_px);
  for (int v = 0; v < cam.height_px; ++v) {
    for (int u = 0; u < cam.width_px; ++u) {
      const size_t pixel = static_cast<size_t>(v) * cam.width_px + u;
      const double* e = &screen_map_[pixel * 6];
      if (e[0] < -1e29) continue;
      const bool black_only = MissesLitPixels(e);
      if (black_only && o.black_radiance <= 0) continue;
      double sum = 0;
      for (int a = 0; a < s; ++a) {
        for (int b = 0; b < s; ++b) sum += black_only ? BlackLevelRadiance(pixel, s, a, b) : DirectRadiance(e, s, a, b);
      }
      out.at(u, v) = static_cast<float>(sum / (s * s) * scale);
    }
  }
  return out;
}

void SimDotMonitor::BuildSampleMap() const {
  if (screen_map_.empty()) BuildScreenMap();
  const SlabSample& sample = *sample_;
  const CameraInfo& cam = camera_->info();
  const int s = options_.render_supersample, ss = s * s;
  const Rigid3d sample_from_cam = cam.cam_from_sample.Inverse();
  const Eigen::Vector3d eye = sample_from_cam.translation;
  // Sample-plane point (z = 0) seen through a camera pixel coordinate; false if the ray misses.
  auto plane = [&](const Eigen::Vector2d& pixel, Eigen::Vector2d* guess, Eigen::Vector2d* x) {
    const Eigen::Vector3d ray_in_cam = PixelToCameraRay(cam, pixel, guess);
    *guess = ray_in_cam.head<2>();
    const Eigen::Vector3d ray = sample_from_cam.rotation * ray_in_cam;
    const double t = -eye.z() / ray.z();
    if (!(t > 0)) return false;
    *x = (eye + t * ray).head<2>();
    return true;
  };
  const size_t num_pixels = static_cast<size_t>(cam.width_px) * cam.height_px;
  direct_weights_.assign(num_pixels * ss, 1.0f);
  pixel_direct_.assign(num_pixels, 1);
  components_.clear();
  const std::vector<PointSource> black = BlockSources(nullptr, 1.0);
  std::vector<int> region_of(ss);
  for (int v = 0; v < cam.height_px; ++v) {
    Eigen::Vector2d guess((0.5 - cam.cx_px) / cam.fx_px, (v + 0.5 - cam.cy_px) / cam.fy_px);
    for (int u = 0; u < cam.width_px; ++u) {
      const int pixel = v * cam.width_px + u;
      const Eigen::Vector2d centre(u + 0.5, v + 0.5);
      Eigen::Vector2d c, xp, xm, yp, ym;
      const bool ok = plane(centre + Eigen::Vector2d(-0.5, 0), &guess, &xm) && plane(centre, &guess, &c) &&
                      plane(centre + Eigen::Vector2d(0.5, 0), &guess, &xp) &&
                      plane(centre + Eigen::Vector2d(0, -0.5), &guess, &ym) &&
                      plane(centre + Eigen::Vector2d(0, 0.5), &guess, &yp);
      if (!ok) continue;  // Sees no sample plane: direct view (weights 1).
      const Eigen::Vector2d ju = xp - xm, jv = yp - ym;
      float* w = &direct_weights_[pixel * static_cast<size_t>(ss)];
      bool any_direct = false;
      // Per region: sub-sample count and the sum of their positions.
      std::vector<std::pair<int, std::pair<int, Eigen::Vector2d>>> acc;
      for (int a = 0; a < s; ++a) {
        for (int b = 0; b < s; ++b) {
          const double du = (b + 0.5) / s - 0.5, dv = (a + 0.5) / s - 0.5;
          const Eigen::Vector2d x = c + du * ju + dv * jv;
          const int k = sample.RegionIndexAt(x);
          float& wk = w[a * s + b];
          if (k < 0) {
            wk = 1.0f;  // Off the sample: the monitor directly.
          } else {
            const SlabMaterial& m = sample.region(k).material;
            if (m.IsSmooth()) {
              const Eigen::Vector3d o = (eye - Eigen::Vector3d(x.x(), x.y(), 0)).normalized();
              wk = static_cast<float>(m.k_s * SlabSample::FlatSlabTransmittance(o.z(), m.eta));
            } else {
              wk = 0.0f;
            }
            if (!m.IsSmooth() || m.rho_d > 0) {
              auto it = std::find_if(acc.begin(), acc.end(), [&](const auto& e) { return e.first == k; });
              if (it == acc.end()) {
                acc.push_back({k, {1, x}});
              } else {
                ++it->second.first;
                it->second.second += x;
              }
            }
          }
          any_direct = any_direct || wk > 0;
        }
      }
      pixel_direct_[pixel] = any_direct ? 1 : 0;
      for (const auto& e : acc) {
        ScatterComponent comp;
        comp.pixel = pixel;
        comp.region = e.first;
        comp.weight = static_cast<float>(e.second.first) / ss;
        const Eigen::Vector2d xm2 = e.second.second / e.second.first;
        comp.x_in_sample = Eigen::Vector3d(xm2.x(), xm2.y(), 0);
        comp.view = (eye - comp.x_in_sample).normalized();
        comp.black_level_radiance = 0;
        if (options_.black_radiance > 0) comp.black_level_radiance = ScatteredRadiance(comp, black);
        components_.push_back(comp);
      }
    }
  }
  sample_map_for_ = sample_.get();
}

double SimDotMonitor::ScatteredRadiance(const ScatterComponent& c, const std::vector<PointSource>& sources) const {
  // L_o(x, o) = sum_q R(x, i_q, o) L_q A_q cos_e cos_i / r^2, R = rho_d + k_s rho (Dai Eq. 13);
  // the screen emits towards +z of the sample frame, so cos_e = |i.z| = cos_i for a parallel screen.
  const SlabSample& sample = *sample_;
  const Eigen::Vector3d emit_normal = -(monitor_.sample_from_monitor.rotation * Eigen::Vector3d::UnitZ());
  const SlabMaterial& m = sample.region(c.region).material;
  const bool thick = sample.options().thickness_m > 0 && sample.table(c.region) != nullptr;
  double sum = 0;
  for (const PointSource& q : sources) {
    // A slab of finite thickness: the light that crossed it once and, spread over several
    // places, the light that crossed it several times enter the monitor-side face where the
    // traced paths put them (SlabSample::LightEntryPoint), each found from the direction seen
    // from x and refined once with the direction seen from there; each part carries its share of
    // the cell's BTDF. The diffuse term enters with the first part.
    for (int part = 0; part < (thick ? SlabSample::kEntryParts : 1); ++part) {
      Eigen::Vector3d entry = c.x_in_sample;
      double share = 1;
      for (int pass = 0; pass < 2 && thick; ++pass) {
        entry = sample.LightEntryPoint(c.region, c.x_in_sample, (q.position_in_sample - entry).normalized(), c.view,
                                       part, &share);
      }
      const Eigen::Vector3d d = q.position_in_sample - entry;
      const double r2 = d.squaredNorm();
      const double r = std::sqrt(r2);
      const Eigen::Vector3d i = d / r;
      const double cos_i = std::abs(i.z()), cos_e = std::abs(emit_normal.dot(i));
      const double transmission = (part == 0 ? m.rho_d : 0.0) + share * m.k_s * sample.Btdf(c.region, i, c.view);
      sum += transmission * q.radiance_area * cos_e * cos_i / r2;
    }
  }
  return sum;
}

Image SimDotMonitor::RenderElectronsThroughSample() const {
  const SimDotMonitorOptions& o = options_;
  const CameraInfo& cam = camera_->info();
  if (screen_map_.empty()) BuildScreenMap();
  if (sample_map_for_ != sample_.get()) BuildSampleMap();
  const int s = o.render_supersample, ss = s * s;
  const double scale = o.electrons_per_radiance_us * camera_->integrated_exposure_us();
  Image out(cam.width_px, cam.height_px);
  // Direct view (off the sample and through smooth regions); a pixel whose screen footprint
  // misses every lit monitor pixel sees the black level alone (nothing when it is 0).
  for (int v = 0; v < cam.height_px; ++v) {
    for (int u = 0; u < cam.width_px; ++u) {
      const size_t pixel = static_cast<size_t>(v) * cam.width_px + u;
      if (!pixel_direct_[pixel]) continue;
      const double* e = &screen_map_[pixel * 6];
      if (e[0] < -1e29) continue;
      const bool black_only = MissesLitPixels(e);
      if (black_only && o.black_radiance <= 0) continue;
      const float* w = &direct_weights_[pixel * ss];
      double sum = 0;
      for (int a = 0; a < s; ++a) {
        for (int b = 0; b < s; ++b) {
          const float wk = w[a * s + b];
          if (wk <= 0) continue;
          sum += wk * (black_only ? BlackLevelRadiance(pixel, s, a, b) : DirectRadiance(e, s, a, b));
        }
      }
      out.at(u, v) = static_cast<float>(sum / ss * scale);
    }
  }
  // Light scattered by the rough regions (and the diffuse term): one table lookup per pixel and
  // point source.
  for (const ScatterComponent& c : components_) {
    double radiance = o.black_radiance * c.black_level_radiance;
    if (!sources_.empty()) radiance += ScatteredRadiance(c, sources_);
    out.data()[c.pixel] += static_cast<float>(c.weight * radiance * scale);
  }
  return out;
}

}  // namespace thinslab
