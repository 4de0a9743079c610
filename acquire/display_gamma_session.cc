// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/display_gamma_session.h"

#include <random>

#include "thinslab/drivers/pattern_id.h"

namespace thinslab {

bool DisplayGammaSessionOptions::Check(std::string* error) const {
  if (steps < 2 || steps > 255) {
    *error = "DisplayGammaSessionOptions::steps = " + std::to_string(steps) +
             ". Violated constraint: in [2, 255] (an 8-bit display has 256 drive levels)";
    return false;
  }
  if (repeats < 1) {
    *error = "DisplayGammaSessionOptions::repeats = " + std::to_string(repeats) + ". Violated constraint: >= 1";
    return false;
  }
  if (dark_frames < 0) {
    *error = "DisplayGammaSessionOptions::dark_frames = " + std::to_string(dark_frames) +
             ". Violated constraint: >= 0";
    return false;
  }
  return bracket.Check(error) && sync.Check(error);
}

std::vector<double> DisplayGammaLevelOrder(const DisplayGammaSessionOptions& options) {
  // Fisher-Yates on the raw engine output: std::shuffle's use of the engine is
  // implementation-defined, and a resumed session must plan the same order on any build.
  std::mt19937_64 engine(options.order_seed);
  std::vector<double> order;
  for (int r = 0; r < options.repeats; ++r) {
    std::vector<double> levels;
    for (int i = 0; i <= options.steps; ++i) levels.push_back(static_cast<double>(i) / options.steps);
    for (size_t i = levels.size() - 1; i > 0; --i) std::swap(levels[i], levels[engine() % (i + 1)]);
    order.insert(order.end(), levels.begin(), levels.end());
  }
  return order;
}

std::vector<PlannedFrame> PlanDisplayGammaSession(const DisplayGammaSessionOptions& options, double refresh_period_s) {
  const std::vector<double> exposures = PlanExposureBracket(WithDisplayRefresh(options.bracket, refresh_period_s));
  std::vector<PlannedFrame> plan;
  for (double t : exposures) {
    for (int k = 0; k < options.dark_frames; ++k) plan.push_back({"dark", "none", "", t, std::nullopt});
  }
  for (double level : DisplayGammaLevelOrder(options)) {
    const std::string pattern = FlatPatternId(level);
    for (double t : exposures) plan.push_back({"level", "none", pattern, t, std::nullopt});
  }
  return plan;
}

Status RunDisplayGammaSession(const DisplayGammaSessionOptions& options, Camera* camera, Projector* display,
                              const SampleChanger& change_sample, SessionWriter* writer) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  const double period = display->refresh_period_s();
  return RunSynchronizedPlan(PlanDisplayGammaSession(options, period), WithDisplayRefresh(options.bracket, period),
                             options.sync, camera, display, change_sample, writer);
}

}  // namespace thinslab
