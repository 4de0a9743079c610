// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/dot_geometry.h"

#include <Eigen/LU>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <optional>
#include <unordered_map>
#include <utility>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "thinslab/core/camera_model.h"
#include "thinslab/core/math.h"

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
  if (window_margin_px < 0 || window_margin_px > 1000) {
    return Status::Error("DotGeometryOptions::window_margin_px: must be in [0, 1000] px");
  }
  if (!(peak_separation_fraction > 0 && peak_separation_fraction < 1)) {
    return Status::Error("DotGeometryOptions::peak_separation_fraction: must be in (0, 1)");
  }
  if (background_window_px < 0 || background_window_px > 4001) {
    return Status::Error("DotGeometryOptions::background_window_px: must be in [0, 4001] px (0: from the dot size)");
  }
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
  double peak = 0;               // Highest smoothed level above the background.
  int pixels_above_threshold = 0; // Pixels of its window whose smoothed level is above the threshold.
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

// Thinslab pixel of undistorted normalised camera coordinates (as ProjectSamplePoint).
Eigen::Vector2d NormalizedToPixel(const CameraInfo& camera, const Eigen::Vector2d& xy) {
  const Eigen::Vector2d d = DistortNormalized(camera.distortion, xy);
  return Eigen::Vector2d(camera.fx_px * d.x() + camera.cx_px + 0.5, camera.fy_px * d.y() + camera.cy_px + 0.5);
}

// Index of each point's nearest other point (O(n^2): grids of a few thousand dots).
std::vector<size_t> NearestNeighbours(const std::vector<Eigen::Vector2d>& points) {
  std::vector<size_t> neighbour(points.size(), 0);
  for (size_t d = 0; d < points.size(); ++d) {
    double best = std::numeric_limits<double>::infinity();
    for (size_t e = 0; e < points.size(); ++e) {
      const double dist = (points[e] - points[d]).squaredNorm();
      if (e != d && dist < best) {
        best = dist;
        neighbour[d] = e;
      }
    }
  }
  return neighbour;
}

// Points in square buckets of a fixed size, for "which points lie near p" in O(1).
class PointBuckets {
 public:
  explicit PointBuckets(double cell_px) : cell_(std::max(1.0, cell_px)) {}
  void Add(const Eigen::Vector2d& p, int id) { cells_[Key(Cell(p.x()), Cell(p.y()))].push_back({p, id}); }
  // Calls f(point, id) for every point within `reach` cells of p (reach * cell_px covers a radius).
  template <typename F>
  void ForNear(const Eigen::Vector2d& p, int reach, F f) const {
    const int64_t cx = Cell(p.x()), cy = Cell(p.y());
    for (int64_t y = cy - reach; y <= cy + reach; ++y) {
      for (int64_t x = cx - reach; x <= cx + reach; ++x) {
        const auto it = cells_.find(Key(x, y));
        if (it == cells_.end()) continue;
        for (const auto& [q, id] : it->second) f(q, id);
      }
    }
  }

 private:
  int64_t Cell(double v) const { return static_cast<int64_t>(std::floor(v / cell_)); }
  static uint64_t Key(int64_t x, int64_t y) {
    return (static_cast<uint64_t>(x) << 32) ^ (static_cast<uint64_t>(y) & 0xffffffffu);
  }
  double cell_;
  std::unordered_map<uint64_t, std::vector<std::pair<Eigen::Vector2d, int>>> cells_;
};

