// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/exposure_plan.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>

#include "thinslab/core/duration_text.h"
#include "thinslab/core/statistics.h"
#include "thinslab/drivers/pattern_id.h"

namespace thinslab {

bool ExposurePlanOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(peak_fill > 0 && peak_fill <= 1)) {
    msg << "ExposurePlanOptions::peak_fill = " << peak_fill << ": expected in (0, 1]";
  } else if (!(max_dark_fraction > 0 && max_dark_fraction < 1)) {
    msg << "ExposurePlanOptions::max_dark_fraction = " << max_dark_fraction << ": expected in (0, 1)";
  } else if (!(edge_fraction > 0 && edge_fraction <= 1)) {
    msg << "ExposurePlanOptions::edge_fraction = " << edge_fraction << ": expected in (0, 1]";
  } else if (!(edge_sigmas > 0) || !std::isfinite(edge_sigmas)) {
    msg << "ExposurePlanOptions::edge_sigmas = " << edge_sigmas << ": expected > 0";
  } else if (!(min_exposure_us >= 0) || !std::isfinite(min_exposure_us)) {
    msg << "ExposurePlanOptions::min_exposure_us = " << min_exposure_us << ": expected >= 0";
  } else if (!(max_exposure_us > 0) || !std::isfinite(max_exposure_us) || max_exposure_us < min_exposure_us) {
    msg << "ExposurePlanOptions::max_exposure_us = " << max_exposure_us << ": expected > 0 and >= min_exposure_us";
  } else if (!(max_step_ratio >= 2) || !std::isfinite(max_step_ratio)) {
    msg << "ExposurePlanOptions::max_step_ratio = " << max_step_ratio << ": expected >= 2";
  } else if (!(probe_exposure_us >= 0) || !std::isfinite(probe_exposure_us)) {
    msg << "ExposurePlanOptions::probe_exposure_us = " << probe_exposure_us << ": expected >= 0";
  } else if (settle_captures < 1 || settle_captures > 20) {
    msg << "ExposurePlanOptions::settle_captures = " << settle_captures << ": expected 1..20";
  }
  *error = msg.str();
  return error->empty();
}

namespace {

std::string Num(double v) {
  std::ostringstream s;
  s << std::setprecision(3) << v;
  return s.str();
}

// The exposure at which a signal of `edge` DN/us, on a glow of `glow` DN/us, reaches `k` sigmas:
// (edge t)^2 = k^2 (read^2 + (edge + glow) t / gain), the positive root.
double EdgeExposureUs(double edge, double glow, double read_dn, double gain, double k) {
  const double b = k * k * (edge + glow) / gain;
  return (b + std::sqrt(b * b + 4 * edge * edge * k * k * read_dn * read_dn)) / (2 * edge * edge);
}

}  // namespace

