// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/exposure_plan.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <iomanip>
#include <limits>
#include <sstream>

#include "thinslab/core/camera_model.h"
#include "thinslab/core/duration_text.h"
#include "thinslab/core/math.h"
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
  } else if (max_longest_frames < 1 || max_longest_frames > 1000) {
    msg << "ExposurePlanOptions::max_longest_frames = " << max_longest_frames << ": expected 1..1000";
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

// Exposures from `shortest` to `longest`, geometric, at most `max_step_ratio` apart, whole
// refresh periods; says how many in `why`.
std::vector<double> GeometricBracket(double shortest, double longest, double max_step_ratio, double refresh_period_s,
                                     std::ostringstream* why) {
  ExposureBracketOptions bracket;
  bracket.refresh_period_s = refresh_period_s;
  if (longest <= shortest * (1 + 1e-9)) {
    bracket.exposures_us = {shortest};
  } else {
    const int steps = static_cast<int>(std::ceil(std::log(longest / shortest) / std::log(max_step_ratio) - 1e-9)) + 1;
    for (int k = 0; k < steps; ++k) {
      bracket.exposures_us.push_back(shortest * std::pow(longest / shortest, static_cast<double>(k) / (steps - 1)));
    }
    *why << "; " << steps << " exposures at most " << Num(max_step_ratio) << "x apart";
  }
  return PlanExposureBracket(bracket);
}

// A brightest state that saturates even in the shortest probe exposure (one refresh period of
// the display, or 1 us) saturates in every exposure a session could take: those pixels would be
// lost in every frame, so the plan refuses before the session instead of planning from a lower
// bound.
Status CheckBrightestUnsaturated(const ProbeMeasurement& brightest, double refresh_period_s) {
  if (!brightest.saturated) return Status::Ok();
  return Status::Error("exposure probe: " + brightest.label + " saturates even at " +
                       DurationText(brightest.exposure_us) +
                       (refresh_period_s > 0 ? ", one refresh period of the display, the shortest exposure a frame can "
                                               "have: dim the display"
                                             : ", the shortest exposure tried: dim the light") +
                       ", close the lens aperture or add a neutral-density filter (or give a fixed --exposures-us)");
}

// The signal to noise of that signal in one frame of `t` us.
double EdgeSignalToNoise(double edge, double glow, double read_dn, double gain, double t) {
  return edge * t / std::sqrt(read_dn * read_dn + (edge + glow) * t / gain);
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
  THINSLAB_RETURN_IF_ERROR(CheckBrightestUnsaturated(brightest, refresh_period_s));
  const double period_us = refresh_period_s > 0 ? refresh_period_s * 1e6 : 0;
  const double floor_us = std::max(options.min_exposure_us, period_us > 0 ? period_us : 1.0);
  std::ostringstream why;
  why << std::setprecision(3);
  // Shortest: the brightest peak at peak_fill of the range.
  double shortest = std::max(floor_us, options.peak_fill * range / brightest.peak_dn_per_us);
  if (period_us > 0) shortest = std::max(1.0, std::floor(shortest / period_us)) * period_us;
  why << "shortest " << DurationText(shortest) << ": " << brightest.label << " peaks at "
      << Num(brightest.peak_dn_per_us) << " DN/us"
      << ", " << Num(100 * brightest.peak_dn_per_us * shortest / range) << " % of the range there";
  // Longest: the dimmest lobe's edge above the noise, the glow below its limit, the cap.
  const double gain = camera.gain_e_per_dn > 0 ? camera.gain_e_per_dn : 1.0;
  const double read_dn = camera.read_noise_dn.value_or(2.0);
  const double glow = std::max(black.peak_dn_per_us, 0.0);
  double longest = options.max_exposure_us;
  std::string longest_reason = "the cap (" + DurationText(options.max_exposure_us) + ")";
  double edge_us = 0;
  std::string edge_label;
  bool edge_measured_snr = false;
  const ProbeMeasurement* dimmest = nullptr;
  for (const ProbeMeasurement& lobe : lobes) {
    if (!(lobe.peak_dn_per_us > 0)) continue;
    // A mean with its own measured signal to noise grows as sqrt(t) under shot noise.
    const double t = lobe.snr > 0 ? lobe.exposure_us * Sqr(options.edge_sigmas / lobe.snr)
                                  : EdgeExposureUs(options.edge_fraction * lobe.peak_dn_per_us, glow, read_dn, gain,
                                                   options.edge_sigmas);
    if (t > edge_us) {
      edge_us = t;
      edge_label = lobe.label;
      edge_measured_snr = lobe.snr > 0;
      dimmest = &lobe;
    }
  }
  if (edge_us > 0 && edge_us < longest) {
    longest = edge_us;
    longest_reason =
        edge_measured_snr ? edge_label + " at " + Num(options.edge_sigmas) + " standard errors"
        : options.edge_fraction < 1
            ? "the edge (" + Num(100 * options.edge_fraction) + " % of the peak) of the dimmest probed lobe, " +
                  edge_label + ", at " + Num(options.edge_sigmas) + " sigma"
            : "the dimmest probed signal, " + edge_label + ", at " + Num(options.edge_sigmas) + " sigma in one pixel";
  } else if (edge_us > longest) {
    longest_reason += "; " + edge_label + " would need " + DurationText(edge_us) + " for " + Num(options.edge_sigmas) +
                      (edge_measured_snr ? " standard errors" : " sigma");
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
  // Where the longest stops short of the edge's signal to noise, average frames there: N frames
  // of t have sqrt(N) the signal to noise of one (shot and read noise alike).
  if (dimmest != nullptr && edge_us > longest * (1 + 1e-9) && options.max_longest_frames > 1) {
    const double snr = dimmest->snr > 0 ? dimmest->snr * std::sqrt(longest / dimmest->exposure_us)
                                        : EdgeSignalToNoise(options.edge_fraction * dimmest->peak_dn_per_us, glow,
                                                            read_dn, gain, longest);
    const double wanted = std::ceil(Sqr(options.edge_sigmas / snr) - 1e-9);
    plan->longest_frames = static_cast<int>(std::clamp(wanted, 1.0, static_cast<double>(options.max_longest_frames)));
    if (plan->longest_frames > 1) {
      longest_reason += "; " + std::to_string(plan->longest_frames) + " frames there, averaged, bring " + edge_label +
                        " from " + Num(snr) + " to " + Num(snr * std::sqrt(plan->longest_frames)) +
                        (edge_measured_snr ? " standard errors" : " sigma") +
                        (wanted > options.max_longest_frames ? " (" + Num(wanted) + " frames wanted, at most " +
                                                                   std::to_string(options.max_longest_frames) + ")"
                                                             : std::string());
    }
  }
  why << "; longest " << DurationText(longest) << ": " << longest_reason;
  plan->exposures_us = GeometricBracket(shortest, longest, options.max_step_ratio, refresh_period_s, &why);
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
  Prober(Camera* camera, const ExposurePlanOptions& options, double refresh_period_s)
      : camera_(camera), options_(options), period_us_(refresh_period_s * 1e6) {}

  // `show` puts the rig in the state; `bright`: the brightest pixel (else the 99th percentile);
  // starting at `start_us`. `frame` (may be nullptr): the measured frame's raw DN.
  Status Measure(const std::string& label, const std::function<Status()>& show, bool bright, double start_us,
                 ProbeMeasurement* m, Image* frame_out = nullptr) {
    *m = ProbeMeasurement();
    m->label = label;
    THINSLAB_RETURN_IF_ERROR(show().WithContext("exposure probe: " + label));
    const CameraInfo& info = camera_->info();
    const double range = info.saturation_dn - info.black_level_dn;
    const double shortest = period_us_ > 0 ? period_us_ : 1.0;
    // Halved while it saturates; lengthened 16-fold (up to the cap) while a bright state's peak
    // is below 2 % of the range, where the brightest pixel is the noise's, not the light's.
    bool shortened = false;
    for (double t = start_us;;) {
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
      if (frame_out != nullptr) *frame_out = raw;
      if (m->saturated && t > shortest) {
        shortened = true;
        t = std::max(shortest, period_us_ > 0 ? std::floor(t / 2 / period_us_) * period_us_ : t / 2);
      } else if (bright && !shortened && level < 0.02 * range && t < options_.max_exposure_us) {
        t = std::min(16 * t, options_.max_exposure_us);
        if (period_us_ > 0) t = std::max(1.0, std::floor(t / period_us_)) * period_us_;
      } else {
        return Status::Ok();
      }
    }
  }

 private:
  Camera* camera_;
  const ExposurePlanOptions& options_;
  double period_us_;
};

// A state lit by one source, probed (`Measure`), and the exposure that puts its brightest pixel
// at peak_fill of the range: whole refresh periods (period_us > 0), within min..max_exposure_us.
Status ProbeFillExposure(Prober* prober, const std::string& label, const std::function<Status()>& show, double start_us,
                         const std::string& source, double range, double period_us, const ExposurePlanOptions& options,
                         ProbeMeasurement* m, double* exposure_us) {
  THINSLAB_RETURN_IF_ERROR(prober->Measure(label, show, true, start_us, m));
  if (!(m->peak_dn_per_us > 0)) {
    return Status::Error("exposure probe: " + label + " shows no light: is " + source + " on and aimed at the board?");
  }
  double t = std::min(std::max(options.peak_fill * range / m->peak_dn_per_us, options.min_exposure_us),
                      options.max_exposure_us);
  if (period_us > 0) t = std::max(1.0, std::floor(t / period_us)) * period_us;
  *exposure_us = t;
  return Status::Ok();
}

}  // namespace

Status ProbeAndPlanDotScanExposures(Camera* camera, Projector* projector, const SampleChanger& change_sample,
                                    const std::string& all_dots_pattern, const std::vector<Eigen::Vector2d>& probe_dots,
                                    const std::string& sample_state, double refresh_period_s,
                                    const ExposurePlanOptions& options, ExposurePlan* plan) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  const double period_us = refresh_period_s * 1e6;
  const double probe_us = options.probe_exposure_us > 0 ? options.probe_exposure_us : period_us > 0 ? period_us : 1000;
  Prober prober(camera, options, refresh_period_s);
  auto show = [projector](const std::string& pattern) {
    return [projector, pattern]() { return projector->ShowPattern(pattern); };
  };
  ProbeMeasurement brightest, black;
  std::vector<ProbeMeasurement> lobes;
  THINSLAB_RETURN_IF_ERROR(change_sample("none"));
  THINSLAB_RETURN_IF_ERROR(
      prober.Measure("the all-dots frame without the sample", show(all_dots_pattern), true, probe_us, &brightest));
  THINSLAB_RETURN_IF_ERROR(change_sample(sample_state));
  // The glow and the lobes are dim: probed long (64 probe exposures), shortened while they saturate.
  const double long_us = std::min(64 * probe_us, options.max_exposure_us);
  THINSLAB_RETURN_IF_ERROR(prober.Measure("the display black with the sample", show(""), false, long_us, &black));
  for (const Eigen::Vector2d& dot : probe_dots) {
    ProbeMeasurement lobe;
    std::ostringstream label;
    label << "dot (" << dot.x() << ", " << dot.y() << ") through the sample";
    THINSLAB_RETURN_IF_ERROR(prober.Measure(label.str(), show(DotPatternId(dot.x(), dot.y())), true, long_us, &lobe));
    // The lobe above the glow the black frame showed.
    lobe.peak_dn_per_us = std::max(0.0, lobe.peak_dn_per_us - black.peak_dn_per_us);
    lobes.push_back(lobe);
  }
  THINSLAB_RETURN_IF_ERROR(projector->ShowPattern(""));
  return PlanExposures(brightest, black, lobes, camera->info(), refresh_period_s, options, plan);
}

