// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "thinslab/core/file.h"
#include "thinslab/core/png_io.h"

namespace thinslab {
namespace {

cv::Scalar Bgr(int rgb) { return cv::Scalar(rgb & 0xff, (rgb >> 8) & 0xff, (rgb >> 16) & 0xff); }

std::string Format(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.3g", v);
  return buf;
}

// "Nice" tick values covering [lo, hi].
std::vector<double> Ticks(double lo, double hi, int target) {
  const double span = hi - lo;
  if (!(span > 0)) return {lo};
  const double raw = span / target;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  double step = mag;
  for (double m : {1.0, 2.0, 5.0, 10.0}) {
    if (m * mag >= raw) {
      step = m * mag;
      break;
    }
  }
  std::vector<double> ticks;
  for (double t = std::ceil(lo / step) * step; t <= hi + 1e-9 * span; t += step) ticks.push_back(t);
  return ticks;
}

// Ticks of a log10 axis spanning [lo, hi] in log10 units: the decades, plus 2 and 5 when the
// axis spans fewer than 3 decades (else an axis inside one decade would have no tick at all).
std::vector<double> LogTicks(double lo, double hi) {
  const bool fine = hi - lo < 3;
  std::vector<double> ticks;
  for (double e = std::floor(lo); e <= hi; e += 1) {
    for (double m : {1.0, 2.0, 5.0}) {
      if (m != 1.0 && !fine) continue;
      const double t = m * std::pow(10.0, e);
      if (std::log10(t) >= lo && std::log10(t) <= hi) ticks.push_back(t);
    }
  }
  return ticks;
}

}  // namespace

Status WritePlotPng(const std::string& path, const std::vector<PlotPanel>& panels, const PlotOptions& options) {
  if (panels.empty()) return Status::Error(path + ": no panels to plot");
  const int W = options.width_px, H = options.height_px;
  cv::Mat canvas(H, W, CV_8UC3, cv::Scalar(255, 255, 255));
  const int left = 90, right = 20, top = 40, bottom = 55, gap = 25;
  // x range in plot coordinates (log10 x on a log axis).
  auto tx = [&](double x) { return options.log_x ? std::log10(x) : x; };
  auto x_usable = [&](double x) { return std::isfinite(x) && (!options.log_x || x > 0); };
  double x_lo = 1e300, x_hi = -1e300;
  for (const auto& panel : panels) {
    for (const auto& s : panel.series) {
      for (double x : s.x) {
        if (x_usable(x)) {
          x_lo = std::min(x_lo, tx(x));
          x_hi = std::max(x_hi, tx(x));
        }
      }
    }
  }
  if (!(x_hi > x_lo)) {
    x_lo -= 1;
    x_hi += 1;
  }
  if (options.log_x) {
    const double pad = 0.04 * (x_hi - x_lo);
    x_lo -= pad;
    x_hi += pad;
  }
  double total_weight = 0;
  for (const auto& panel : panels) total_weight += panel.height_weight;
  const int plot_h_total = H - top - bottom - gap * static_cast<int>(panels.size() - 1);
  cv::putText(canvas, options.title, cv::Point(left, 25), cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 0, 0), 1,
              cv::LINE_AA);
  int y0 = top;
  for (size_t pi = 0; pi < panels.size(); ++pi) {
    const PlotPanel& panel = panels[pi];
    const int ph = static_cast<int>(plot_h_total * panel.height_weight / total_weight);
    const cv::Rect box(left, y0, W - left - right, ph);
    // y range.
    double y_lo = 1e300, y_hi = -1e300;
    auto ty = [&](double y) { return panel.log_y ? std::log10(y) : y; };
    for (const auto& s : panel.series) {
      for (size_t i = 0; i < s.y.size(); ++i) {
        const double e = s.y_error.size() == s.y.size() ? s.y_error[i] : 0.0;
        for (double v : {s.y[i] - e, s.y[i] + e}) {
          if (panel.log_y && !(v > 0)) continue;
          if (!std::isfinite(v)) continue;
          y_lo = std::min(y_lo, ty(v));
          y_hi = std::max(y_hi, ty(v));
        }
      }
    }
    if (!(y_hi > y_lo)) {
      y_lo -= 1;
      y_hi += 1;
    }
    const double pad = 0.05 * (y_hi - y_lo);
    y_lo -= pad;
    y_hi += pad;
    auto px = [&](double x) { return box.x + (tx(x) - x_lo) / (x_hi - x_lo) * box.width; };
    auto py = [&](double y) { return box.y + box.height - (ty(y) - y_lo) / (y_hi - y_lo) * box.height; };
    // Grid, ticks.
    std::vector<double> xt;
    if (options.log_x) {
      xt = LogTicks(x_lo, x_hi);
    } else {
      xt = Ticks(x_lo, x_hi, 8);
    }
    for (double t : xt) {
      const int x = static_cast<int>(px(t));
      cv::line(canvas, cv::Point(x, box.y), cv::Point(x, box.y + box.height), cv::Scalar(230, 230, 230));
      if (pi + 1 == panels.size()) {
        cv::putText(canvas, Format(t), cv::Point(x - 12, box.y + box.height + 18), cv::FONT_HERSHEY_SIMPLEX, 0.4,
                    cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
      }
    }
    std::vector<double> yt;
    if (panel.log_y) {
      yt = LogTicks(y_lo, y_hi);
    } else {
      yt = Ticks(y_lo, y_hi, 5);
    }
    for (double t : yt) {
      const int y = static_cast<int>(py(t));
      cv::line(canvas, cv::Point(box.x, y), cv::Point(box.x + box.width, y), cv::Scalar(230, 230, 230));
      cv::putText(canvas, Format(t), cv::Point(8, y + 4), cv::FONT_HERSHEY_SIMPLEX, 0.4, cv::Scalar(0, 0, 0), 1,
                  cv::LINE_AA);
    }
    if (panel.zero_line && !panel.log_y && y_lo < 0 && y_hi > 0) {
      cv::line(canvas, cv::Point(box.x, static_cast<int>(py(0))), cv::Point(box.x + box.width, static_cast<int>(py(0))),
               cv::Scalar(120, 120, 120));
    }
    cv::rectangle(canvas, box, cv::Scalar(0, 0, 0));
    cv::putText(canvas, panel.y_label, cv::Point(box.x + 5, box.y + 15), cv::FONT_HERSHEY_SIMPLEX, 0.45,
                cv::Scalar(60, 60, 60), 1, cv::LINE_AA);
    // Series.
    int num_labels = 0;
    for (const auto& s : panel.series) num_labels += !s.label.empty();
    int legend_y = panel.legend_bottom_left ? box.y + box.height - 8 - 17 * (num_labels - 1) : box.y + 15;
    for (const auto& s : panel.series) {
      const cv::Scalar color = Bgr(s.color_bgr);
      std::vector<cv::Point> pts;
      for (size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
        if (panel.log_y && !(s.y[i] > 0)) continue;
        if (!x_usable(s.x[i]) || !std::isfinite(s.y[i])) continue;
        const cv::Point pt(static_cast<int>(px(s.x[i])), static_cast<int>(py(s.y[i])));
        if (s.line) {
          pts.push_back(pt);
        } else {
          if (s.y_error.size() == s.y.size()) {
            const double lo = s.y[i] - s.y_error[i], hi = s.y[i] + s.y_error[i];
            const int ylo = panel.log_y && !(lo > 0) ? box.y + box.height : static_cast<int>(py(lo));
            cv::line(canvas, cv::Point(pt.x, ylo), cv::Point(pt.x, static_cast<int>(py(hi))), color);
          }
          cv::circle(canvas, pt, 3, color, cv::FILLED, cv::LINE_AA);
        }
        if (s.point_labels.size() == s.x.size() && !s.point_labels[i].empty()) {
          // Right of the point, or left of it where the text would leave the box.
          const cv::Size size = cv::getTextSize(s.point_labels[i], cv::FONT_HERSHEY_SIMPLEX, 0.36, 1, nullptr);
          const int x = pt.x + 5 + size.width > box.x + box.width ? pt.x - 5 - size.width : pt.x + 5;
          cv::putText(canvas, s.point_labels[i], cv::Point(x, pt.y - 5), cv::FONT_HERSHEY_SIMPLEX, 0.36, color, 1,
                      cv::LINE_AA);
        }
      }
      if (s.line && pts.size() > 1) cv::polylines(canvas, pts, false, color, 2, cv::LINE_AA);
      if (!s.label.empty()) {
        const int lx = panel.legend_bottom_left ? box.x + 10 : box.x + box.width - 260;
        cv::line(canvas, cv::Point(lx, legend_y - 4), cv::Point(lx + 20, legend_y - 4), color, 2);
        cv::putText(canvas, s.label, cv::Point(lx + 26, legend_y), cv::FONT_HERSHEY_SIMPLEX, 0.42,
                    cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
        legend_y += 17;
      }
    }
    y0 += ph + gap;
  }
  cv::putText(canvas, options.x_label, cv::Point(W / 2 - 60, H - 15), cv::FONT_HERSHEY_SIMPLEX, 0.5,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  THINSLAB_RETURN_IF_ERROR(WritePngAtomically(path, canvas));
  return WriteFileAtomically(PlotCsvPath(path), PlotCsv(panels, options));
}

std::string PlotCsvPath(const std::string& png_path) {
  const bool png = png_path.size() > 4 && png_path.compare(png_path.size() - 4, 4, ".png") == 0;
  // "_data": a command's own CSV of the same name (knob_sweep_dmf.csv) is not replaced.
  return (png ? png_path.substr(0, png_path.size() - 4) : png_path) + "_data.csv";
}

std::string PlotCsv(const std::vector<PlotPanel>& panels, const PlotOptions& options) {
  std::ostringstream csv;
  csv.precision(10);
  csv << "# " << options.title << "; x: " << options.x_label << "\n";
  csv << "panel,y_label,series,x,y,y_error\n";
  auto quoted = [](const std::string& text) {
    std::string q = "\"";
    for (char c : text) q += c == '"' ? std::string("\"\"") : std::string(1, c);
    return q + "\"";
  };
  for (size_t p = 0; p < panels.size(); ++p) {
    for (const PlotSeries& series : panels[p].series) {
      for (size_t k = 0; k < series.x.size() && k < series.y.size(); ++k) {
        csv << p << "," << quoted(panels[p].y_label) << "," << quoted(series.label) << "," << series.x[k] << ","
            << series.y[k] << ",";
        if (k < series.y_error.size()) csv << series.y_error[k];
        csv << "\n";
      }
    }
  }
  return csv.str();
}

}  // namespace thinslab
