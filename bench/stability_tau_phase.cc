// SPDX-License-Identifier: Apache-2.0
// Stability sweep of issue #8 for the tau fit (Gu et al. 2007 Eqs. 5-7) and the laser-lobe g
// fit (Gu Eq. 8): each axis of tests/stability_tau_phase_test.cc, finer, on the same CI-sized
// simulated rigs (app/stability_cases.h). Writes one CSV and one PNG chart per axis: the error
// against the axis with the tolerance the test states, and where the fit flags instead of
// fitting (the failure boundaries). docs/stability.md reads its figures off them.
//
//   stability_tau_phase OUT_DIR [axis ...]
//   axes: tau_level exposure pose g_value g_tau g_noise coverage (default: all)
//   e.g. build-stab/bench/stability_tau_phase docs/stability
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <string>
#include <vector>

#include "thinslab/app/stability_cases.h"
#include "thinslab/core/plot.h"
#include "thinslab/sim/contamination_pattern.h"

namespace thinslab {
namespace {

// Tolerances of tests/stability_tau_phase_test.cc, drawn on the charts.
constexpr double kNominalMaxRmsAbsErrorTau = 0.01;
constexpr double kMaxErrorOverSigmaTau = 1.5;
constexpr double kMaxAbsErrorG = 0.03;
constexpr int kTextureSize = 48;

constexpr int kBlue = 0x1f77b4, kRed = 0xd62728, kGreen = 0x2ca02c, kOrange = 0xff7f0e, kGrey = 0x7f7f7f,
              kPurple = 0x9467bd;

PlotSeries Series(const std::string& label, int color, bool line) {
  PlotSeries s;
  s.label = label;
  s.color_bgr = color;
  s.line = line;
  return s;
}

PlotSeries HorizontalLine(const std::string& label, double y, double x0, double x1, int color) {
  PlotSeries s = Series(label, color, true);
  s.x = {x0, x1};
  s.y = {y, y};
  return s;
}

double Fraction(int64_t n, int64_t total) { return total > 0 ? static_cast<double>(n) / total : 0; }

std::string CsvText(std::string s) {
  for (char& c : s) {
    if (c == '"' || c == '\n' || c == ',') c = ';';
  }
  return "\"" + s + "\"";
}

// ---- tau axes ----

struct TauPoint {
  double axis = 0, x = 0;  // x: the plotted coordinate (log10 for log axes).
  TauStabilityResult r;
};

Status RunTauAxis(const std::string& out_dir, const std::string& axis, const std::vector<double>& values, bool log_x,
                  const std::function<TauStabilityCase(double)>& make, std::vector<TauPoint>* points) {
  std::ofstream csv(out_dir + "/tau_" + axis + ".csv");
  csv << axis << ",fitted,pixels,ok,dark,dark_noise,saturated,outside,clamped,next_to_clamped,non_finite,"
      << "invalid_status,rms_abs_error,rms_sigma_tau,mean_error,max_abs_error,rms_abs_error_plain,"
      << "rms_abs_error_realigned,ok_beyond_tau_max,clamped_below_tau_max,split_half_rms_z,"
      << "mean_scattered_fraction,seconds,message\n";
  const std::string work = out_dir + "/work_" + axis;
  for (double v : values) {
    std::filesystem::remove_all(work);
    TauPoint p;
    p.axis = v;
    p.x = log_x ? std::log10(v) : v;
    const auto t0 = std::chrono::steady_clock::now();
    THINSLAB_RETURN_IF_ERROR(RunTauStabilityCase(make(v), work, &p.r));
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const TauStabilityResult& r = p.r;
    char line[2048];
    std::snprintf(line, sizeof(line),
                  "%g,%d,%lld,%lld,%lld,%lld,%lld,%lld,%lld,%lld,%lld,%lld,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%lld,%lld,%.6g,"
                  "%.6g,%.2f,%s\n",
                  v, r.pipeline.ok() ? 1 : 0, static_cast<long long>(r.pixels), static_cast<long long>(r.ok),
                  static_cast<long long>(r.dark), static_cast<long long>(r.summary.pixels_dark_noise),
                  static_cast<long long>(r.saturated), static_cast<long long>(r.outside),
                  static_cast<long long>(r.clamped), static_cast<long long>(r.next_to_clamped),
                  static_cast<long long>(r.non_finite_values), static_cast<long long>(r.invalid_status),
                  r.rms_abs_error, r.rms_sigma_tau, r.mean_error, r.max_abs_error, r.rms_abs_error_plain,
                  r.rms_abs_error_realigned, static_cast<long long>(r.ok_beyond_tau_max),
                  static_cast<long long>(r.clamped_below_tau_max), r.consistency_rms_z,
                  r.summary.mean_scattered_fraction, seconds,
                  CsvText(r.pipeline.ok() ? r.summary.message : r.pipeline.message()).c_str());
    csv << line;
    std::fprintf(stderr, "tau %s %g: %s", axis.c_str(), v, line);
    points->push_back(p);
  }
  std::filesystem::remove_all(work);
  return Status::Ok();
}

// Upper panel: RMS error of the ok pixels, the fit's own RMS sigma_tau, the tolerances.
// Lower panel: fraction of the map per outcome (a refused capture counts as all flagged).
Status WriteTauChart(const std::string& path, const std::string& title, const std::string& x_label,
                     const std::vector<TauPoint>& points, bool realigned) {
  PlotSeries error = Series("RMS |tau - tau_true| (status ok)", kBlue, false);
  PlotSeries sigma = Series("RMS sigma_tau (the fit's own)", kOrange, true);
  PlotSeries aligned = Series("RMS error vs shifted truth", kGreen, false);
  PlotSeries ok = Series("ok", kBlue, true), dark = Series("dark", kGrey, true),
             saturated = Series("saturated", kOrange, true), clamped = Series("clamped + next to clamped", kRed, true),
             refused = Series("capture refused (message)", kPurple, false);
  for (const TauPoint& p : points) {
    const TauStabilityResult& r = p.r;
    if (r.pipeline.ok() && r.ok > 0) {
      error.x.push_back(p.x);
      error.y.push_back(std::max(r.rms_abs_error, 1e-5));
      sigma.x.push_back(p.x);
      sigma.y.push_back(std::max(r.rms_sigma_tau, 1e-5));
      aligned.x.push_back(p.x);
      aligned.y.push_back(std::max(r.rms_abs_error_realigned, 1e-5));
    }
    const int64_t n = std::max<int64_t>(r.pixels, 1);
    ok.x.push_back(p.x);
    ok.y.push_back(r.pipeline.ok() ? Fraction(r.ok, n) : 0);
    dark.x.push_back(p.x);
    dark.y.push_back(r.pipeline.ok() ? Fraction(r.dark, n) : 0);
    saturated.x.push_back(p.x);
    saturated.y.push_back(r.pipeline.ok() ? Fraction(r.saturated, n) : 0);
    clamped.x.push_back(p.x);
    clamped.y.push_back(r.pipeline.ok() ? Fraction(r.clamped + r.next_to_clamped, n) : 0);
    if (!r.pipeline.ok()) {
      refused.x.push_back(p.x);
      refused.y.push_back(1);
    }
  }
  const double x0 = points.front().x, x1 = points.back().x;
  PlotPanel errors;
  errors.log_y = true;
  errors.y_label = "tau error";
  errors.height_weight = 2;
  errors.series = {error, sigma};
  if (realigned) errors.series.push_back(aligned);
  errors.series.push_back(HorizontalLine("nominal tolerance (test)", kNominalMaxRmsAbsErrorTau, x0, x1, kRed));
  errors.legend_bottom_left = false;
  PlotPanel outcome;
  outcome.y_label = "fraction of map";
  outcome.series = {ok, dark, saturated, clamped};
  if (!refused.x.empty()) outcome.series.push_back(refused);
  outcome.legend_bottom_left = true;
  PlotOptions options;
  options.title = title;
  options.x_label = x_label;
  return WritePlotPng(path, {errors, outcome}, options);
}

// ---- g axes ----

struct GPoint {
  double axis = 0, x = 0, g_true = 0;
  PhaseStabilityResult r;
};

Status RunGAxis(const std::string& out_dir, const std::string& axis, const std::vector<double>& values, bool log_x,
                const std::function<PhaseStabilityCase(double)>& make, std::vector<GPoint>* points) {
  std::ofstream csv(out_dir + "/g_" + axis + ".csv");
  csv << axis << ",g_true,result,g,sigma_g,sigma_g_covariance,sigma_g_jackknife,sigma_g_range,error,error_in_sigma,"
      << "chi2_reduced,detection_significance,rings,summary_finite,non_finite_in_files,seconds,message\n";
  const std::string work = out_dir + "/work_" + axis;
  for (double v : values) {
    std::filesystem::remove_all(work);
    GPoint p;
    p.axis = v;
    p.x = log_x ? std::log10(v) : v;
    const PhaseStabilityCase c = make(v);
    p.g_true = c.sim.rig.layer_g;
    const auto t0 = std::chrono::steady_clock::now();
    THINSLAB_RETURN_IF_ERROR(RunPhaseStabilityCase(c, work, &p.r));
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const PhaseFitSummary& s = p.r.summary;
    const double error = s.g - p.g_true;
    char line[2048];
    std::snprintf(line, sizeof(line), "%g,%g,%s,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%d,%d,%lld,%.2f,%s\n", v,
                  p.g_true, s.ResultName().c_str(), s.g, s.sigma_g, s.sigma_g_covariance, s.sigma_g_jackknife,
                  s.sigma_g_range, error, s.sigma_g > 0 ? std::abs(error) / s.sigma_g : 0.0, s.chi2_reduced,
                  s.detection_significance, s.num_rings, p.r.summary_finite ? 1 : 0,
                  static_cast<long long>(p.r.non_finite_in_files), seconds, CsvText(s.message).c_str());
    csv << line;
    std::fprintf(stderr, "g %s %g: %s", axis.c_str(), v, line);
    points->push_back(p);
  }
  std::filesystem::remove_all(work);
  return Status::Ok();
}

// Upper panel: g - g_true +- sigma_g of the successes, the +-tolerance band. Lower panel: the
// result per case (success, no measurable scattering, failure with a message).
Status WriteGChart(const std::string& path, const std::string& title, const std::string& x_label,
                   const std::vector<GPoint>& points) {
  PlotSeries error = Series("g - g_true +- sigma_g (success)", kBlue, false);
  PlotSeries success = Series("success", kBlue, false), none = Series("no measurable scattering", kGrey, false),
             failure = Series("failure: g not determined (message)", kRed, false);
  for (const GPoint& p : points) {
    const PhaseFitSummary& s = p.r.summary;
    if (s.IsUsable()) {
      error.x.push_back(p.x);
      error.y.push_back(s.g - p.g_true);
      error.y_error.push_back(s.sigma_g);
      success.x.push_back(p.x);
      success.y.push_back(1);
    } else if (s.result == PhaseFitSummary::Result::kNoMeasurableScattering) {
      none.x.push_back(p.x);
      none.y.push_back(0);
    } else {
      failure.x.push_back(p.x);
      failure.y.push_back(-1);
    }
  }
  const double x0 = points.front().x, x1 = points.back().x;
  PlotPanel errors;
  errors.y_label = "g error";
  errors.height_weight = 2;
  errors.zero_line = true;
  errors.series = {error, HorizontalLine("+-tolerance (test)", kMaxAbsErrorG, x0, x1, kRed),
                   HorizontalLine("", -kMaxAbsErrorG, x0, x1, kRed)};
  PlotPanel outcome;
  outcome.y_label = "result: 1 success, 0 no scattering, -1 failure";
  outcome.series = {success};
  if (!none.x.empty()) outcome.series.push_back(none);
  if (!failure.x.empty()) outcome.series.push_back(failure);
  outcome.legend_bottom_left = true;
  PlotOptions options;
  options.title = title;
  options.x_label = x_label;
  return WritePlotPng(path, {errors, outcome}, options);
}

TauStabilityCase SpecksCase(const Image& specks) {
  TauStabilityCase c;
  c.sim = SmallShadowMapRig(1);
  c.tau_true = specks;
  return c;
}

// ---- coverage (issue #24 section 4) ----

// Fraction of the status-ok estimates within 1 and 2 sigma of the truth, and the share of
// estimates that are status ok, per capture made harder than the fitted model on purpose.
struct CoveragePoint {
  std::string fit, name;
  double within_1 = 0, within_2 = 0, ok = 0;
  int64_t estimates = 0;
};

Status RunTauCoverage(const std::string& out_dir, const Image& specks, std::vector<CoveragePoint>* points) {
  const double patch_taus[4] = {0.5, 1, 2, 3};
  struct Named {
    std::string name;
    std::function<void(TauStabilityCase*)> change;
  };
  const std::vector<Named> cases = {
      {"nominal (specks, 320 x 240 camera, board 1 mm)", [](TauStabilityCase*) {}},
      {"texture finer than the camera (80 x 60 camera)",
       [](TauStabilityCase* c) {
         c->sim.rig.camera_width_px = 80;
         c->sim.rig.camera_height_px = 60;
       }},
      {"one linear float frame, value scale 1000, no gain",
       [](TauStabilityCase* c) {
         c->sim.rig.sensor.linear_float_frames = true;
         c->sim.rig.sensor.value_scale = 1000;
         c->sim.session.frames_per_state = 1;
       }},
      {"photon-starved: exposure x0.01", [](TauStabilityCase* c) { c->sim.session.exposure_time_us *= 0.01; }},
      {"multiple scattering: albedo 0.9, board 5 mm",
       [](TauStabilityCase* c) {
         c->sim.rig.layer_albedo = 0.9;
         c->sim.rig.board_distance_m = 5e-3;
       }},
      {"board 10 mm", [](TauStabilityCase* c) { c->sim.rig.board_distance_m = 10e-3; }},
      {"uniform tau 2", [](TauStabilityCase* c) { c->tau_true = UniformTau(kTextureSize, kTextureSize, 2); }},
      {"hard edges: patches tau 0.5-3",
       [&](TauStabilityCase* c) { c->tau_true = PatchTau(kTextureSize, kTextureSize, patch_taus, 0); }},
      {"reference judged from the shadow (auto)", [](TauStabilityCase* c) { c->run.fit.reference = "auto"; }},
  };
  const std::string work = out_dir + "/work_coverage";
  for (const Named& named : cases) {
    std::filesystem::remove_all(work);
    TauStabilityCase c = SpecksCase(specks);
    named.change(&c);
    TauStabilityResult r;
    THINSLAB_RETURN_IF_ERROR(RunTauStabilityCase(c, work, &r));
    CoveragePoint p;
    p.fit = "tau";
    p.name = named.name;
    p.estimates = r.ok;
    p.within_1 = Fraction(r.within_1_sigma, r.ok);
    p.within_2 = Fraction(r.within_2_sigma, r.ok);
    p.ok = r.pipeline.ok() ? Fraction(r.ok, r.pixels - r.outside) : 0;
    std::fprintf(stderr, "coverage tau, %s: %.3f / %.3f, ok %.3f; RMS error %.4f, bias %+.4f, RMS sigma_tau %.4f (%s)\n",
                 p.name.c_str(), p.within_1, p.within_2, p.ok, r.rms_abs_error, r.mean_error, r.rms_sigma_tau,
                 r.pipeline.ok() ? "fitted" : r.pipeline.message().c_str());
    points->push_back(p);
  }
  std::filesystem::remove_all(work);
  return Status::Ok();
}

// g: one estimate per capture, so coverage is over seeds of each case.
Status RunGCoverage(const std::string& out_dir, int seeds, std::vector<CoveragePoint>* points) {
  struct Named {
    std::string name;
    double tau, g;
    std::function<void(PhaseStabilityCase*)> change;
  };
  const std::vector<Named> cases = {
      {"g 0.2 (tau 0.3, albedo 0.3: multiple scattering)", 0.3, 0.2, [](PhaseStabilityCase*) {}},
      {"g 0.5", 0.3, 0.5, [](PhaseStabilityCase*) {}},
      {"g 0.8", 0.3, 0.8, [](PhaseStabilityCase*) {}},
      {"g 0.8, tau 1 (more multiple scattering)", 1.0, 0.8, [](PhaseStabilityCase*) {}},
      {"g 0.5, photon-starved single float exposure, no gain",
       0.3, 0.5,
       [](PhaseStabilityCase* c) {
         c->sim.rig.sensor.linear_float_frames = true;
         c->sim.rig.sensor.read_noise_e = 0;
         c->sim.session.exposure_times_us = {200};
       }},
  };
  const std::string work = out_dir + "/work_coverage_g";
  for (const Named& named : cases) {
    CoveragePoint p;
    p.fit = "g";
    p.name = named.name;
    int64_t usable = 0, within_1 = 0, within_2 = 0;
    for (int seed = 1; seed <= seeds; ++seed) {
      std::filesystem::remove_all(work);
      PhaseStabilityCase c;
      c.sim = SmallLaserLobeRig(named.tau, named.g, 100 + seed);
      c.fit.tau = named.tau;
      named.change(&c);
      PhaseStabilityResult r;
      THINSLAB_RETURN_IF_ERROR(RunPhaseStabilityCase(c, work, &r));
      const PhaseFitSummary& s = r.summary;
      if (!r.pipeline.ok() || !s.IsUsable()) continue;
      std::fprintf(stderr,
                   "  seed %d: g %.4f +- %.4f (cov %.4f jack %.4f range %.4f second-order %.4f [predicted c %.3f: "
                   "%.4f] choice %.4f), theta_max %.0f, chi2/dof %.1f\n",
                   100 + seed, s.g, s.sigma_g, s.sigma_g_covariance, s.sigma_g_jackknife, s.sigma_g_range,
                   s.sigma_g_multiple, s.predicted_second_order_fraction, s.sigma_g_predicted_second_order,
                   s.sigma_g_choice, s.max_theta_deg, s.chi2_reduced);
      ++usable;
      within_1 += std::abs(s.g - named.g) <= s.sigma_g;
      within_2 += std::abs(s.g - named.g) <= 2 * s.sigma_g;
    }
    p.estimates = usable;
    p.within_1 = Fraction(within_1, usable);
    p.within_2 = Fraction(within_2, usable);
    p.ok = Fraction(usable, seeds);
    std::fprintf(stderr, "coverage g, %s: %.3f / %.3f, ok %.3f\n", p.name.c_str(), p.within_1, p.within_2, p.ok);
    points->push_back(p);
  }
  std::filesystem::remove_all(work);
  return Status::Ok();
}

Status WriteCoverage(const std::string& out_dir, const std::vector<CoveragePoint>& points) {
  std::ofstream csv(out_dir + "/coverage.csv");
  csv << "fit,case,index,estimates,within_1_sigma,within_2_sigma,ok_fraction\n";
  std::vector<PlotPanel> panels;
  for (const std::string fit : {"tau", "g"}) {
    PlotSeries one = Series("within 1 sigma", kBlue, false), two = Series("within 2 sigma", kGreen, false),
               ok = Series("status ok / usable", kGrey, false);
    int index = 0;
    for (const CoveragePoint& p : points) {
      if (p.fit != fit) continue;
      ++index;
      csv << p.fit << "," << CsvText(p.name) << "," << index << "," << p.estimates << "," << p.within_1 << ","
          << p.within_2 << "," << p.ok << "\n";
      one.x.push_back(index);
      one.y.push_back(p.within_1);
      two.x.push_back(index);
      two.y.push_back(p.within_2);
      ok.x.push_back(index);
      ok.y.push_back(p.ok);
    }
    if (index == 0) continue;
    PlotPanel panel;
    panel.y_label = fit + " coverage (cases: coverage.csv)";
    panel.series = {one, two, ok, HorizontalLine("goal 1 sigma (60 %)", 0.6, 1, index, kRed),
                    HorizontalLine("goal 2 sigma (90 %)", 0.9, 1, index, kOrange)};
    panel.legend_bottom_left = true;
    panels.push_back(panel);
  }
  PlotOptions options;
  options.title = "coverage of sigma on captures harder than the fitted models (issue #24)";
  options.x_label = "case (docs/stability.md, coverage.csv)";
  return WritePlotPng(out_dir + "/coverage.png", panels, options);
}

Status Run(const std::string& out_dir, const std::set<std::string>& axes) {
  auto want = [&](const std::string& a) { return axes.empty() || axes.count(a) > 0; };
  ContaminationPatternOptions pattern;
  pattern.width_px = kTextureSize;
  pattern.height_px = kTextureSize;
  pattern.num_dust_specks = 6;
  const Image specks = GenerateContaminationPattern(pattern);

  if (want("tau_level")) {
    std::vector<TauPoint> points;
    THINSLAB_RETURN_IF_ERROR(RunTauAxis(
        out_dir, "tau_level",
        {0.001, 0.002, 0.005, 0.01, 0.02, 0.05, 0.1, 0.2, 0.5, 1, 1.5, 2, 2.5, 3, 3.5, 3.8, 4, 4.2, 4.5, 5, 6}, true,
        [&](double tau) {
          TauStabilityCase c = SpecksCase(specks);
          c.tau_true = UniformTau(kTextureSize, kTextureSize, tau);
          return c;
        },
        &points));
    THINSLAB_RETURN_IF_ERROR(WriteTauChart(out_dir + "/tau_level.png",
                                           "tau fit: uniform layer of optical thickness tau (tau_max 4)",
                                           "log10 tau_true", points, false));
  }
  if (want("exposure")) {
    std::vector<TauPoint> points;
    THINSLAB_RETURN_IF_ERROR(RunTauAxis(
        out_dir, "exposure",
        {0.0001, 0.0003, 0.001, 0.002, 0.003, 0.005, 0.01, 0.03, 0.1, 0.3, 1, 1.2, 1.3, 1.4, 1.5, 2, 5, 10}, true,
        [&](double scale) {
          TauStabilityCase c = SpecksCase(specks);
          c.sim.session.exposure_time_us = scale * c.sim.rig.exposure_time_us;
          return c;
        },
        &points));
    THINSLAB_RETURN_IF_ERROR(WriteTauChart(out_dir + "/tau_exposure.png",
                                           "tau fit: exposure (1 = clean board at 75 % of full well)",
                                           "log10 exposure scale", points, false));
  }
  if (want("pose")) {
    std::vector<TauPoint> points;
    THINSLAB_RETURN_IF_ERROR(RunTauAxis(
        out_dir, "pose", {0, 0.5, 1, 1.5, 2, 2.5, 3, 4, 5}, false,
        [&](double px) {
          TauStabilityCase c = SpecksCase(specks);
          c.pose_error_px = px;
          return c;
        },
        &points));
    THINSLAB_RETURN_IF_ERROR(WriteTauChart(out_dir + "/tau_pose.png",
                                           "tau fit: camera pose error in the manifest (image x)",
                                           "pose error [camera pixels]", points, true));
  }
  if (want("g_value")) {
    std::vector<GPoint> points;
    THINSLAB_RETURN_IF_ERROR(RunGAxis(
        out_dir, "g_value", {0, 0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.85, 0.9, 0.93, 0.95, 0.97, 0.98, 0.99}, false,
        [&](double g) {
          PhaseStabilityCase c;
          c.sim = SmallLaserLobeRig(0.3, g, 1);
          return c;
        },
        &points));
    THINSLAB_RETURN_IF_ERROR(
        WriteGChart(out_dir + "/g_value.png", "g fit (Gu Eq. 8): HG g of the layer, tau 0.3", "g_true", points));
  }
  if (want("g_tau")) {
    std::vector<GPoint> points;
    THINSLAB_RETURN_IF_ERROR(RunGAxis(
        out_dir, "g_tau", {1e-8, 3e-8, 1e-7, 3e-7, 1e-6, 3e-6, 1e-5, 1e-4, 1e-3, 0.01, 0.1, 0.3, 1, 2, 3}, true,
        [&](double tau) {
          PhaseStabilityCase c;
          c.sim = SmallLaserLobeRig(tau, 0.8, 2);
          c.fit.tau = tau;
          return c;
        },
        &points));
    THINSLAB_RETURN_IF_ERROR(
        WriteGChart(out_dir + "/g_tau.png", "g fit (Gu Eq. 8): layer tau, g 0.8", "log10 tau_true", points));
  }
  if (want("coverage")) {
    std::vector<CoveragePoint> points;
    THINSLAB_RETURN_IF_ERROR(RunTauCoverage(out_dir, specks, &points));
    THINSLAB_RETURN_IF_ERROR(RunGCoverage(out_dir, 4, &points));
    THINSLAB_RETURN_IF_ERROR(WriteCoverage(out_dir, points));
  }
  if (want("g_noise")) {
    std::vector<GPoint> points;
    THINSLAB_RETURN_IF_ERROR(RunGAxis(
        out_dir, "g_noise", {6, 30, 100, 200, 300, 400, 500, 700, 1000, 3000}, true,
        [&](double read_noise_e) {
          PhaseStabilityCase c;
          c.sim = SmallLaserLobeRig(0.3, 0.8, 1);
          c.sim.rig.sensor.read_noise_e = read_noise_e;
          c.sim.session.exposure_times_us = {20, 200, 2000};
          return c;
        },
        &points));
    THINSLAB_RETURN_IF_ERROR(WriteGChart(out_dir + "/g_noise.png",
                                         "g fit (Gu Eq. 8): read noise, 3-exposure bracket (20-2000 us)",
                                         "log10 read noise [e-]", points));
  }
  return Status::Ok();
}

}  // namespace
}  // namespace thinslab

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: stability_tau_phase OUT_DIR [tau_level|exposure|pose|g_value|g_tau|g_noise|coverage ...]\n");
    return 2;
  }
  const std::string out_dir = argv[1];
  std::set<std::string> axes;
  for (int k = 2; k < argc; ++k) axes.insert(argv[k]);
  for (const std::string& a : axes) {
    if (a != "tau_level" && a != "exposure" && a != "pose" && a != "g_value" && a != "g_tau" && a != "g_noise" &&
        a != "coverage") {
      std::fprintf(stderr, "stability_tau_phase: unknown axis '%s'\n", a.c_str());
      return 2;
    }
  }
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec) {
    std::fprintf(stderr, "stability_tau_phase: cannot create %s: %s\n", out_dir.c_str(), ec.message().c_str());
    return 1;
  }
  const auto t0 = std::chrono::steady_clock::now();
  const thinslab::Status status = thinslab::Run(out_dir, axes);
  if (!status.ok()) {
    std::fprintf(stderr, "error: %s\n", status.message().c_str());
    return 1;
  }
  std::fprintf(stderr, "sweep done in %.0f s\n",
               std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return 0;
}