// Matches displayed dots (monitor px) to blobs through homography H (monitor px -> normalised
// image), refits H on the matches with RANSAC and repeats. Returns the number of matches and
// fills match[d] = blob index or -1. `neighbour[d]`: dot d's nearest displayed dot.
int MatchWithHomography(Eigen::Matrix3d H, const std::vector<Eigen::Vector2d>& dots,
                        const std::vector<size_t>& neighbour, const std::vector<Blob>& blobs, double gate_fraction,
                        double ransac_threshold, std::vector<int>* match, Eigen::Matrix3d* H_out) {
  const size_t nd = dots.size(), nb = blobs.size();
  // The local spacing in the image is the distance between the predictions of a dot and of its
  // nearest displayed neighbour.
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

// Step 1: how the nominal geometry maps the screen into the image at the displayed grid's centre.
struct DotImageScale {
  Eigen::Matrix2d px_per_monitor_px = Eigen::Matrix2d::Identity();  // J = d(camera px) / d(monitor px).
  double largest_stretch = 1;      // J's largest singular value.
  double spacing_monitor_px = 0;   // Median distance of a displayed dot to its nearest one.
  double dot_radius_image_px = 0;  // A dot's radius along the image's most stretched direction.
};

Status NominalDotImageScale(const CameraInfo& camera, const MonitorInfo& monitor,
                            const std::vector<Eigen::Vector2d>& dots, const std::vector<size_t>& neighbour,
                            double dot_radius_px, DotImageScale* out) {
  Eigen::Vector2d centre = Eigen::Vector2d::Zero();
  for (const Eigen::Vector2d& d : dots) centre += d;
  centre /= static_cast<double>(dots.size());
  const double pitch = monitor.pixel_pitch_m;
  auto project = [&](const Eigen::Vector2d& q, Eigen::Vector2d* px) {
    return ProjectSamplePoint(camera, monitor.sample_from_monitor * Eigen::Vector3d(q.x() * pitch, q.y() * pitch, 0),
                              px);
  };
  Eigen::Vector2d xp, xm, yp, ym;
  const bool ok = project(centre + Eigen::Vector2d(1, 0), &xp) && project(centre - Eigen::Vector2d(1, 0), &xm) &&
                  project(centre + Eigen::Vector2d(0, 1), &yp) && project(centre - Eigen::Vector2d(0, 1), &ym);
  Eigen::Matrix2d J;
  J.col(0) = 0.5 * (xp - xm);
  J.col(1) = 0.5 * (yp - ym);
  if (!ok || !J.allFinite() || !(std::abs(J.determinant()) > 1e-12)) {
    return Status::Error("dots: rig.monitor puts the displayed grid's centre behind camera '" + camera.id +
                         "' or edge-on to it: check rig.monitor.sample_from_monitor and the camera pose");
  }
  out->px_per_monitor_px = J;
  out->largest_stretch = Eigen::JacobiSVD<Eigen::Matrix2d>(J).singularValues()(0);
  std::vector<float> spacing;
  for (size_t d = 0; d < dots.size(); ++d) spacing.push_back(static_cast<float>((dots[neighbour[d]] - dots[d]).norm()));
  out->spacing_monitor_px = Median(spacing);
  out->dot_radius_image_px = dot_radius_px * out->largest_stretch;
  return Status::Ok();
}

// Step 2: the grey opening (erode, then dilate) of the 3x3 mean with a square window wider than a
// dot's image removes the dots and keeps what lies between them, however much of the frame they
// light; a box mean of the same size smooths the opening's blocks. Outside the frame counts as
// dark (the 5th percentile of the 3x3 means): a window cut by the border would otherwise fit
// inside a dot cut by it and keep it as background.
cv::Mat LocalBackground(const cv::Mat& box3, int window) {
  std::vector<float> values(reinterpret_cast<const float*>(box3.data),
                            reinterpret_cast<const float*>(box3.data) + box3.total());
  const size_t k = values.size() / 20;
  std::nth_element(values.begin(), values.begin() + k, values.end());
  const int pad = window / 2 + 1;
  cv::Mat padded, opened, smooth;
  cv::copyMakeBorder(box3, padded, pad, pad, pad, pad, cv::BORDER_CONSTANT, cv::Scalar(values[k]));
  const cv::Mat element = cv::getStructuringElement(cv::MORPH_RECT, cv::Size(window, window));
  cv::morphologyEx(padded, opened, cv::MORPH_OPEN, element);
  cv::blur(opened, smooth, cv::Size(window, window), cv::Point(-1, -1), cv::BORDER_REPLICATE);
  return smooth(cv::Rect(pad, pad, box3.cols, box3.rows)).clone();
}

// Noise sigma of one frame value at the background: d = (v(x+1, y) - v(x, y)) / sqrt(2) has one
// value's variance and, for white noise, is uncorrelated with the 3x3 mean that contains both
// values, so selecting the darkest 30 % of 3x3 means (above the local background) does not bias
// it. A grid lighting up to about 70 % of the frame leaves that much background.
double BackgroundNoise(const Image& frame, const cv::Mat& box3, const cv::Mat& background) {
  const int w = frame.width(), h = frame.height();
  std::vector<float> level;
  level.reserve(static_cast<size_t>(w) * h);
  for (int y = 1; y + 1 < h; ++y) {
    for (int x = 1; x + 1 < w; ++x) level.push_back(box3.at<float>(y, x) - background.at<float>(y, x));
  }
  if (level.empty()) return 0.5;
  std::vector<float> sorted = level;
  const size_t k = sorted.size() * 3 / 10;
  std::nth_element(sorted.begin(), sorted.begin() + k, sorted.end());
  const float cut = sorted[k];
  std::vector<float> differences;
  size_t i = 0;
  for (int y = 1; y + 1 < h; ++y) {
    for (int x = 1; x + 1 < w; ++x, ++i) {
      if (level[i] <= cut) differences.push_back(std::abs(frame.at(x + 1, y) - frame.at(x, y)) / std::sqrt(2.0f));
    }
  }
  const double noise = 1.4826 * Median(differences);
  return noise > 0 ? noise : 0.5;  // Noise-free quantised frames: half a DN.
}

// Step 3: the frame convolved with a Gaussian of sigma `sigma_monitor_px` on the screen, i.e.
// covariance sigma^2 J J^T in the image (at least half a pixel). A dot's image is a convex disc;
// blurred by a Gaussian it is log-concave, so unimodal: touching dots keep separate maxima and a
// dot's flat top does not break into several. The kernel is cut at 3 sigma and at most 64 px
// (a Gaussian cut to a box is still log-concave; dots that large need no finer smoothing).
cv::Mat SmoothLikeADot(const cv::Mat& frame, const Eigen::Matrix2d& J, double sigma_monitor_px) {
  const Eigen::Matrix2d cov = Sqr(sigma_monitor_px) * J * J.transpose() + 0.25 * Eigen::Matrix2d::Identity();
  const Eigen::Matrix2d info = cov.inverse();
  const int r = static_cast<int>(std::min(64.0, std::ceil(3 * std::sqrt(std::max(cov(0, 0), cov(1, 1))))));
  cv::Mat kernel(2 * r + 1, 2 * r + 1, CV_32FC1);
  double sum = 0;
  for (int y = -r; y <= r; ++y) {
    for (int x = -r; x <= r; ++x) {
      const Eigen::Vector2d d(x, y);
      const double v = std::exp(-0.5 * d.dot(info * d));
      kernel.at<float>(y + r, x + r) = static_cast<float>(v);
      sum += v;
    }
  }
  kernel /= sum;
  cv::Mat out;
  cv::filter2D(frame, out, CV_32F, kernel, cv::Point(-1, -1), 0, cv::BORDER_REPLICATE);
  return out;
}

// Local maxima of `height` at or above `threshold`, highest first, dropping any within
// `separation_monitor_px` (measured on the screen through J^-1) of a higher one. Returns thinslab
// pixel coordinates (centres at +0.5).
std::vector<Eigen::Vector2d> SeparatedMaxima(const cv::Mat& height, double threshold, const DotImageScale& scale,
                                             double separation_monitor_px) {
  cv::Mat dilated;
  cv::dilate(height, dilated, cv::Mat());
  std::vector<std::pair<float, Eigen::Vector2d>> candidates;
  for (int y = 0; y < height.rows; ++y) {
    for (int x = 0; x < height.cols; ++x) {
      const float v = height.at<float>(y, x);
      if (v >= threshold && v >= dilated.at<float>(y, x)) candidates.push_back({v, Eigen::Vector2d(x + 0.5, y + 0.5)});
    }
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  const Eigen::Matrix2d monitor_per_px = scale.px_per_monitor_px.inverse();
  PointBuckets accepted(separation_monitor_px * scale.largest_stretch);
  std::vector<Eigen::Vector2d> peaks;
  for (const auto& [v, p] : candidates) {
    bool separate = true;
    accepted.ForNear(p, 1, [&](const Eigen::Vector2d& q, int) {
      separate = separate && (monitor_per_px * (p - q)).norm() >= separation_monitor_px;
    });
    if (!separate) continue;
    accepted.Add(p, static_cast<int>(peaks.size()));
    peaks.push_back(p);
  }
  return peaks;
}

// Step 4: what a dot's measurement reads.
struct DotWindow {
  const Image& frame;          // DN, black removed.
  const cv::Mat& smooth;       // Smoothed like a dot's image (SmoothLikeADot): the detection's levels.
  const cv::Mat& background;   // Local background (DN).
  int half = 3;                // Half-size of the square window [px].
  double saturation_dn = 0;
  double inv_exposure = 1;
};

// Centroid, flux and flags of the dot seeded at `seed` (thinslab px). Pixels of the window nearer
// a seed in `others` belong to that dot. The window is re-centred on the centroid once. False if
// the window holds no signal.
bool MeasureDot(const DotWindow& in, const Eigen::Vector2d& seed, const std::vector<Eigen::Vector2d>& others,
                double threshold, const CameraInfo& camera, Blob* blob) {
  const int w = in.frame.width(), h = in.frame.height();
  Eigen::Vector2d centre = seed;
  for (int pass = 0; pass < 2; ++pass) {
    const int cx = static_cast<int>(std::floor(centre.x())), cy = static_cast<int>(std::floor(centre.y()));
    const int x0 = std::max(0, cx - in.half), x1 = std::min(w - 1, cx + in.half);
    const int y0 = std::max(0, cy - in.half), y1 = std::min(h - 1, cy + in.half);
    Blob b;
    double sw = 0, sx = 0, sy = 0, flux = 0;
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const Eigen::Vector2d p(x + 0.5, y + 0.5);
        const double own_d2 = (p - seed).squaredNorm();
        bool mine = true;
        for (const Eigen::Vector2d& n : others) mine = mine && (p - n).squaredNorm() >= own_d2;
        if (!mine) continue;
        const double v = in.frame.at(x, y);
        const double s = v - in.background.at<float>(y, x);
        flux += s;
        // Intensity-weighted centroid of the background-subtracted signal (negative noise
        // excursions clamped so they cannot pull the centroid).
        const double wgt = std::max(0.0, s);
        sw += wgt;
        sx += wgt * p.x();
        sy += wgt * p.y();
        const double level = in.smooth.at<float>(y, x) - in.background.at<float>(y, x);
        b.peak = std::max(b.peak, level);
        b.pixels_above_threshold += level > threshold;
        if (in.saturation_dn > 0 && v >= in.saturation_dn) b.saturated = true;
      }
    }
    if (!(sw > 0)) return false;
    centre = Eigen::Vector2d(sx / sw, sy / sw);
    b.centroid_px = centre;
    b.flux_dn_per_us = flux * in.inv_exposure;
    *blob = b;
  }
  const int cx = static_cast<int>(std::floor(centre.x())), cy = static_cast<int>(std::floor(centre.y()));
  blob->clipped = cx - in.half < 0 || cy - in.half < 0 || cx + in.half > w - 1 || cy + in.half > h - 1;
  blob->normalized = PixelToCameraRay(camera, blob->centroid_px).head<2>();
  return true;
}

