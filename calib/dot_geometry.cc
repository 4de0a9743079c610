// SPDX-License-Identifier: Apache-2.0
#include "calib/dot_geometry.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "core/camera_model.h"
#include "core/math.h"

namespace thinslab {

Status DotGeometryOptions::Check() const {
  if (!(dot_radius_px > 0)) return Status::Error("DotGeometryOptions::dot_radius_px: must be > 0 px");
  if (!(threshold_sigma > 0)) return Status::Error("DotGeometryOptions::threshold_sigma: must be > 0");
  if (!(threshold_fraction >= 0 && threshold_fraction < 1)) {
    return Status::Error("DotGeometryOptions::threshold_fraction: must be in [0, 1)");
  }
  if (!(min_peak_fraction >= 0 && min_peak_fraction < 1)) {
    return Status::Error("DotGeometryOptions::min_peak_fraction: must be in [0, 1)");
  }
  if (min_blob_area_px < 1) return Status::Error("DotGeometryOptions::min_blob_area_px: must be >= 1");
  if (window_margin_px < 0) return Status::Error("DotGeometryOptions::window_margin_px: must be >= 0");
  if (!(match_gate_fraction > 0 && match_gate_fraction < 0.5)) {
    return Status::Error("DotGeometryOptions::match_gate_fraction: must be in (0, 0.5)");
  }
  return Status::Ok();
}

bool BackProjectToMonitor(const CameraInfo& camera, const Rigid3d& sample_from_monitor, const Eigen::Vector2d& pixel,
                          Eigen::Vector3d* x_in_sample) {
  const Rigid3d monitor_from_cam = [&] {
    const Rigid3d monitor_from_sample = sample_from_monitor.Inverse();
    const Rigid3d sample_from_cam = camera.cam_from_sample.Inverse();
    Rigid3d m;
    m.rotation = monitor_from_sample.rotation * sample_from_cam.rotation;
    m.translation = monitor_from_sample * sample_from_cam.translation;
    return m;
  }();
  const Eigen::Vector3d ray = monitor_from_cam.rotation * PixelToCameraRay(camera, pixel);
  const Eigen::Vector3d eye = monitor_from_cam.translation;
  if (std::abs(ray.z()) < 1e-12) return false;
  const double t = -eye.z() / ray.z();
  if (!(t > 0)) return false;
  *x_in_sample = sample_from_monitor * (eye + t * ray);
  return true;
}

namespace {

struct Blob {
  Eigen::Vector2d centroid_px;   // thinslab pixel coordinates.
  Eigen::Vector2d normalized;    // Undistorted normalised camera coordinates.
  double flux_dn_per_us = 0;     // Background-subtracted sum over the window.
  double peak = 0;
  bool saturated = false;
  bool clipped = false;          // Its window reaches the image border: centroid and flux are cut.
};

double Median(std::vector<float> v) {
  if (v.empty()) return 0;
  const size_t mid = v.size() / 2;
  std::nth_element(v.begin(), v.begin() + mid, v.end());
  return v[mid];
}

Eigen::Vector2d ApplyH(const Eigen::Matrix3d& H, const Eigen::Vector2d& p) {
  const Eigen::Vector3d q = H * Eigen::Vector3d(p.x(), p.y(), 1.0);
  return q.head<2>() / q.z();
}

// Matches displayed dots (monitor px) to blobs through homography H (monitor px -> normalised
// image), refits H on the matches with RANSAC and repeats. Returns the number of matches and
// fills match[d] = blob index or -1.
int MatchWithHomography(Eigen::Matrix3d H, const std::vector<Eigen::Vector2d>& dots, const std::vector<Blob>& blobs,
                        double gate_fraction, double ransac_threshold, std::vector<int>* match, Eigen::Matrix3d* H_out) {
  const size_t nd = dots.size(), nb = blobs.size();
  // Each dot's nearest displayed neighbour (monitor px), once: the local spacing in the image
  // is then the distance between their predictions.
  std::vector<size_t> neighbour(nd, 0);
  for (size_t d = 0; d < nd; ++d) {
    double best = std::numeric_limits<double>::infinity();
    for (size_t e = 0; e < nd; ++e) {
      const double dist = (dots[e] - dots[d]).squaredNorm();
      if (e != d && dist < best) {
        best = dist;
        neighbour[d] = e;
      }
    }
  }
  int num = 0;
  for (int iter = 0; iter < 4; ++iter) {
    std::vector<Eigen::Vector2d> pred(nd);
    for (size_t d = 0; d < nd; ++d) pred[d] = ApplyH(H, dots[d]);
    std::vector<int> m(nd, -1);
    std::vector<double> best_dist(nb, std::numeric_limits<double>::infinity());
    std::vector<int> owner(nb, -1);
    for (size_t d = 0; d < nd; ++d) {
      if (!pred[d].allFinite()) continue;
      double spacing = (pred[neighbour[d]] - pred[d]).norm();
      if (!std::isfinite(spacing) || !(spacing > 0)) continue;
      int best = -1;
      double best_d = gate_fraction * spacing;
      for (size_t b = 0; b < nb; ++b) {
        const double dist = (blobs[b].normalized - pred[d]).norm();
        if (dist < best_d) {
          best_d = dist;
          best = static_cast<int>(b);
        }
      }
      if (best < 0) continue;
      if (best_d < best_dist[best]) {  // A blob belongs to at most one dot: the closer one.
        if (owner[best] >= 0) m[owner[best]] = -1;
        best_dist[best] = best_d;
        owner[best] = static_cast<int>(d);
        m[d] = best;
      }
    }
    std::vector<cv::Point2d> src, dst;
    for (size_t d = 0; d < nd; ++d) {
      if (m[d] < 0) continue;
      src.emplace_back(dots[d].x(), dots[d].y());
      dst.emplace_back(blobs[m[d]].normalized.x(), blobs[m[d]].normalized.y());
    }
    num = static_cast<int>(src.size());
    *match = m;
    if (num < 4) break;
    cv::Mat inliers;
    const cv::Mat Hcv = cv::findHomography(src, dst, cv::RANSAC, ransac_threshold, inliers, 2000, 0.999);
    if (Hcv.empty()) break;
    for (int r = 0; r < 3; ++r) {
      for (int c = 0; c < 3; ++c) H(r, c) = Hcv.at<double>(r, c);
    }
  }
  *H_out = H;
  return num;
}

// Four corners of the convex hull of `points` (approxPolyDP with a growing tolerance), or empty.
std::vector<cv::Point2f> HullCorners(const std::vector<Eigen::Vector2d>& points) {
  std::vector<cv::Point2f> pts, hull;
  for (const Eigen::Vector2d& p : points) pts.emplace_back(static_cast<float>(p.x()), static_cast<float>(p.y()));
  if (pts.size() < 4) return {};
  cv::convexHull(pts, hull);
  const double perimeter = cv::arcLength(hull, true);
  for (double eps = 0.005; eps < 0.2; eps *= 1.3) {
    std::vector<cv::Point2f> approx;
    cv::approxPolyDP(hull, approx, eps * perimeter, true);
    if (approx.size() == 4) return approx;
    if (approx.size() < 4) break;
  }
  return {};
}

// Unit normal of the monitor plane pointing to the camera's side (sample frame).
Eigen::Vector3d TowardsCamera(const CameraInfo& camera, const MonitorInfo& monitor) {
  const Eigen::Vector3d n = monitor.sample_from_monitor.rotation * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d centre = camera.cam_from_sample.Inverse().translation;
  return n.dot(centre - monitor.sample_from_monitor.translation) >= 0 ? n : Eigen::Vector3d(-n);
}

// Back-projects the matched blobs onto `monitor`'s plane (positions, L_q), fits the in-plane
// rigid correction and the grid's scale. Fills the per-dot records and the geometry fields of
// *out (the detection fields are the caller's).
Status FitGridOnPlane(const CameraInfo& camera, const MonitorInfo& monitor,
                      const std::vector<Eigen::Vector2d>& displayed_dots_px, const std::vector<Blob>& blobs,
                      const std::vector<int>& match, const DotGeometryOptions& options, DotGeometryResult* result) {
  DotGeometryResult& out = *result;
  out.dots.clear();
  out.max_residual_m = 0;
  const Rigid3d monitor_from_sample = monitor.sample_from_monitor.Inverse();
  const double pitch = monitor.pixel_pitch_m;
  std::vector<Eigen::Vector2d> grid_m, measured_m;
  for (size_t d = 0; d < displayed_dots_px.size(); ++d) {
    DotRecord rec;
    rec.dot_px = displayed_dots_px[d];
    if (match[d] >= 0) {
      const Blob& blob = blobs[match[d]];
      Eigen::Vector3d x_in_sample;
      if (BackProjectToMonitor(camera, monitor.sample_from_monitor, blob.centroid_px, &x_in_sample)) {
        rec.detected = true;
        rec.centroid_px = blob.centroid_px;
        rec.position_in_sample_m = x_in_sample;
        rec.saturated = blob.saturated;
        rec.clipped = blob.clipped;
      }
      if (rec.detected && !rec.clipped) {
        // L_q = integrated signal / projected dot area in camera px. The area is the dot's
        // area on the screen (pi r^2 pitch^2) times |det| of d(pixel)/d(screen metres), taken by
        // central differences through the full camera model (distortion included).
        const Eigen::Vector3d ex = monitor.sample_from_monitor.rotation * Eigen::Vector3d::UnitX();
        const Eigen::Vector3d ey = monitor.sample_from_monitor.rotation * Eigen::Vector3d::UnitY();
        const double step = 0.5 * pitch;
        Eigen::Vector2d pxp, pxm, pyp, pym;
        const bool ok = ProjectSamplePoint(camera, x_in_sample + step * ex, &pxp) &&
                        ProjectSamplePoint(camera, x_in_sample - step * ex, &pxm) &&
                        ProjectSamplePoint(camera, x_in_sample + step * ey, &pyp) &&
                        ProjectSamplePoint(camera, x_in_sample - step * ey, &pym);
        if (ok) {
          Eigen::Matrix2d J;
          J.col(0) = (pxp - pxm) / (2 * step);
          J.col(1) = (pyp - pym) / (2 * step);
          const double area_px = std::abs(J.determinant()) * kPi * Sqr(options.dot_radius_px * pitch);
          rec.radiance_dn_per_us = area_px > 0 ? blob.flux_dn_per_us / area_px : 0;
        }
        const Eigen::Vector3d in_monitor = monitor_from_sample * x_in_sample;
        grid_m.emplace_back(rec.dot_px * pitch);
        measured_m.emplace_back(in_monitor.head<2>());
      }
    }
    out.dots.push_back(rec);
  }
  if (grid_m.size() < 3) {
    return Status::Error("dots: fewer than 3 dots inside the frame back-project onto the monitor plane");
  }

  // In-plane rigid correction (2D Procrustes, no scale: the pitch is known) of the nominal
  // monitor pose: measured ~ R * grid + t in monitor coordinates.
  Eigen::Vector2d mean_g = Eigen::Vector2d::Zero(), mean_m = Eigen::Vector2d::Zero();
  for (size_t k = 0; k < grid_m.size(); ++k) {
    mean_g += grid_m[k];
    mean_m += measured_m[k];
  }
  mean_g /= grid_m.size();
  mean_m /= grid_m.size();
  Eigen::Matrix2d cov = Eigen::Matrix2d::Zero();
  for (size_t k = 0; k < grid_m.size(); ++k) cov += (measured_m[k] - mean_m) * (grid_m[k] - mean_g).transpose();
  const double angle = std::atan2(cov(1, 0) - cov(0, 1), cov(0, 0) + cov(1, 1));
  const Eigen::Matrix2d R = Eigen::Rotation2Dd(angle).toRotationMatrix();
  const Eigen::Vector2d t = mean_m - R * mean_g;
  Rigid3d correction;  // monitor_nominal_from_monitor_refined.
  correction.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()));
  correction.translation = Eigen::Vector3d(t.x(), t.y(), 0);
  out.sample_from_monitor.rotation = (monitor.sample_from_monitor.rotation * correction.rotation).normalized();
  out.sample_from_monitor.translation = monitor.sample_from_monitor * correction.translation;
  out.in_plane_correction_m = t.norm();
  out.in_plane_correction_rad = angle;
  double sum2 = 0;
  size_t k = 0;
  for (DotRecord& rec : out.dots) {
    if (!rec.detected || rec.clipped) {
      // Outside the camera's view, lost in the background, or cut by the image border: placed
      // from the fitted monitor geometry (the monitor lights the sample from there all the same).
      rec.placed_from_geometry = true;
      rec.position_in_sample_m =
          out.sample_from_monitor * Eigen::Vector3d(rec.dot_px.x() * pitch, rec.dot_px.y() * pitch, 0);
      continue;
    }
    rec.residual_m = (R * grid_m[k] + t - measured_m[k]).norm();
    sum2 += Sqr(rec.residual_m);
    out.max_residual_m = std::max(out.max_residual_m, rec.residual_m);
    ++k;
  }
  out.rms_residual_m = std::sqrt(sum2 / grid_m.size());