bool LaserProbeGeometry::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(board_distance_m > 0) || !std::isfinite(board_distance_m)) {
    msg << "rig.board.distance_m = " << board_distance_m << ": the lobe's ring needs the board's distance (> 0)";
  } else if (!(outer_angle_deg > 0 && outer_angle_deg < 89)) {
    msg << "LaserProbeGeometry::outer_angle_deg = " << outer_angle_deg << ": expected in (0, 89)";
  } else if (!(ring_width_deg > 0 && ring_width_deg < outer_angle_deg)) {
    msg << "LaserProbeGeometry::ring_width_deg = " << ring_width_deg << ": expected in (0, outer_angle_deg)";
  } else if (std::abs(laser.direction_in_sample.z()) < 1e-9) {
    msg << "rig.laser.direction_in_sample: parallel to the board, the beam never meets it";
  } else if (camera.width_px <= 0 || camera.height_px <= 0 || !(camera.fx_px > 0) || !(camera.fy_px > 0)) {
    msg << "camera '" << camera.id << "': no intrinsics to find the lobe's ring with";
  }
  *error = msg.str();
  return error->empty();
}

std::vector<int> LaserRingPixels(const LaserProbeGeometry& geometry) {
  std::vector<int> pixels;
  std::string error;
  if (!geometry.Check(&error)) return pixels;
  const double d = geometry.board_distance_m;
  const LaserInfo& laser = geometry.laser;
  const Eigen::Vector3d spot =
      laser.origin_in_sample +
      ((-d - laser.origin_in_sample.z()) / laser.direction_in_sample.z()) * laser.direction_in_sample;
  const double inner = d * std::tan((geometry.outer_angle_deg - geometry.ring_width_deg) * kPi / 180);
  const double outer = d * std::tan(geometry.outer_angle_deg * kPi / 180);
  const Rigid3d sample_from_cam = geometry.camera.cam_from_sample.Inverse();
  const Eigen::Vector3d centre = sample_from_cam.translation;
  for (int y = 0; y < geometry.camera.height_px; ++y) {
    for (int x = 0; x < geometry.camera.width_px; ++x) {
      const Eigen::Vector3d ray =
          sample_from_cam.rotation * PixelToCameraRay(geometry.camera, Eigen::Vector2d(x + 0.5, y + 0.5));
      if (std::abs(ray.z()) < 1e-12) continue;
      const double s = (-d - centre.z()) / ray.z();
      if (!(s > 0)) continue;  // The board is behind the camera along this pixel.
      const double r = ((centre + s * ray) - spot).head<2>().norm();
      if (r >= inner && r <= outer) pixels.push_back(y * geometry.camera.width_px + x);
    }
  }
  return pixels;
}

