// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/false_color.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "thinslab/core/file.h"
#include "thinslab/core/png_io.h"

namespace thinslab {
namespace {

const cv::Vec3b kGrey(128, 128, 128);

// Tableau 10 (BGR): distinct categories, none of them grey.
const cv::Vec3b kCategoryColors[] = {{180, 119, 31}, {14, 127, 255}, {44, 160, 44},  {40, 39, 214},
                                     {189, 103, 148}, {75, 86, 140}, {194, 119, 227}, {34, 189, 188},
                                     {207, 190, 23}, {0, 0, 0}};

// Blue (t = -1) through white (0) to red (+1), as ColorBrewer's RdBu ends (BGR).
cv::Vec3b Diverging(double t) {
  t = std::clamp(t, -1.0, 1.0);
  const cv::Vec3d white(247, 247, 247), blue(172, 102, 33), red(43, 24, 178);
  const cv::Vec3d c = t < 0 ? white + (-t) * (blue - white) : white + t * (red - white);
  return cv::Vec3b(static_cast<uint8_t>(c[0] + 0.5), static_cast<uint8_t>(c[1] + 0.5), static_cast<uint8_t>(c[2] + 0.5));
}

// OpenCV's viridis, as a 256-entry table built once.
cv::Vec3b Viridis(double t) {
  static const cv::Mat table = [] {
    cv::Mat ramp(1, 256, CV_8U), color;
    for (int k = 0; k < 256; ++k) ramp.at<uint8_t>(0, k) = static_cast<uint8_t>(k);
    cv::applyColorMap(ramp, color, cv::COLORMAP_VIRIDIS);
    return color;
  }();
  return table.at<cv::Vec3b>(0, static_cast<int>(std::clamp(t, 0.0, 1.0) * 255 + 0.5));
}

void Text(cv::Mat* canvas, const std::string& text, cv::Point at, double size = 0.4) {
  cv::putText(*canvas, text, at, cv::FONT_HERSHEY_SIMPLEX, size, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
}

// A bar of 1, 2 or 5 x 10^k mm, about a fifth of the map's width, at its lower left.
void DrawScaleBar(cv::Mat* canvas, cv::Rect map, double mm_per_canvas_px) {
  const double target_mm = map.width * mm_per_canvas_px / 5;
  const double decade = std::pow(10.0, std::floor(std::log10(target_mm)));
  double length_mm = decade;
  for (double m : {2.0, 5.0}) {
    if (m * decade <= target_mm) length_mm = m * decade;
  }
  const int length_px = static_cast<int>(std::lround(length_mm / mm_per_canvas_px));
  if (length_px < 4) return;
  const int x0 = map.x + 8, y0 = map.y + map.height - 10;
  cv::rectangle(*canvas, cv::Rect(x0 - 1, y0 - 4, length_px + 2, 8), cv::Scalar(0, 0, 0), cv::FILLED);
  cv::rectangle(*canvas, cv::Rect(x0, y0 - 3, length_px, 6), cv::Scalar(255, 255, 255), cv::FILLED);
  char text[32];
  std::snprintf(text, sizeof(text), "%g mm", length_mm);
  cv::putText(*canvas, text, cv::Point(x0, y0 - 8), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
  cv::putText(*canvas, text, cv::Point(x0, y0 - 8), cv::FONT_HERSHEY_SIMPLEX, 0.45, cv::Scalar(255, 255, 255), 1,
              cv::LINE_AA);
}

}  // namespace

Status WriteFalseColorPng(const std::string& path, const Image& image, int channel, const Image* mask,
                          const FalseColorOptions& options) {
  if (image.empty() || channel < 0 || channel >= image.num_channels()) {
    return Status::Error(path + ": nothing to draw (empty image or bad channel)");
  }
  const bool categorical = options.scale_kind == ColorScale::kCategorical;
  const bool diverging = options.scale_kind == ColorScale::kDiverging;
  if (categorical && options.category_names.empty()) {
    return Status::Error(path + ": FalseColorOptions category_names is empty for a categorical map");
  }
  double lo = options.min_value, hi = options.max_value;
  if (diverging) hi = std::max(std::abs(lo), std::abs(hi)), lo = -hi;
  if (!categorical && !(hi > lo)) return Status::Error(path + ": FalseColorOptions max_value must exceed min_value");

  const int s = std::max(1, options.scale);
  const int w = image.width() * s, h = image.height() * s;
  const int num_categories = static_cast<int>(options.category_names.size());
  const int bar_w = 24, margin = 10;
  int legend_w = 70 + bar_w + margin;
  if (categorical) {
    size_t longest = options.label.size();
    for (const std::string& n : options.category_names) longest = std::max(longest, n.size() + 4);
    legend_w = 24 + static_cast<int>(longest) * 8 + margin;
  }
  const int canvas_h = std::max({h, 200, categorical ? 30 + 20 * num_categories : 0}) + 2 * margin;
  cv::Mat canvas(canvas_h, w + 2 * margin + legend_w, CV_8UC3, cv::Scalar(255, 255, 255));
  const int lx = w + 2 * margin;  // Legend's left edge.

  auto color_of = [&](double v) -> cv::Vec3b {
    if (!std::isfinite(v)) return kGrey;
    if (categorical) {
      const long code = std::lround(v);
      if (code < 0 || code >= num_categories || std::abs(v - code) > 1e-6) return kGrey;
      return kCategoryColors[code % 10];
    }
    if (diverging) return Diverging(v / hi);
    return Viridis((v - lo) / (hi - lo));
  };
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const bool masked = mask != nullptr && mask->at(x / s, y / s) != 0;
      canvas.at<cv::Vec3b>(margin + y, margin + x) = masked ? kGrey : color_of(image.at(x / s, y / s, channel));
    }
  }
  Text(&canvas, options.label, cv::Point(lx, margin + 12), 0.45);
  if (categorical) {
    // One swatch per named code.
    for (int k = 0; k < num_categories; ++k) {
      const int y = margin + 24 + 20 * k;
      const cv::Vec3b c = kCategoryColors[k % 10];
      cv::rectangle(canvas, cv::Rect(lx, y, 14, 14), cv::Scalar(c[0], c[1], c[2]), cv::FILLED);
      cv::rectangle(canvas, cv::Rect(lx, y, 14, 14), cv::Scalar(0, 0, 0));
      Text(&canvas, std::to_string(k) + " " + options.category_names[k], cv::Point(lx + 20, y + 12));
    }
  } else {
    // Colour bar, max at the top.
    const int bar_h = canvas_h - 2 * margin - 20, bar_y = margin + 20;
    for (int y = 0; y < bar_h; ++y) {
      const double v = hi - (hi - lo) * y / std::max(1, bar_h - 1);
      const cv::Vec3b c = color_of(v);
      cv::line(canvas, cv::Point(lx, bar_y + y), cv::Point(lx + bar_w - 1, bar_y + y), cv::Scalar(c[0], c[1], c[2]));
    }
    for (int k = 0; k <= 4; ++k) {
      char text[32];
      std::snprintf(text, sizeof(text), "%.3g", hi - (hi - lo) * k / 4.0);
      const int y = bar_y + (bar_h - 1) * k / 4;
      cv::line(canvas, cv::Point(lx + bar_w, y), cv::Point(lx + bar_w + 4, y), cv::Scalar(0, 0, 0));
      Text(&canvas, text, cv::Point(lx + bar_w + 7, y + 4));
    }
  }
  if (options.pixel_pitch_m > 0) DrawScaleBar(&canvas, cv::Rect(margin, margin, w, h), options.pixel_pitch_m * 1e3 / s);
  return WritePngAtomically(path, canvas);
}

}  // namespace thinslab