  // Not in Dai et al.: the grid's scale, s = sum (m - mean_m) . R (g - mean_g) / sum |g - mean_g|^2
  // (the least-squares similarity with the rotation above). The pitch is known, so s != 1 says
  // the plane is at the wrong distance: between parallel planes, back-projection through the
  // camera centre is a homothety of ratio h_plane / h_true (h: the centre's distance to the
  // plane), so the plane is delta = h (1 - 1/s) too far from the camera.
  double sum_g2 = 0, sum_mg = 0;
  for (size_t j = 0; j < grid_m.size(); ++j) {
    sum_g2 += (grid_m[j] - mean_g).squaredNorm();
    sum_mg += (measured_m[j] - mean_m).dot(R * (grid_m[j] - mean_g));
  }
  out.grid_scale = sum_g2 > 0 ? sum_mg / sum_g2 : 1;
  double similarity_ssr = 0;
  for (size_t j = 0; j < grid_m.size(); ++j) {
    similarity_ssr += (out.grid_scale * R * (grid_m[j] - mean_g) + mean_m - measured_m[j]).squaredNorm();
  }
  const double h = TowardsCamera(camera, monitor).dot(camera.cam_from_sample.Inverse().translation -
                                                      monitor.sample_from_monitor.translation);
  out.camera_to_plane_m = h;
  out.distance_error_m = h * (1 - 1 / out.grid_scale);
  // Statistical only (residuals as independent): calibration errors of the camera add a
  // systematic part (docs/models/geometric_calibration.md, 3.7).
  const double dof = std::max<double>(1, 2.0 * grid_m.size() - 4);
  const double sigma_scale = sum_g2 > 0 ? std::sqrt(similarity_ssr / dof / sum_g2) : 0;
  out.distance_error_sigma_m = h * sigma_scale / Sqr(out.grid_scale);
  return Status::Ok();
}

}  // namespace