Status ProbeAndPlanLaserExposures(Camera* camera, Laser* laser, Projector* flat_source,
                                  const SampleChanger& change_sample, const std::string& brightest_state,
                                  const LaserProbeGeometry& geometry, const ExposurePlanOptions& options,
                                  ExposurePlan* plan) {
  std::string error;
  if (!options.Check(&error) || !geometry.Check(&error)) return Status::Error("exposure probe: " + error);
  const std::vector<int> ring = LaserRingPixels(geometry);
  std::ostringstream ring_label;
  ring_label << "the lobe's ring at " << Num(geometry.outer_angle_deg) << " degrees (" << ring.size()
             << " pixels, through the sample)";
  if (ring.size() < 20) {
    return Status::Error("exposure probe: " + ring_label.str() + " is not in the view of camera '" +
                         geometry.camera.id +
                         "': check the manifest's camera pose, board distance and beam, or give --exposures-us");
  }
  const CameraInfo& info = camera->info();
  const double range = info.saturation_dn - info.black_level_dn;
  const double probe_us = options.probe_exposure_us > 0 ? options.probe_exposure_us : 1000;
  Prober prober(camera, options, 0);
  auto state = [&](const std::string& sample, bool on) {
    return [&change_sample, laser, sample, on]() {
      THINSLAB_RETURN_IF_ERROR(change_sample(sample));
      return laser->SetEmission(on);
    };
  };
  ProbeMeasurement brightest, black, spot;
  THINSLAB_RETURN_IF_ERROR(prober.Measure("the laser spot through the " + brightest_state + " sample",
                                          state(brightest_state, true), true, probe_us, &brightest));
  // The dark frame (room light, the camera's dark signal), probed long: the glow limit.
  const double long_us = std::min(64 * probe_us, options.max_exposure_us);
  THINSLAB_RETURN_IF_ERROR(prober.Measure("the laser off", state("contaminated", false), false, long_us, &black));
  THINSLAB_RETURN_IF_ERROR(prober.Measure("the laser spot through the contaminated sample", state("contaminated", true),
                                          true, probe_us, &spot));
  // The ring: exposures growing from the spot's until its mean, laser on minus laser off at the
  // same exposure, clears the asked-for standard errors (from its pixels' spread over sqrt(n): no
  // gain needed) or the cap is reached.
  ProbeMeasurement tail;
  tail.label = ring_label.str();
  auto ring_mean = [&](bool on, double t, double* mean, double* standard_error, double* exposure,
                       bool* saturated) -> Status {
    THINSLAB_RETURN_IF_ERROR(state("contaminated", on)().WithContext("exposure probe: " + tail.label));
    double applied = 0;
    THINSLAB_RETURN_IF_ERROR(camera->SetExposure(t, &applied).WithContext("exposure probe: " + tail.label));
    CapturedFrame frame;
    for (int k = 0; k < options.settle_captures; ++k) {
      THINSLAB_RETURN_IF_ERROR(camera->Capture(&frame).WithContext("exposure probe: " + tail.label));
    }
    *exposure = frame.exposure_time_us > 0 ? frame.exposure_time_us : applied;
    double sum = 0, sum_sq = 0;
    for (int i : ring) {
      const double v = frame.raw_dn.data()[i] - info.black_level_dn;
      *saturated = *saturated || v >= 0.9 * range;
      sum += v;
      sum_sq += v * v;
    }
    const double n = static_cast<double>(ring.size());
    *mean = sum / n;
    *standard_error = std::sqrt(std::max(sum_sq / n - *mean * *mean, 0.0) / (n - 1));
    return Status::Ok();
  };
  for (double t = std::min(spot.exposure_us * options.max_step_ratio, options.max_exposure_us);;
       t = std::min(t * options.max_step_ratio, options.max_exposure_us)) {
    double on = 0, on_error = 0, off = 0, off_error = 0, exposure = 0, off_exposure = 0;
    bool saturated = false;
    THINSLAB_RETURN_IF_ERROR(ring_mean(true, t, &on, &on_error, &exposure, &saturated));
    THINSLAB_RETURN_IF_ERROR(ring_mean(false, t, &off, &off_error, &off_exposure, &saturated));
    const double signal = on - off, standard_error = std::hypot(on_error, off_error);
    tail.exposure_us = exposure;
    tail.peak_dn_per_us = std::max(signal, 0.0) / exposure;
    tail.saturated = saturated;
    tail.snr = standard_error > 0 ? std::max(signal, 0.0) / standard_error : (signal > 0 ? options.edge_sigmas : 0);
    if (saturated || tail.snr >= options.edge_sigmas || t >= options.max_exposure_us) break;
  }
  THINSLAB_RETURN_IF_ERROR(laser->SetEmission(false).WithContext("exposure probe"));
  std::vector<ProbeMeasurement> lobes;
  if (tail.peak_dn_per_us > 0) lobes.push_back(tail);
  THINSLAB_RETURN_IF_ERROR(PlanExposures(brightest, black, lobes, info, 0, options, plan));
  if (lobes.empty()) {
    plan->why += "; " + tail.label + " showed no light above the laser-off frame within the cap";
    plan->probes.push_back(tail);
  }
  plan->probes.insert(plan->probes.begin() + 2, spot);
  if (flat_source == nullptr) return Status::Ok();
  // The flat field lights the whole board for the camera's vignetting: one exposure, its
  // brightest pixel at peak_fill of the range, whole refresh periods of its source.
  const double period_us = flat_source->refresh_period_s() * 1e6;
  Prober flat_prober(camera, options, flat_source->refresh_period_s());
  ProbeMeasurement flat;
  double t = 0;
  THINSLAB_RETURN_IF_ERROR(ProbeFillExposure(
      &flat_prober, "the flat field without the sample",
      [&]() {
        THINSLAB_RETURN_IF_ERROR(change_sample("none"));
        return flat_source->ShowPattern("flat");
      },
      period_us > 0 ? 16 * period_us : probe_us, "the flat-field source", range, period_us, options, &flat, &t));
  THINSLAB_RETURN_IF_ERROR(flat_source->ShowPattern("").WithContext("exposure probe"));
  plan->flat_exposures_us = {t};
  plan->why += "; flat field " + DurationText(t) + ": it peaks at " + Num(flat.peak_dn_per_us) + " DN/us, " +
               Num(100 * flat.peak_dn_per_us * t / range) + " % of the range there";
  plan->probes.push_back(flat);
  return Status::Ok();
}