Status PlanExposures(const ProbeMeasurement& brightest, const ProbeMeasurement& black,
                     const std::vector<ProbeMeasurement>& lobes, const CameraInfo& camera, double refresh_period_s,
                     const ExposurePlanOptions& options, ExposurePlan* plan) {
  *plan = ExposurePlan();
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  const double range = camera.saturation_dn - camera.black_level_dn;
  if (!(range > 0) || !std::isfinite(range)) {
    return Status::Error("PlanExposures: camera '" + camera.id + "' has no finite saturation level to plan against");
  }
  if (!(brightest.peak_dn_per_us > 0)) {
    return Status::Error("exposure probe: the brightest state (" + brightest.label +
                         ") shows no light: is the display on and in the camera's view?");
  }
  const double period_us = refresh_period_s > 0 ? refresh_period_s * 1e6 : 0;
  const double floor_us = std::max(options.min_exposure_us, period_us > 0 ? period_us : 1.0);
  std::ostringstream why;
  why << std::setprecision(3);
  // Shortest: the brightest peak at peak_fill of the range.
  double shortest = std::max(floor_us, options.peak_fill * range / brightest.peak_dn_per_us);
  if (period_us > 0) shortest = std::max(1.0, std::floor(shortest / period_us)) * period_us;
  why << "shortest " << DurationText(shortest) << ": " << brightest.label << " peaks at "
      << Num(brightest.peak_dn_per_us) << " DN/us"
      << (brightest.saturated ? " (at least: saturated in the shortest probe)" : "") << ", "
      << Num(100 * brightest.peak_dn_per_us * shortest / range) << " % of the range there";
  // Longest: the dimmest lobe's edge above the noise, the glow below its limit, the cap.
  const double gain = camera.gain_e_per_dn > 0 ? camera.gain_e_per_dn : 1.0;
  const double read_dn = camera.read_noise_dn.value_or(2.0);
  const double glow = std::max(black.peak_dn_per_us, 0.0);
  double longest = options.max_exposure_us;
  std::string longest_reason = "the cap (" + DurationText(options.max_exposure_us) + ")";
  double edge_us = 0;
  std::string edge_label;
  for (const ProbeMeasurement& lobe : lobes) {
    if (!(lobe.peak_dn_per_us > 0)) continue;
    const double t =
        EdgeExposureUs(options.edge_fraction * lobe.peak_dn_per_us, glow, read_dn, gain, options.edge_sigmas);
    if (t > edge_us) {
      edge_us = t;
      edge_label = lobe.label;
    }
  }
  if (edge_us > 0 && edge_us < longest) {
    longest = edge_us;
    longest_reason = "the edge (" + Num(100 * options.edge_fraction) + " % of the peak) of the dimmest probed lobe, " +
                     edge_label + ", at " + Num(options.edge_sigmas) + " sigma";
  }
  if (glow > 0 && options.max_dark_fraction * range / glow < longest) {
    longest = options.max_dark_fraction * range / glow;
    longest_reason = "the display's black glow (" + Num(glow) + " DN/us, 99th percentile) at " +
                     Num(100 * options.max_dark_fraction) + " % of the range" +
                     (edge_us > longest ? "; the dimmest lobe's edge would need " + DurationText(edge_us) +
                                              ": its tails stay noisier than planned"
                                        : std::string());
  }
  if (period_us > 0) longest = std::max(1.0, std::floor(longest / period_us)) * period_us;
  longest = std::max(longest, shortest);
  why << "; longest " << DurationText(longest) << ": " << longest_reason;
  ExposureBracketOptions bracket;
  bracket.refresh_period_s = refresh_period_s;
  if (longest <= shortest * (1 + 1e-9)) {
    bracket.exposures_us = {shortest};
  } else {
    const int steps =
        static_cast<int>(std::ceil(std::log(longest / shortest) / std::log(options.max_step_ratio) - 1e-9)) + 1;
    for (int k = 0; k < steps; ++k) {
      bracket.exposures_us.push_back(shortest * std::pow(longest / shortest, static_cast<double>(k) / (steps - 1)));
    }
    why << "; " << steps << " exposures at most " << Num(options.max_step_ratio) << "x apart";
  }
  plan->exposures_us = PlanExposureBracket(bracket);
  plan->probes.push_back(brightest);
  plan->probes.push_back(black);
  plan->probes.insert(plan->probes.end(), lobes.begin(), lobes.end());
  plan->why = why.str();
  return Status::Ok();
}

namespace {

// One probe state: shown, settled, measured; the exposure halved while it saturates.
class Prober {
 public:
  Prober(Camera* camera, Projector* projector, const ExposurePlanOptions& options, double refresh_period_s)
      : camera_(camera), projector_(projector), options_(options), period_us_(refresh_period_s * 1e6) {}

