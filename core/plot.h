// SPDX-License-Identifier: Apache-2.0
// Small PNG charts drawn with OpenCV (no plotting program needed at run time): stacked panels
// sharing an x axis, linear or log10 y, points with error bars and lines, a legend.
#pragma once

#include <string>
#include <vector>

#include "thinslab/core/status.h"

namespace thinslab {

struct PlotSeries {
  std::vector<double> x, y, y_error;  // y_error optional (empty or same size).
  std::vector<std::string> point_labels;  // Optional: drawn beside each point (empty or same size).
  std::string label;
  bool line = false;                  // Line (true) or points (false).
  int color_bgr = 0x1f77b4;           // 0xRRGGBB.
};

struct PlotPanel {
  std::vector<PlotSeries> series;
  std::string y_label;
  bool log_y = false;
  double height_weight = 1;  // Relative panel height.
  bool zero_line = false;
  bool legend_bottom_left = false;  // Default: top right.
};

struct PlotOptions {
  std::string title;
  std::string x_label;
  bool log_x = false;  // Shared x axis in log10 (positive x only).
  int width_px = 900;
  int height_px = 700;
};

// Writes the chart and, beside it, the data it shows as CSV (PlotCsvPath: x.png -> x_data.csv).
Status WritePlotPng(const std::string& path, const std::vector<PlotPanel>& panels, const PlotOptions& options);
std::string PlotCsvPath(const std::string& png_path);
// One row per point: panel, y_label, series, x, y, y_error (empty when the series has none).
std::string PlotCsv(const std::vector<PlotPanel>& panels, const PlotOptions& options);

}  // namespace thinslab
