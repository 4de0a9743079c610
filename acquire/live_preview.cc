// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/live_preview.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "thinslab/core/camera_model.h"

namespace thinslab {

std::string PreviewStatistics::Describe() const {
  std::ostringstream s;
  s << std::setprecision(3) << "saturated " << 100 * saturated_fraction << " %, peak " << 100 * peak_fraction
    << " % of range, mean " << 100 * mean_fraction << " %, focus " << focus;
  return s.str();
}

namespace {

double Range(const CameraInfo& camera) {
  const double range = camera.saturation_dn - camera.black_level_dn;
  return range > 0 && std::isfinite(range) ? range : 1.0;
}

void SetRgb(uint8_t* p, uint8_t r, uint8_t g, uint8_t b) {
  p[0] = r;
  p[1] = g;
  p[2] = b;
}

// A line of the outline, one pixel wide, clipped to the frame.
void DrawLine(PreviewPicture* picture, int frame_height, Eigen::Vector2d a, Eigen::Vector2d b) {
  const int steps = static_cast<int>(std::ceil((b - a).norm())) + 1;
  if (steps > 100000) return;
  for (int k = 0; k <= steps; ++k) {
    const Eigen::Vector2d p = a + (b - a) * (static_cast<double>(k) / steps);
    const int x = static_cast<int>(std::floor(p.x())), y = static_cast<int>(std::floor(p.y()));
    if (x >= 0 && y >= 0 && x < picture->width && y < frame_height) SetRgb(picture->at(x, y), 0, 255, 0);
  }
}

// The sample rectangle at height z, carried along `along` (unit z component < 0) from z = 0.
void DrawRegion(PreviewPicture* picture, int frame_height, const CameraInfo& camera, const SampleInfo& sample, double z,
                const Eigen::Vector3d& along) {
  const Eigen::Vector2d lo = sample.region_min_m, hi = sample.region_max_m;
  const Eigen::Vector2d corners[4] = {lo, {hi.x(), lo.y()}, hi, {lo.x(), hi.y()}};
  constexpr int kPerSide = 16;  // Sub-segments, so a distorted edge is drawn curved.
  for (int c = 0; c < 4; ++c) {
    Eigen::Vector2d previous;
    bool have_previous = false;
    for (int k = 0; k <= kPerSide; ++k) {
      const Eigen::Vector2d q = corners[c] + (corners[(c + 1) % 4] - corners[c]) * (static_cast<double>(k) / kPerSide);
      const Eigen::Vector3d point = Eigen::Vector3d(q.x(), q.y(), 0) + (z / along.z()) * along;
      Eigen::Vector2d pixel;
      const bool ok = ProjectSamplePoint(camera, point, &pixel);
      if (ok && have_previous) DrawLine(picture, frame_height, previous, pixel);
      previous = pixel;
      have_previous = ok;
    }
  }
}

}  // namespace

PreviewStatistics MeasurePreview(const Image& raw_dn, const CameraInfo& camera) {
  PreviewStatistics s;
  s.histogram.assign(256, 0);
  const double range = Range(camera), black = camera.black_level_dn;
  const size_t n = raw_dn.data().size();
  if (n == 0) return s;
  double sum = 0, sum_sq = 0, peak = 0;
  int64_t saturated = 0;
  for (float raw : raw_dn.data()) {
    const double v = raw - black;
    sum += v;
    sum_sq += v * v;
    peak = std::max(peak, v);
    saturated += raw >= camera.saturation_dn - 0.5;
    ++s.histogram[std::clamp(static_cast<int>(v / range * 256), 0, 255)];
  }
  s.saturated_fraction = static_cast<double>(saturated) / n;
  s.peak_fraction = peak / range;
  s.mean_fraction = sum / n / range;
  double laplacian_sq = 0;
  int64_t count = 0;
  for (int y = 1; y + 1 < raw_dn.height(); ++y) {
    for (int x = 1; x + 1 < raw_dn.width(); ++x) {
      const double l =
          4.0 * raw_dn.at(x, y) - raw_dn.at(x - 1, y) - raw_dn.at(x + 1, y) - raw_dn.at(x, y - 1) - raw_dn.at(x, y + 1);
      laplacian_sq += l * l;
      ++count;
    }
  }
  const double mean_sq = sum_sq / n;
  s.focus = count > 0 && mean_sq > 0 ? laplacian_sq / count / mean_sq : 0;
  return s;
}

PreviewPicture ComposePreview(const Image& raw_dn, const CameraInfo& camera, const RigInfo& rig,
                              const PreviewStatistics& statistics, double best_focus) {
  PreviewPicture picture;
  const int frame_height = raw_dn.height();
  picture.width = raw_dn.width();
  picture.height = frame_height + kPreviewHistogramHeight + kPreviewFocusBarHeight;
  picture.rgb.assign(static_cast<size_t>(picture.width) * picture.height * 3, 0);
  const double range = Range(camera);
  for (int y = 0; y < frame_height; ++y) {
    for (int x = 0; x < picture.width; ++x) {
      const double raw = raw_dn.at(x, y);
      if (raw >= camera.saturation_dn - 0.5) {
        SetRgb(picture.at(x, y), 255, 0, 0);
        continue;
      }
      const double f = std::clamp((raw - camera.black_level_dn) / range, 0.0, 1.0);
      const auto g = static_cast<uint8_t>(std::lround(255 * std::pow(f, 1 / 2.2)));
      SetRgb(picture.at(x, y), g, g, g);
    }
  }
  if (rig.sample.region_max_m.x() > rig.sample.region_min_m.x()) {
    DrawRegion(&picture, frame_height, camera, rig.sample, 0, Eigen::Vector3d(0, 0, -1));
    if (rig.board.present && rig.board.distance_m > 0) {
      const Eigen::Vector3d along = rig.projector.present && rig.projector.direction_in_sample.z() < -1e-6
                                        ? rig.projector.direction_in_sample
                                        : Eigen::Vector3d(0, 0, -1);
      DrawRegion(&picture, frame_height, camera, rig.sample, -rig.board.distance_m, along);
    }
  }
  // Histogram: 256 bins across the width, bar height log(1 + count) over the largest.
  double top = 0;
  for (int64_t c : statistics.histogram) top = std::max(top, std::log1p(static_cast<double>(c)));
  for (int x = 0; x < picture.width && top > 0; ++x) {
    // Column 0 is bin 0 and the last column the saturated bin 255, whatever the width.
    const int bin = picture.width > 1 ? x * 255 / (picture.width - 1) : 255;
    const int bar =
        static_cast<int>(std::lround(kPreviewHistogramHeight * std::log1p(statistics.histogram[bin]) / top));
    for (int k = 0; k < bar; ++k) {
      uint8_t* p = picture.at(x, frame_height + kPreviewHistogramHeight - 1 - k);
      if (bin == 255)
        SetRgb(p, 255, 0, 0);
      else
        SetRgb(p, 255, 255, 255);
    }
  }
  // Focus bar: this frame's measure against the best seen.
  const double fraction = best_focus > 0 ? std::clamp(statistics.focus / best_focus, 0.0, 1.0) : 0;
  const int length = static_cast<int>(std::lround(fraction * picture.width));
  for (int y = frame_height + kPreviewHistogramHeight; y < picture.height; ++y) {
    for (int x = 0; x < length; ++x) SetRgb(picture.at(x, y), 255, 200, 0);
  }
  return picture;
}

}  // namespace thinslab