  // `bright`: the 3 x 3 peak (else the 99th percentile); starting at `start_us`.
  Status Measure(const std::string& label, const std::string& pattern, bool bright, double start_us,
                 ProbeMeasurement* m) {
    *m = ProbeMeasurement();
    m->label = label;
    THINSLAB_RETURN_IF_ERROR(projector_->ShowPattern(pattern).WithContext("exposure probe: " + label));
    const CameraInfo& info = camera_->info();
    const double range = info.saturation_dn - info.black_level_dn;
    const double shortest = period_us_ > 0 ? period_us_ : 1.0;
    for (double t = start_us;;
         t = std::max(shortest, period_us_ > 0 ? std::floor(t / 2 / period_us_) * period_us_ : t / 2)) {
      double applied = 0;
      THINSLAB_RETURN_IF_ERROR(camera_->SetExposure(t, &applied).WithContext("exposure probe: " + label));
      CapturedFrame frame;
      for (int k = 0; k < options_.settle_captures; ++k) {
        THINSLAB_RETURN_IF_ERROR(camera_->Capture(&frame).WithContext("exposure probe: " + label));
      }
      const Image& raw = frame.raw_dn;
      double level = 0;
      if (bright) {
        // The brightest pixel: saturation is per pixel, and a dot's image can be one pixel.
        level = *std::max_element(raw.data().begin(), raw.data().end()) - info.black_level_dn;
      } else {
        level = Quantile(raw.data(), 0.99) - info.black_level_dn;
      }
      m->exposure_us = frame.exposure_time_us > 0 ? frame.exposure_time_us : applied;
      m->peak_dn_per_us = std::max(level, 0.0) / m->exposure_us;
      m->saturated = level >= 0.9 * range;
      if (!m->saturated || t <= shortest) return Status::Ok();
    }
  }

 private:
  Camera* camera_;
  Projector* projector_;
  const ExposurePlanOptions& options_;
  double period_us_;
};

}  // namespace

Status ProbeAndPlanDotScanExposures(Camera* camera, Projector* projector, const SampleChanger& change_sample,
                                    const std::string& all_dots_pattern, const std::vector<Eigen::Vector2d>& probe_dots,
                                    const std::string& sample_state, double refresh_period_s,
                                    const ExposurePlanOptions& options, ExposurePlan* plan) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  const double period_us = refresh_period_s * 1e6;
  const double probe_us = options.probe_exposure_us > 0 ? options.probe_exposure_us : period_us > 0 ? period_us : 1000;
  Prober prober(camera, projector, options, refresh_period_s);
  ProbeMeasurement brightest, black;
  std::vector<ProbeMeasurement> lobes;
  THINSLAB_RETURN_IF_ERROR(change_sample("none"));
  THINSLAB_RETURN_IF_ERROR(
      prober.Measure("the all-dots frame without the sample", all_dots_pattern, true, probe_us, &brightest));
  THINSLAB_RETURN_IF_ERROR(change_sample(sample_state));
  // The glow and the lobes are dim: probed long (64 probe exposures), shortened while they saturate.
  const double long_us = std::min(64 * probe_us, options.max_exposure_us);
  THINSLAB_RETURN_IF_ERROR(prober.Measure("the display black with the sample", "", false, long_us, &black));
  for (const Eigen::Vector2d& dot : probe_dots) {
    ProbeMeasurement lobe;
    std::ostringstream label;
    label << "dot (" << dot.x() << ", " << dot.y() << ") through the sample";
    THINSLAB_RETURN_IF_ERROR(prober.Measure(label.str(), DotPatternId(dot.x(), dot.y()), true, long_us, &lobe));
    // The lobe above the glow the black frame showed.
    lobe.peak_dn_per_us = std::max(0.0, lobe.peak_dn_per_us - black.peak_dn_per_us);
    lobes.push_back(lobe);
  }
  THINSLAB_RETURN_IF_ERROR(projector->ShowPattern(""));
  return PlanExposures(brightest, black, lobes, camera->info(), refresh_period_s, options, plan);
}

}  // namespace thinslab
