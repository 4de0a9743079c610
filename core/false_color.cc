// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/false_color.h"

#include <algorithm>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "thinslab/core/file.h"
#include "thinslab/core/png_io.h"

namespace thinslab {

Status WriteFalseColorPng(const std::string& path, const Image& image, int channel, const Image* mask,
                          const FalseColorOptions& options) {
  if (image.empty() || channel < 0 || channel >= image.num_channels()) {
    return Status::Error(path + ": nothing to draw (empty image or bad channel)");
  }
  if (!(options.max_value > options.min_value)) {
    return Status::Error(path + ": FalseColorOptions max_value must exceed min_value");
  }
  const int s = std::max(1, options.scale);
  const int w = image.width() * s, h = image.height() * s;
  const int bar_w = 24, margin = 10, label_w = 70;
  const int canvas_h = std::max(h, 200) + 2 * margin;
  cv::Mat gray(h, w, CV_8U);
  cv::Mat masked(h, w, CV_8U, cv::Scalar(0));
  const double range = options.max_value - options.min_value;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double v = image.at(x / s, y / s, channel);
      gray.at<uint8_t>(y, x) = static_cast<uint8_t>(std::clamp((v - options.min_value) / range, 0.0, 1.0) * 255 + 0.5);
      if (mask != nullptr && mask->at(x / s, y / s) != 0) masked.at<uint8_t>(y, x) = 1;
    }
  }
  cv::Mat colored;
  cv::applyColorMap(gray, colored, cv::COLORMAP_VIRIDIS);
  colored.setTo(cv::Scalar(128, 128, 128), masked);
  cv::Mat canvas(canvas_h, w + 3 * margin + bar_w + label_w, CV_8UC3, cv::Scalar(255, 255, 255));
  colored.copyTo(canvas(cv::Rect(margin, margin, w, h)));
  // Colour bar, max at the top.
  const int bar_h = canvas_h - 2 * margin - 20, bar_x = w + 2 * margin, bar_y = margin + 20;
  cv::Mat ramp(bar_h, bar_w, CV_8U);
  for (int y = 0; y < bar_h; ++y) ramp.row(y).setTo(cv::Scalar(255 - (255 * y) / std::max(1, bar_h - 1)));
  cv::Mat ramp_color;
  cv::applyColorMap(ramp, ramp_color, cv::COLORMAP_VIRIDIS);
  ramp_color.copyTo(canvas(cv::Rect(bar_x, bar_y, bar_w, bar_h)));
  cv::putText(canvas, options.label, cv::Point(bar_x, margin + 12), cv::FONT_HERSHEY_SIMPLEX, 0.45,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  for (int k = 0; k <= 4; ++k) {
    const double v = options.max_value - range * k / 4.0;
    char text[32];
    std::snprintf(text, sizeof(text), "%.3g", v);
    const int y = bar_y + (bar_h - 1) * k / 4;
    cv::line(canvas, cv::Point(bar_x + bar_w, y), cv::Point(bar_x + bar_w + 4, y), cv::Scalar(0, 0, 0));
    cv::putText(canvas, text, cv::Point(bar_x + bar_w + 7, y + 4), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  return WritePngAtomically(path, canvas);
}

}  // namespace thinslab