Status ProbeAndPlanShadowMapExposure(Camera* camera, Projector* projector, const SampleChanger& change_sample,
                                     const ExposurePlanOptions& options, ExposurePlan* plan) {
  *plan = ExposurePlan();
  std::string error;
  if (!options.Check(&error)) return Status::Error("exposure probe: " + error);
  const double period_us = projector->refresh_period_s() * 1e6;
  const double probe_us = options.probe_exposure_us > 0 ? options.probe_exposure_us : period_us > 0 ? period_us : 1000;
  const CameraInfo& info = camera->info();
  const double range = info.saturation_dn - info.black_level_dn;
  Prober prober(camera, options, projector->refresh_period_s());
  auto state = [&](const std::string& pattern) {
    return [&change_sample, projector, pattern]() {
      THINSLAB_RETURN_IF_ERROR(change_sample("clean"));
      return projector->ShowPattern(pattern);
    };
  };
  ProbeMeasurement reference, dark;
  double t = 0;
  THINSLAB_RETURN_IF_ERROR(ProbeFillExposure(&prober, "the flat field through clean glass", state("flat"), probe_us,
                                             "the projector", range, period_us, options, &reference, &t));
  THINSLAB_RETURN_IF_ERROR(CheckBrightestUnsaturated(reference, projector->refresh_period_s()));
  THINSLAB_RETURN_IF_ERROR(prober.Measure("the projector off", state(""), false, t, &dark));
  std::ostringstream why;
  why << "exposure " << DurationText(t) << ": " << reference.label << " peaks at " << Num(reference.peak_dn_per_us)
      << " DN/us, " << Num(100 * reference.peak_dn_per_us * t / range) << " % of the range there";
  const double dark_fill = dark.peak_dn_per_us * t / range;
  if (dark_fill > options.max_dark_fraction) {
    why << "; the projector-off frame already fills " << Num(100 * dark_fill) << " % of the range: darken the room";
  }
  plan->exposures_us = {t};
  plan->probes = {reference, dark};
  plan->why = why.str();
  return Status::Ok();
}

