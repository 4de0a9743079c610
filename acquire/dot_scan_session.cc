// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/dot_scan_session.h"

#include <algorithm>
#include <sstream>

#include "thinslab/drivers/pattern_id.h"

namespace thinslab {
namespace {

std::string Shortest(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

// Dark frames at the longest exposure per dot frame there, when the dots take several: the dark
// is subtracted from every dot, so its noise is shared by all of them and does not average out
// over the scan; 4x costs 4 N long frames once (the 0.2 % black display's 10 x 10 scan: 112 and
// 107 correct points with N darks, 116 and 113 with 4 N; docs/acquisition.md).
constexpr int kDarkFramesPerLongestFrame = 4;

// Grid origin and step from the options.
void GridGeometry(const DotScanSessionOptions& o, double* x0, double* y0, double* dx, double* dy) {
  if (o.step_x_px > 0 && o.step_y_px > 0) {
    *x0 = o.first_x_px;
    *y0 = o.first_y_px;
    *dx = o.step_x_px;
    *dy = o.step_y_px;
    return;
  }
  // Dots on whole-pixel centres, so every dot rasterises the same way.
  const double span_x = o.monitor_width_px * (1 - 2 * o.margin_fraction);
  const double span_y = o.monitor_height_px * (1 - 2 * o.margin_fraction);
  *dx = o.grid_nx > 1 ? std::max(1.0, std::floor(span_x / (o.grid_nx - 1))) : 0;
  *dy = o.grid_ny > 1 ? std::max(1.0, std::floor(span_y / (o.grid_ny - 1))) : 0;
  *x0 = std::floor((o.monitor_width_px - *dx * (o.grid_nx - 1)) / 2) + 0.5;
  *y0 = std::floor((o.monitor_height_px - *dy * (o.grid_ny - 1)) / 2) + 0.5;
}

}  // namespace

bool DotScanSessionOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (grid_nx < 1 || grid_ny < 1 || grid_nx > 1000 || grid_ny > 1000) {
    msg << "DotScanSessionOptions::grid_nx, grid_ny = " << grid_nx << ", " << grid_ny
        << ". Violated constraint: in [1, 1000]";
  } else if ((step_x_px > 0) != (step_y_px > 0)) {
    msg << "DotScanSessionOptions::step_x_px and step_y_px must both be > 0 or both 0";
  } else if (!(step_x_px > 0) && (monitor_width_px <= 0 || monitor_height_px <= 0)) {
    msg << "DotScanSessionOptions::monitor_width_px, monitor_height_px = " << monitor_width_px << ", "
        << monitor_height_px << ". Violated constraint: > 0 (or give step_x_px, step_y_px)";
  } else if (!(margin_fraction >= 0 && margin_fraction < 0.5)) {
    msg << "DotScanSessionOptions::margin_fraction = " << margin_fraction << ". Violated constraint: [0, 0.5)";
  } else if (sample_state != "contaminated" && sample_state != "clean" && sample_state != "none") {
    msg << "DotScanSessionOptions::sample_state = '" << sample_state
        << "'. Violated constraint: contaminated, clean or none";
  } else if (std::any_of(validation_dots_px.begin(), validation_dots_px.end(),
                         [](const Eigen::Vector2d& d) { return !d.allFinite() || d.minCoeff() < 0; })) {
    msg << "DotScanSessionOptions::validation_dots_px: every dot must be finite and >= 0 monitor px";
  } else if (longest_exposure_frames < 1 || longest_exposure_frames > 1000) {
    msg << "DotScanSessionOptions::longest_exposure_frames = " << longest_exposure_frames
        << ". Violated constraint: in [1, 1000]";
  } else if (!bracket.Check(error) || !sync.Check(error)) {
    return false;
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

std::vector<Eigen::Vector2d> DotScanGrid(const DotScanSessionOptions& options) {
  double x0, y0, dx, dy;
  GridGeometry(options, &x0, &y0, &dx, &dy);
  std::vector<Eigen::Vector2d> dots;
  for (int j = 0; j < options.grid_ny; ++j) {
    for (int i = 0; i < options.grid_nx; ++i) dots.emplace_back(x0 + i * dx, y0 + j * dy);
  }
  return dots;
}

std::string DotScanGridPattern(const DotScanSessionOptions& options) {
  double x0, y0, dx, dy;
  GridGeometry(options, &x0, &y0, &dx, &dy);
  return "dots:" + Shortest(x0) + "," + Shortest(y0) + "," + Shortest(dx) + "," + Shortest(dy) + "," +
         std::to_string(options.grid_nx) + "," + std::to_string(options.grid_ny);
}

std::vector<PlannedFrame> PlanDotScan(const DotScanSessionOptions& options, double refresh_period_s) {
  const std::vector<double> exposures = PlanExposureBracket(WithDisplayRefresh(options.bracket, refresh_period_s));
  // The exposures of one dot or of the dark bracket, the longest repeated.
  std::vector<double> repeated;
  for (double t : exposures) {
    const int copies = t == exposures.back() ? options.longest_exposure_frames : 1;
    repeated.insert(repeated.end(), copies, t);
  }
  std::vector<PlannedFrame> plan;
  if (options.capture_all_dots) {
    for (double t : exposures) plan.push_back({"all_dots", "none", DotScanGridPattern(options), t, std::nullopt});
  }
  if (options.capture_dark) {
    for (double t : exposures) {
      const int copies = t != exposures.back() ? 1
                         : options.longest_exposure_frames > 1
                             ? kDarkFramesPerLongestFrame * options.longest_exposure_frames
                             : 1;
      for (int k = 0; k < copies; ++k) plan.push_back({"dark", options.sample_state, "", t, std::nullopt});
    }
  }
  for (const Eigen::Vector2d& dot : DotScanGrid(options)) {
    const std::string pattern = DotPatternId(dot.x(), dot.y());
    for (double t : repeated) plan.push_back({"dot", options.sample_state, pattern, t, dot});
  }
  for (const Eigen::Vector2d& dot : options.validation_dots_px) {
    const std::string pattern = DotPatternId(dot.x(), dot.y());
    for (double t : repeated) {
      PlannedFrame frame{"dot", options.sample_state, pattern, t, dot};
      frame.validation = true;
      plan.push_back(frame);
    }
  }
  return plan;
}

std::vector<Eigen::Vector2d> DotScanValidationDots(const DotScanSessionOptions& options, int count) {
  const std::vector<Eigen::Vector2d> grid = DotScanGrid(options);
  std::vector<Eigen::Vector2d> dots;
  const int cells_x = options.grid_nx - 1, cells_y = options.grid_ny - 1, cells = cells_x * cells_y;
  if (count <= 0 || cells <= 0) return dots;
  for (int k = 0; k < std::min(count, cells); ++k) {
    // Cells k * cells / count + half a stride, so the dots spread over the grid.
    const int cell = static_cast<int>((static_cast<int64_t>(2 * k + 1) * cells) / (2 * std::min(count, cells)));
    const int cx = cell % cells_x, cy = cell / cells_x;
    const Eigen::Vector2d& a = grid[static_cast<size_t>(cy) * options.grid_nx + cx];
    const Eigen::Vector2d& b = grid[static_cast<size_t>(cy + 1) * options.grid_nx + cx + 1];
    dots.push_back(0.5 * (a + b));
  }
  return dots;
}

Status RunDotScanSession(const DotScanSessionOptions& options, Camera* camera, Projector* monitor,
                         const SampleChanger& change_sample, SessionWriter* writer) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  const double period = monitor->refresh_period_s();
  return RunSynchronizedPlan(PlanDotScan(options, period), WithDisplayRefresh(options.bracket, period), options.sync,
                             camera, monitor, change_sample, writer);
}

bool BracketSessionOptions::Check(std::string* error) const {
  if (frames_per_exposure < 1) {
    *error = "BracketSessionOptions::frames_per_exposure = " + std::to_string(frames_per_exposure) +
             ". Violated constraint: >= 1";
    return false;
  }
  PatternSpec spec;
  const Status parsed = ParsePatternId(pattern, &spec);
  if (!parsed.ok()) {
    *error = "BracketSessionOptions::pattern: " + parsed.message();
    return false;
  }
  return bracket.Check(error) && sync.Check(error);
}

std::vector<PlannedFrame> PlanBracketSession(const BracketSessionOptions& options, double refresh_period_s) {
  const std::vector<double> exposures = PlanExposureBracket(WithDisplayRefresh(options.bracket, refresh_period_s));
  std::vector<PlannedFrame> plan;
  if (options.capture_dark) {
    for (double t : exposures) {
      for (int k = 0; k < options.frames_per_exposure; ++k) plan.push_back({"dark", "none", "", t, std::nullopt});
    }
  }
  for (double t : exposures) {
    for (int k = 0; k < options.frames_per_exposure; ++k) {
      plan.push_back({"bracket", "none", options.pattern, t, std::nullopt});
    }
  }
  return plan;
}

Status RunBracketSession(const BracketSessionOptions& options, Camera* camera, Projector* projector,
                         const SampleChanger& change_sample, SessionWriter* writer) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  const double period = projector->refresh_period_s();
  return RunSynchronizedPlan(PlanBracketSession(options, period), WithDisplayRefresh(options.bracket, period),
                             options.sync, camera, projector, change_sample, writer);
}

}  // namespace thinslab