Status CalibrateDotGeometry(const Image& frame_dn, double exposure_us, double saturation_dn, const CameraInfo& camera,
                            const MonitorInfo& monitor, const std::vector<Eigen::Vector2d>& displayed_dots_px,
                            const DotGeometryOptions& options, DotGeometryResult* result) {
  THINSLAB_RETURN_IF_ERROR(options.Check());
  if (frame_dn.empty() || frame_dn.num_channels() != 1) return Status::Error("dots: all-dots frame is empty or not single-channel");
  if (frame_dn.width() != camera.width_px || frame_dn.height() != camera.height_px) {
    return Status::Error("dots: frame is " + std::to_string(frame_dn.width()) + "x" + std::to_string(frame_dn.height()) +
                         ", camera '" + camera.id + "' is " + std::to_string(camera.width_px) + "x" +
                         std::to_string(camera.height_px));
  }
  if (!(exposure_us > 0)) return Status::Error("dots: exposure must be > 0 us");
  if (!(camera.fx_px > 0) || !(camera.fy_px > 0)) return Status::Error("dots: camera '" + camera.id + "' has no intrinsics");
  if (!(monitor.pixel_pitch_m > 0)) return Status::Error("dots: rig.monitor.pixel_pitch_m must be > 0");
  if (displayed_dots_px.size() < 4) {
    return Status::Error("dots: need at least 4 displayed dots, got " + std::to_string(displayed_dots_px.size()));
  }
  const int w = frame_dn.width(), h = frame_dn.height();

  // Background and noise: the dots cover a small part of the frame, so the median is the
  // background (CRT black level + stray light) and 1.4826 MAD the noise.
  const double inv_t = 1.0 / exposure_us;
  std::vector<float> values(frame_dn.data().begin(), frame_dn.data().end());
  const double background = Median(values);
  for (float& v : values) v = static_cast<float>(std::abs(v - background));
  double noise = 1.4826 * Median(values);
  if (!(noise > 0)) noise = 0.5;  // Noise-free quantised frames: half a DN.
  cv::Mat frame_cv(h, w, CV_32FC1, const_cast<float*>(frame_dn.data().data())), box;
  cv::blur(frame_cv, box, cv::Size(3, 3));
  double brightest = 0;
  cv::minMaxLoc(box, nullptr, &brightest);
  const double threshold =
      background + std::max(options.threshold_sigma * noise, options.threshold_fraction * (brightest - background));

  cv::Mat mask(h, w, CV_8UC1, cv::Scalar(0));
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) mask.at<uint8_t>(y, x) = frame_dn.at(x, y) > threshold ? 255 : 0;
  }
  cv::Mat labels, stats, centroids;
  const int num_labels = cv::connectedComponentsWithStats(mask, labels, stats, centroids, 8, CV_32S);
  std::vector<Blob> blobs;
  // Windows of neighbouring dots may overlap on dense grids: each pixel counts only for the
  // blob whose (threshold) centroid is nearest, a Voronoi split of the frame.
  std::vector<int> kept;
  for (int l = 1; l < num_labels; ++l) {
    if (stats.at<int>(l, cv::CC_STAT_AREA) >= options.min_blob_area_px) kept.push_back(l);
  }
  const int m = options.window_margin_px;
  auto window = [&](int l, int* x0, int* y0, int* x1, int* y1) {
    *x0 = std::max(0, stats.at<int>(l, cv::CC_STAT_LEFT) - m);
    *y0 = std::max(0, stats.at<int>(l, cv::CC_STAT_TOP) - m);
    *x1 = std::min(w - 1, stats.at<int>(l, cv::CC_STAT_LEFT) + stats.at<int>(l, cv::CC_STAT_WIDTH) - 1 + m);
    *y1 = std::min(h - 1, stats.at<int>(l, cv::CC_STAT_TOP) + stats.at<int>(l, cv::CC_STAT_HEIGHT) - 1 + m);
  };
  auto centre = [&](int l) {
    return Eigen::Vector2d(centroids.at<double>(l, 0) + 0.5, centroids.at<double>(l, 1) + 0.5);
  };
  for (int l : kept) {
    int x0, y0, x1, y1;
    window(l, &x0, &y0, &x1, &y1);
    std::vector<Eigen::Vector2d> neighbours;
    for (int o : kept) {
      if (o == l) continue;
      int ox0, oy0, ox1, oy1;
      window(o, &ox0, &oy0, &ox1, &oy1);
      if (ox0 <= x1 && ox1 >= x0 && oy0 <= y1 && oy1 >= y0) neighbours.push_back(centre(o));
    }
    const Eigen::Vector2d own = centre(l);
    Blob blob;
    blob.clipped = stats.at<int>(l, cv::CC_STAT_LEFT) < m || stats.at<int>(l, cv::CC_STAT_TOP) < m ||
                   stats.at<int>(l, cv::CC_STAT_LEFT) + stats.at<int>(l, cv::CC_STAT_WIDTH) > w - m ||
                   stats.at<int>(l, cv::CC_STAT_TOP) + stats.at<int>(l, cv::CC_STAT_HEIGHT) > h - m;
    double sw = 0, sx = 0, sy = 0, flux = 0;
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2d p(x + 0.5, y + 0.5);
        const double own_d2 = (p - own).squaredNorm();
        bool mine = true;
        for (const Eigen::Vector2d& n : neighbours) mine = mine && (p - n).squaredNorm() >= own_d2;
        if (!mine) continue;
        const double v = frame_dn.at(x, y);
        const double s = v - background;
        flux += s;
        // Intensity-weighted centroid of the background-subtracted signal (negative noise
        // excursions clamped so they cannot pull the centroid).
        const double wgt = std::max(0.0, s);
        sw += wgt;
        sx += wgt * (x + 0.5);
        sy += wgt * (y + 0.5);
        blob.peak = std::max(blob.peak, s);
        if (saturation_dn > 0 && v >= saturation_dn) blob.saturated = true;
      }
    }
    if (!(sw > 0)) continue;
    blob.centroid_px = Eigen::Vector2d(sx / sw, sy / sw);
    blob.flux_dn_per_us = flux * inv_t;
    const Eigen::Vector3d ray = PixelToCameraRay(camera, blob.centroid_px);
    blob.normalized = ray.head<2>();
    blobs.push_back(blob);
  }
  if (!blobs.empty() && options.min_peak_fraction > 0) {
    std::vector<float> peaks;
    for (const Blob& b : blobs) peaks.push_back(static_cast<float>(b.peak));
    const double cut = options.min_peak_fraction * Median(peaks);
    blobs.erase(std::remove_if(blobs.begin(), blobs.end(), [&](const Blob& b) { return b.peak < cut; }), blobs.end());
  }
  if (blobs.size() < 4) {
    return Status::Error("dots: found " + std::to_string(blobs.size()) + " dots in the all-dots frame (background " +
                         std::to_string(background) + " DN, threshold " + std::to_string(threshold) +
                         " DN); need at least 4: check exposure and that the monitor is in view");
  }

  // Matching hypotheses: (A) the nominal geometry, (B) hull corners of blobs <-> hull corners
  // of the displayed grid in each of the 8 correspondences of two quadrilaterals.
  std::vector<Eigen::Matrix3d> seeds;
  bool have_nominal = false;
  {
    // Nominal H from four grid points projected through the manifest geometry (no distortion:
    // normalised coordinates).
    std::vector<cv::Point2d> src, dst;
    Eigen::Vector2d lo = displayed_dots_px.front(), hi = lo;
    for (const Eigen::Vector2d& p : displayed_dots_px) {
      lo = lo.cwiseMin(p);
      hi = hi.cwiseMax(p);
    }
    const Eigen::Vector2d quad[4] = {{lo.x(), lo.y()}, {hi.x(), lo.y()}, {hi.x(), hi.y()}, {lo.x(), hi.y()}};
    bool ok = true;
    for (const Eigen::Vector2d& q : quad) {
      const Eigen::Vector3d x_in_cam =
          camera.cam_from_sample * (monitor.sample_from_monitor * Eigen::Vector3d(q.x() * monitor.pixel_pitch_m,
                                                                                  q.y() * monitor.pixel_pitch_m, 0));
      if (!(x_in_cam.z() > 0)) ok = false;
      src.emplace_back(q.x(), q.y());
      dst.emplace_back(x_in_cam.x() / x_in_cam.z(), x_in_cam.y() / x_in_cam.z());
    }
    if (ok && (hi - lo).cwiseAbs().minCoeff() > 0) {
      const cv::Mat H = cv::getPerspectiveTransform(std::vector<cv::Point2f>(src.begin(), src.end()),
                                                    std::vector<cv::Point2f>(dst.begin(), dst.end()));
      Eigen::Matrix3d He;
      for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 3; ++c) He(r, c) = H.at<double>(r, c);
      }
      seeds.push_back(He);
      have_nominal = true;
    }
  }
  {
    std::vector<Eigen::Vector2d> blob_pts;
    for (const Blob& b : blobs) blob_pts.push_back(b.normalized);
    const std::vector<cv::Point2f> grid_quad = HullCorners(displayed_dots_px), blob_quad = HullCorners(blob_pts);
    if (grid_quad.size() == 4 && blob_quad.size() == 4) {
      for (int reverse = 0; reverse < 2; ++reverse) {
        for (int shift = 0; shift < 4; ++shift) {
          std::vector<cv::Point2f> dst(4);
          for (int k = 0; k < 4; ++k) dst[k] = blob_quad[reverse ? (shift - k + 8) % 4 : (shift + k) % 4];
          const cv::Mat H = cv::getPerspectiveTransform(grid_quad, dst);
          Eigen::Matrix3d He;
          for (int r = 0; r < 3; ++r) {
            for (int c = 0; c < 3; ++c) He(r, c) = H.at<double>(r, c);
          }
          seeds.push_back(He);
        }
      }
    }
  }
  if (seeds.empty()) return Status::Error("dots: cannot seed the grid match (nominal monitor not in front of the camera?)");
  const double ransac_threshold = 1.5 / camera.fx_px;  // 1.5 px in normalised units.
  // A regular grid matches itself after a half or quarter turn or a mirror, so several seeds
  // can match every dot; among those with the most matches (less one), the nominal geometry
  // decides: the hypothesis whose dot predictions are closest to the nominal ones wins.
  struct Hypothesis {
    int num = 0;
    std::vector<int> match;
    Eigen::Matrix3d H;
    double distance_to_nominal = 0;
  };
  std::vector<Hypothesis> hypotheses;
  int best_num = -1;
  for (const Eigen::Matrix3d& seed : seeds) {
    Hypothesis hyp;
    hyp.num = MatchWithHomography(seed, displayed_dots_px, blobs, options.match_gate_fraction, ransac_threshold,
                                  &hyp.match, &hyp.H);
    for (const Eigen::Vector2d& dot : displayed_dots_px) {
      if (!have_nominal) break;
      hyp.distance_to_nominal += (ApplyH(hyp.H, dot) - ApplyH(seeds.front(), dot)).norm();
    }
    if (!std::isfinite(hyp.distance_to_nominal)) hyp.distance_to_nominal = std::numeric_limits<double>::max();
    best_num = std::max(best_num, hyp.num);
    hypotheses.push_back(std::move(hyp));
  }
  const Hypothesis* chosen = nullptr;
  for (const Hypothesis& hyp : hypotheses) {
    if (hyp.num < best_num - 1) continue;  // A grid shifted by one row or column loses a row.
    if (chosen == nullptr || hyp.distance_to_nominal < chosen->distance_to_nominal) chosen = &hyp;
  }
  best_num = chosen ? chosen->num : 0;
  std::vector<int> match = chosen ? chosen->match : std::vector<int>();
  const Eigen::Matrix3d H = chosen ? chosen->H : Eigen::Matrix3d::Identity();
  double best_rms = 0;
  for (size_t d = 0; d < match.size(); ++d) {
    if (match[d] >= 0) best_rms += (ApplyH(H, displayed_dots_px[d]) - blobs[match[d]].normalized).squaredNorm();
  }
  best_rms = best_num > 0 ? std::sqrt(best_rms / best_num) : 0;
  if (best_num < 4) {
    return Status::Error("dots: could not match the " + std::to_string(blobs.size()) + " detected dots to the " +
                         std::to_string(displayed_dots_px.size()) + " displayed ones");
  }

  DotGeometryResult out;
  out.num_blobs = static_cast<int>(blobs.size());
  out.num_matched = best_num;
  out.num_unmatched_blobs = out.num_blobs - best_num;
  for (size_t d = 0; d < match.size(); ++d) out.num_clipped += match[d] >= 0 && blobs[match[d]].clipped;
  out.background_dn_per_us = background * inv_t;
  out.noise_dn_per_us = noise * inv_t;
  out.homography_rms_px = best_rms * camera.fx_px;
  // Dai Section 4.1: "projected to the 3D plane (x, y, d)", with d from the manifest; with
  // options.refine_distance the plane is moved along its normal until the back-projected grid
  // has the displayed pitch (FitGridOnPlane; docs/models/geometric_calibration.md, 3.7).
  MonitorInfo plane = monitor;
  THINSLAB_RETURN_IF_ERROR(FitGridOnPlane(camera, plane, displayed_dots_px, blobs, match, options, &out));
  for (int pass = 0; options.refine_distance && pass < 8 && std::abs(out.distance_error_m) > 1e-7; ++pass) {
    plane.sample_from_monitor.translation += out.distance_error_m * TowardsCamera(camera, plane);
    THINSLAB_RETURN_IF_ERROR(FitGridOnPlane(camera, plane, displayed_dots_px, blobs, match, options, &out));
  }
  out.distance_correction_m = TowardsCamera(camera, monitor).dot(plane.sample_from_monitor.translation -
                                                                 monitor.sample_from_monitor.translation);
  *result = std::move(out);
  return Status::Ok();
}

std::string MonitorDistanceWarning(double distance_error_m, double distance_error_sigma_m) {
  if (std::abs(distance_error_m) <= std::max(kMonitorDistanceWarningM, 5 * distance_error_sigma_m)) return "";
  char text[400];
  std::snprintf(text, sizeof(text),
                "the displayed dot grid's scale says the monitor plane is %.2f mm (+- %.3f mm) %s the camera than "
                "rig.monitor puts it (distance d %s); the dot positions are off by about as much. Measure d again, "
                "or let the grid's scale set it: calib dots --refine-distance, fit dmf --refine-monitor-distance",
                std::abs(distance_error_m) * 1e3, distance_error_sigma_m * 1e3,
                distance_error_m > 0 ? "nearer to" : "further from", distance_error_m > 0 ? "too large" : "too small");
  return text;
}

}  // namespace thinslab