bool ResponseBracketPlanOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(low_fill > 0 && low_fill < high_fill && high_fill <= 1)) {
    msg << "ResponseBracketPlanOptions::low_fill, high_fill = " << low_fill << ", " << high_fill
        << ": expected 0 < low_fill < high_fill <= 1";
  } else if (!(dimmest_quantile >= 0 && dimmest_quantile < 1)) {
    msg << "ResponseBracketPlanOptions::dimmest_quantile = " << dimmest_quantile << ": expected in [0, 1)";
  } else if (!(max_step_ratio > 1) || !std::isfinite(max_step_ratio)) {
    msg << "ResponseBracketPlanOptions::max_step_ratio = " << max_step_ratio << ": expected > 1";
  }
  *error = msg.str();
  return error->empty();
}

Status PlanResponseBracket(const ProbeMeasurement& brightest, const ProbeMeasurement& dimmest, const CameraInfo& camera,
                           double refresh_period_s, const ExposurePlanOptions& options,
                           const ResponseBracketPlanOptions& response, ExposurePlan* plan) {
  *plan = ExposurePlan();
  std::string error;
  if (!options.Check(&error) || !response.Check(&error)) return Status::Error(error);
  const double range = camera.saturation_dn - camera.black_level_dn;
  if (!(range > 0) || !std::isfinite(range)) {
    return Status::Error("PlanResponseBracket: camera '" + camera.id +
                         "' has no finite saturation level to plan against");
  }
  if (!(brightest.peak_dn_per_us > 0) || !(dimmest.peak_dn_per_us > 0)) {
    return Status::Error("exposure probe: " + brightest.label +
                         " shows no light: is the display on and in the camera's view?");
  }
  THINSLAB_RETURN_IF_ERROR(CheckBrightestUnsaturated(brightest, refresh_period_s));
  const double period_us = refresh_period_s > 0 ? refresh_period_s * 1e6 : 0;
  auto whole_periods = [period_us](double t) {
    return period_us > 0 ? std::max(1.0, std::round(t / period_us)) * period_us : std::max(t, 1.0);
  };
  std::ostringstream why;
  why << std::setprecision(3);
  double shortest = std::max(options.min_exposure_us, response.low_fill * range / brightest.peak_dn_per_us);
  shortest = whole_periods(std::min(shortest, options.max_exposure_us));
  why << "shortest " << DurationText(shortest) << ": " << brightest.label << " peaks at "
      << Num(brightest.peak_dn_per_us) << " DN/us, " << Num(100 * brightest.peak_dn_per_us * shortest / range)
      << " % of the range there (the response's low end; aimed at " << Num(100 * response.low_fill) << " %)";
  double longest = response.high_fill * range / dimmest.peak_dn_per_us;
  std::string capped;
  if (longest > options.max_exposure_us) {
    longest = options.max_exposure_us;
    capped = " (capped by the longest allowed, " + DurationText(options.max_exposure_us) + ")";
  }
  longest = std::max(shortest, whole_periods(longest));
  why << "; longest " << DurationText(longest) << ": " << dimmest.label << " at " << Num(dimmest.peak_dn_per_us)
      << " DN/us reach " << Num(100 * dimmest.peak_dn_per_us * longest / range) << " % of the range there" << capped
      << " (the response's high end; aimed at " << Num(100 * response.high_fill) << " %)";
  plan->exposures_us = GeometricBracket(shortest, longest, response.max_step_ratio, refresh_period_s, &why);
  plan->probes = {brightest, dimmest};
  plan->why = why.str();
  return Status::Ok();
}