// Measures a dot at every seed (nullopt where a seed's window holds no signal).
std::vector<std::optional<Blob>> MeasureDots(const DotWindow& in, const std::vector<Eigen::Vector2d>& seeds,
                                             double threshold, const CameraInfo& camera) {
  PointBuckets buckets(2 * in.half + 1);
  for (size_t k = 0; k < seeds.size(); ++k) buckets.Add(seeds[k], static_cast<int>(k));
  std::vector<std::optional<Blob>> blobs(seeds.size());
  for (size_t k = 0; k < seeds.size(); ++k) {
    std::vector<Eigen::Vector2d> others;
    buckets.ForNear(seeds[k], 2, [&](const Eigen::Vector2d& q, int id) {
      if (id != static_cast<int>(k)) others.push_back(q);
    });
    Blob blob;
    if (MeasureDot(in, seeds[k], others, threshold, camera, &blob)) blobs[k] = blob;
  }
  return blobs;
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
  const double inv_t = 1.0 / exposure_us;

  // 1. The dots' size and spacing in the image, from the nominal geometry.
  const std::vector<size_t> neighbour = NearestNeighbours(displayed_dots_px);  // Also for the matching.
  DotImageScale scale;
  THINSLAB_RETURN_IF_ERROR(
      NominalDotImageScale(camera, monitor, displayed_dots_px, neighbour, options.dot_radius_px, &scale));
  const int half = static_cast<int>(std::ceil(scale.dot_radius_image_px)) + options.window_margin_px;

  // 2. Local background and the noise at it.
  cv::Mat frame_cv(h, w, CV_32FC1, const_cast<float*>(frame_dn.data().data())), box3;
  cv::blur(frame_cv, box3, cv::Size(3, 3));
  const int background_window = options.background_window_px > 0 ? options.background_window_px : 2 * half + 1;
  cv::Mat background = LocalBackground(box3, background_window);
  const double noise = BackgroundNoise(frame_dn, box3, background);

  // 3. Dots as local maxima of the frame smoothed like a dot's image, one per spacing.
  const cv::Mat smooth = SmoothLikeADot(frame_cv, scale.px_per_monitor_px, 0.5 * options.dot_radius_px);
  cv::Mat height = smooth - background;
  double brightest = 0;
  cv::minMaxLoc(height, nullptr, &brightest);
  const double threshold = std::max(options.threshold_sigma * noise, options.threshold_fraction * brightest);
  const std::vector<Eigen::Vector2d> peaks =
      SeparatedMaxima(height, threshold, scale, options.peak_separation_fraction * scale.spacing_monitor_px);

  // 4. Centroids and fluxes, pixels shared by neighbouring windows split by the nearest dot.
  const DotWindow window{frame_dn, smooth, background, half, saturation_dn, inv_t};
  std::vector<Blob> blobs;
  for (const std::optional<Blob>& b : MeasureDots(window, peaks, threshold, camera)) {
    if (b && b->pixels_above_threshold >= options.min_blob_area_px) blobs.push_back(*b);
  }
  double peak_cut = 0;
  if (!blobs.empty() && options.min_peak_fraction > 0) {
    std::vector<float> peak_heights;
    for (const Blob& b : blobs) peak_heights.push_back(static_cast<float>(b.peak));
    peak_cut = options.min_peak_fraction * Median(peak_heights);
    blobs.erase(std::remove_if(blobs.begin(), blobs.end(), [&](const Blob& b) { return b.peak < peak_cut; }),
                blobs.end());
  }
  std::vector<float> background_values(reinterpret_cast<const float*>(background.data),
                                       reinterpret_cast<const float*>(background.data) + background.total());
  const double median_background = Median(background_values);
  if (blobs.size() < 4) {
    return Status::Error("dots: found " + std::to_string(blobs.size()) + " dots in the all-dots frame (background " +
                         std::to_string(median_background) + " DN, noise " + std::to_string(noise) + " DN, threshold " +
                         std::to_string(threshold) + " DN above the background); need at least 4: check exposure, " +
                         "that the monitor is in view, and rig.monitor's dot_radius_px (--dot-radius-px)");
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
    hyp.num = MatchWithHomography(seed, displayed_dots_px, neighbour, blobs, options.match_gate_fraction,
                                  ransac_threshold, &hyp.match, &hyp.H);
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
  out.num_unmatched_blobs = out.num_blobs - best_num;

  // 6. The grid as a prior: every displayed dot the homography puts inside the frame is measured
  // at its place, windows split among all of them, found or not. A dot the maxima missed (merged
  // into a neighbour's, or below a cut) is refined instead of lost, and a found dot's window no
  // longer takes a missed neighbour's light.
  std::vector<Eigen::Vector2d> seeds_px;
  std::vector<size_t> seed_dot;
  for (size_t d = 0; d < displayed_dots_px.size(); ++d) {
    Eigen::Vector2d px;
    if (match[d] >= 0) {
      px = blobs[match[d]].centroid_px;
    } else {
      const Eigen::Vector2d xy = ApplyH(H, displayed_dots_px[d]);
      if (!xy.allFinite() || xy.norm() > 10) continue;  // Far outside any lens's field.
      px = NormalizedToPixel(camera, xy);
      if (!(px.x() >= 0 && px.y() >= 0 && px.x() < w && px.y() < h)) continue;
    }
    seeds_px.push_back(px);
    seed_dot.push_back(d);
  }
  const std::vector<std::optional<Blob>> remeasured = MeasureDots(window, seeds_px, threshold, camera);
  std::vector<Blob> found;
  std::vector<int> found_of_dot(displayed_dots_px.size(), -1);
  for (size_t k = 0; k < seed_dot.size(); ++k) {
    const size_t d = seed_dot[k];
    std::optional<Blob> blob = remeasured[k];
    if (match[d] >= 0) {
      if (!blob) blob = blobs[match[d]];
    } else {
      // Missed by the maxima: a dot only if its window holds a dot's signal where the grid puts it.
      const Eigen::Vector2d predicted = ApplyH(H, displayed_dots_px[d]);
      const double spacing = (ApplyH(H, displayed_dots_px[neighbour[d]]) - predicted).norm();
      if (!blob || blob->peak < std::max(threshold, peak_cut) ||
          blob->pixels_above_threshold < options.min_blob_area_px ||
          !((blob->normalized - predicted).norm() < options.match_gate_fraction * spacing)) {
        continue;
      }
      ++out.num_found_by_grid_prior;
    }
    found_of_dot[d] = static_cast<int>(found.size());
    found.push_back(*blob);
  }
  blobs = std::move(found);
  match = std::move(found_of_dot);
  out.num_matched = static_cast<int>(blobs.size());
  for (const Blob& b : blobs) out.num_clipped += b.clipped;
  out.background_dn_per_us = median_background * inv_t;
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

double ResolveDotRadiusPx(double option_px, const MonitorInfo& monitor, std::string* source) {
  if (option_px > 0) {
    *source = "option";
    return option_px;
  }
  if (monitor.dot_radius_px > 0) {
    *source = "manifest";
    return monitor.dot_radius_px;
  }
  *source = "default";
  return kDefaultDotRadiusPx;
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