Status ProbeAndPlanResponseBracket(Camera* camera, Projector* projector, const SampleChanger& change_sample,
                                   const std::string& pattern, const ExposurePlanOptions& options,
                                   const ResponseBracketPlanOptions& response, ExposurePlan* plan) {
  *plan = ExposurePlan();
  std::string error;
  if (!options.Check(&error) || !response.Check(&error)) return Status::Error("exposure probe: " + error);
  const double period_s = projector->refresh_period_s();
  const double probe_us = options.probe_exposure_us > 0 ? options.probe_exposure_us
                          : period_s > 0                ? period_s * 1e6
                                                        : 1000;
  Prober prober(camera, options, period_s);
  THINSLAB_RETURN_IF_ERROR(change_sample("none"));
  ProbeMeasurement brightest, dimmest;
  Image frame;
  const std::string label = "the '" + pattern + "' pattern";
  THINSLAB_RETURN_IF_ERROR(prober.Measure(
      label + "'s brightest pixel", [&]() { return projector->ShowPattern(pattern); }, true, probe_us, &brightest,
      &frame));
  // The dimmest lit pixels: a low quantile of the pixels above a tenth of the brightest (the
  // unlit rest of the view has no response to calibrate).
  const double black = camera->info().black_level_dn;
  const double peak_dn = brightest.peak_dn_per_us * brightest.exposure_us;
  std::vector<float> lit;
  for (float v : frame.data()) {
    if (v - black > 0.1 * peak_dn) lit.push_back(static_cast<float>(v - black));
  }
  dimmest = brightest;
  dimmest.label = label + "'s dimmest lit pixels (" + Num(100 * response.dimmest_quantile) + "th percentile)";
  dimmest.peak_dn_per_us = lit.empty() ? 0 : Quantile(lit, response.dimmest_quantile) / brightest.exposure_us;
  THINSLAB_RETURN_IF_ERROR(projector->ShowPattern(""));
  return PlanResponseBracket(brightest, dimmest, camera->info(), period_s, options, response, plan);
}

Status ProbeAndPlanDisplayGammaExposures(Camera* camera, Projector* projector, const SampleChanger& change_sample,
                                         int steps, const ExposurePlanOptions& options, ExposurePlan* plan) {
  *plan = ExposurePlan();
  std::string error;
  if (!options.Check(&error)) return Status::Error("exposure probe: " + error);
  if (steps < 2 || steps > 255) {
    return Status::Error("exposure probe: display gamma steps = " + std::to_string(steps) + ": expected 2..255");
  }
  const double period_s = projector->refresh_period_s();
  const double probe_us = options.probe_exposure_us > 0 ? options.probe_exposure_us
                          : period_s > 0                ? period_s * 1e6
                                                        : 1000;
  Prober prober(camera, options, period_s);
  auto show = [projector](const std::string& pattern) {
    return [projector, pattern]() { return projector->ShowPattern(pattern); };
  };
  THINSLAB_RETURN_IF_ERROR(change_sample("none"));
  ProbeMeasurement brightest, black, first;
  Image full_frame, black_frame, first_frame;
  THINSLAB_RETURN_IF_ERROR(
      prober.Measure("level 1", show(FlatPatternId(1.0)), true, probe_us, &brightest, &full_frame));
  // Level 1/steps is ~(1/steps)^2.2 of level 1 on a gamma 2.2 display: probed long, like the black.
  const double long_us = std::min(64 * probe_us, options.max_exposure_us);
  THINSLAB_RETURN_IF_ERROR(
      prober.Measure("the display black", show(FlatPatternId(0.0)), false, long_us, &black, &black_frame));
  std::ostringstream level;
  level << "level 1/" << steps;
  THINSLAB_RETURN_IF_ERROR(prober.Measure(level.str() + " above black", show(FlatPatternId(1.0 / steps)), false,
                                          long_us, &first, &first_frame));
  THINSLAB_RETURN_IF_ERROR(projector->ShowPattern(""));
  // The signal of the first level, per pixel of the lit region: its rate less the black's.
  const double black_dn = camera->info().black_level_dn;
  const float threshold = 0.5f * static_cast<float>(Quantile(full_frame.data(), 0.99) - black_dn);
  std::vector<float> signal;
  for (size_t i = 0; i < full_frame.data().size(); ++i) {
    if (full_frame.data()[i] - black_dn <= threshold) continue;
    signal.push_back(static_cast<float>((first_frame.data()[i] - black_dn) / first.exposure_us -
                                        (black_frame.data()[i] - black_dn) / black.exposure_us));
  }
  first.peak_dn_per_us = signal.empty() ? 0 : std::max(0.0, Median(signal));
  ExposurePlanOptions gamma = options;
  gamma.edge_fraction = 1;  // The level itself is the signal of interest.
  return PlanExposures(brightest, black, {first}, camera->info(), period_s, gamma, plan);
}

}  // namespace thinslab
