// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/knob_sweep.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

#include "thinslab/core/parallel.h"
#include "thinslab/core/plot.h"
#include "thinslab/fit/dmf_model_ladder.h"
#include "thinslab/fit/single_interface_fit.h"
#include "thinslab/fit/tau_evaluation.h"

namespace thinslab {
namespace {

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

double Median(std::vector<double> v) {
  if (v.empty()) return -1;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

std::string Number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%g", v);
  return buf;
}

// Mean over the one-sided regions of their median NDF relative L2; -1 without truth.
double MeanNdfError(const DmfSliceSet& slices, const DmfMaps& maps, const std::vector<DmfTruthRegion>& truth) {
  if (truth.empty()) return -1;
  double sum = 0;
  int n = 0;
  for (const DmfRegionAccuracy& a : CompareDmfWithTruth(slices, maps, truth)) {
    if (a.median_ndf_l2 < 0) continue;
    sum += a.median_ndf_l2;
    ++n;
  }
  return n > 0 ? sum / n : -1;
}

Status ScoreDmfConfiguration(const DmfSliceSet& slices, const std::vector<DmfTruthRegion>& truth,
                             const DmfMapFitOptions& options, SweepPoint* point) {
  DmfMaps maps;
  THINSLAB_RETURN_IF_ERROR(FitDualMicrofacetMaps(slices, options, &maps)
                               .WithContext("knob " + point->knob + " = " + point->value));
  point->seconds = maps.timings.total_s;
  std::vector<double> errors;
  for (int p = 0; p < slices.num_points(); ++p) {
    const double e = DmfHeldOutError(slices, maps, p);
    if (e >= 0) errors.push_back(e);
  }
  point->error = Median(errors);
  point->truth_error = MeanNdfError(slices, maps, truth);
  const int cells = DmfNdfGrid(options.point.ndf_resolution).num_unknowns();
  point->fitted_points = maps.num_fitted;
  point->parameters = maps.num_fitted * (cells + 3);  // NDF cells, alpha, smith_alpha, k_s.
  return Status::Ok();
}

// Rungs 3 and 4 of the model ladder fitted at every point, timed as a whole (wall time on the
// same threads as the map fit), scored on the held-out dots.
template <typename Fit, typename Predict>
void ScoreRung(const DmfSliceSet& slices, const DmfPointFitOptions& point_options, int num_threads, const Fit& fit,
               const Predict& predict, SweepPoint* point) {
  std::vector<double> errors(slices.num_points(), -1);
  const auto start = std::chrono::steady_clock::now();
  ParallelFor(slices.num_points(), num_threads, [&](int p) {
    if (!slices.point_status.empty() && slices.point_status[p] != static_cast<uint8_t>(DmfStatus::kOk)) return;
    const DmfSlice slice = slices.Slice(p);
    if (PrecheckSlice(slice, point_options) != DmfStatus::kOk) return;
    const auto fitted = fit(slice);
    if (!fitted.ok) return;
    errors[p] = HeldOutRelativeRms(slice, 0.1, [&](const Eigen::Vector3d& i, const Eigen::Vector3d& o) {
      return predict(fitted, i, o);
    });
  });
  point->seconds = Seconds(start);
  errors.erase(std::remove(errors.begin(), errors.end(), -1.0), errors.end());
  point->error = Median(errors);
}

}  // namespace

void MarkParetoFront(std::vector<SweepPoint>* points) {
  for (SweepPoint& a : *points) {
    a.pareto = a.error >= 0;
    for (const SweepPoint& b : *points) {
      if (!a.pareto) break;
      if (&a == &b || b.method != a.method || b.error < 0) continue;
      const bool no_worse = b.seconds <= a.seconds && b.error <= a.error;
      const bool better = b.seconds < a.seconds || b.error < a.error;
      if (no_worse && better) a.pareto = false;
    }
  }
}

Status SweepDmfKnobs(const DmfSliceSet& slices, const std::vector<DmfTruthRegion>& truth,
                     const DmfSweepOptions& options, std::vector<SweepPoint>* points) {
  std::string error;
  if (!options.defaults.Check(&error)) return Status::Error("dmf sweep defaults: " + error);
  bool has_held_out = false;
  for (uint8_t t : slices.train) has_held_out |= t == 0;
  if (!has_held_out) return Status::Error("dmf sweep: the slices have no held-out dots (process with hold_out)");
  auto run = [&](const std::string& knob, const std::string& value, const DmfMapFitOptions& o) -> Status {
    SweepPoint p;
    p.method = "dmf";
    p.knob = knob;
    p.value = value;
    THINSLAB_RETURN_IF_ERROR(ScoreDmfConfiguration(slices, truth, o, &p));
    std::fprintf(stderr, "  dmf %s = %s: %.2f s, held-out %.4f, NDF L2 %.3f\n", knob.c_str(), value.c_str(), p.seconds,
                 p.error, p.truth_error);
    points->push_back(p);
    return Status::Ok();
  };
  const DmfMapFitOptions& d = options.defaults;
  THINSLAB_RETURN_IF_ERROR(run("default", "-", d));
  for (int n : options.ndf_resolutions) {
    if (n == d.point.ndf_resolution) continue;
    DmfMapFitOptions o = d;
    o.point.ndf_resolution = n;
    THINSLAB_RETURN_IF_ERROR(run("ndf_resolution", std::to_string(n), o));
  }
  for (double f : options.cluster_fractions) {
    if (d.cluster && f == d.clustering.fraction) continue;
    if (f == 0 && options.model_rungs) continue;  // Run below as rung 5.
    DmfMapFitOptions o = d;
    o.cluster = f > 0;
    if (f > 0) o.clustering.fraction = f;
    // The fraction alone sets the representatives here (the default's floor of
    // min_representatives would hide the knob on small grids); the label says how many.
    o.clustering.min_representatives = 1;
    THINSLAB_RETURN_IF_ERROR(run("cluster_fraction", f > 0 ? Number(f) : "every point", o));
    if (f > 0) points->back().value += " (" + std::to_string(points->back().fitted_points) + " fitted)";
  }
  for (int cap : options.alpha_iteration_caps) {
    if (cap == d.point.max_alpha_iterations) continue;
    DmfMapFitOptions o = d;
    o.point.max_alpha_iterations = cap;
    THINSLAB_RETURN_IF_ERROR(run("max_alpha_iterations", std::to_string(cap), o));
  }
  for (double w : options.smoothness) {
    if (w == d.point.smoothness) continue;
    DmfMapFitOptions o = d;
    o.point.smoothness = w;
    THINSLAB_RETURN_IF_ERROR(run("smoothness", Number(w), o));
  }
  if (options.smith_off && d.point.fit_smith_alpha) {
    DmfMapFitOptions o = d;
    o.point.fit_smith_alpha = false;
    THINSLAB_RETURN_IF_ERROR(run("fit_smith_alpha", "false", o));
  }
  // Combined fast settings: coarse NDF and few alternations on few representatives.
  {
    DmfMapFitOptions o = d;
    o.point.ndf_resolution = 16;
    o.point.max_alpha_iterations = 2;
    THINSLAB_RETURN_IF_ERROR(run("fast", "N16+2it", o));
    o.cluster = true;
    o.clustering.fraction = 0.03;
    o.clustering.min_representatives = 1;
    THINSLAB_RETURN_IF_ERROR(run("fast", "N16+2it+3%", o));
  }
  if (options.model_rungs) {
    const DmfPointFitOptions& po = d.point;
    // Rungs 3 and 4 as the ladder fits them: on the lobe's training dots.
    LadderOptions ladder;
    ladder.point = po;
    const DmfPointFitOptions rung_options = AnalyticRungOptions(ladder);
    SweepPoint single{"dmf", "model_rung", "3 single interface"};
    ScoreRung(slices, po, d.num_threads, [&](const DmfSlice& s) { return FitSingleInterface(s, rung_options); },
              [&](const SingleInterfaceFit& f, const Eigen::Vector3d& i, const Eigen::Vector3d& o) {
                return PredictSingleInterface(f, po.eta, i, o);
              },
              &single);
    single.parameters = 2 * slices.num_points();
    points->push_back(single);
    SweepPoint analytic{"dmf", "model_rung", "4 analytic DMF"};
    ScoreRung(slices, po, d.num_threads, [&](const DmfSlice& s) { return FitAnalyticDualMicrofacet(s, rung_options); },
              [&](const AnalyticDmfFit& f, const Eigen::Vector3d& i, const Eigen::Vector3d& o) {
                return PredictAnalyticDualMicrofacet(f, po.eta, i, o);
              },
              &analytic);
    analytic.parameters = 3 * slices.num_points();
    points->push_back(analytic);
    for (const SweepPoint* p : {&single, &analytic}) {
      std::fprintf(stderr, "  dmf model_rung = %s: %.2f s, held-out %.4f\n", p->value.c_str(), p->seconds, p->error);
    }
    // Rung 5 at every point is the unclustered tabulated fit (the cluster-fraction knob's "every
    // point", which is therefore not run twice).
    DmfMapFitOptions o = d;
    o.cluster = false;
    THINSLAB_RETURN_IF_ERROR(run("model_rung", "5 tabulated DMF (every point)", o));
  }
  MarkParetoFront(points);
  return Status::Ok();
}

Status SweepTauKnobs(const RectifiedShadowMaps& data, const Image& truth, const TauSweepOptions& options,
                     std::vector<SweepPoint>* points) {
  std::string error;
  if (!options.defaults.Check(&error)) return Status::Error("tau sweep defaults: " + error);
  if (truth.width() != data.shadow.width() || truth.height() != data.shadow.height()) {
    return Status::Error("tau sweep: the truth map is " + std::to_string(truth.width()) + " x " +
                         std::to_string(truth.height()) + ", the rectified grid " +
                         std::to_string(data.shadow.width()) + " x " + std::to_string(data.shadow.height()));
  }
  // Same range as `thinslab fit tau` compares over (app/fit_commands.cc).
  const double min_tau = 0.05, max_tau = 1.5;
  auto run = [&](const std::string& knob, const std::string& value, const TauFitOptions& o, bool plain) -> Status {
    TauMaps maps;
    TauFitSummary summary;
    THINSLAB_RETURN_IF_ERROR(FitTau(o, data, &maps, &summary).WithContext("knob " + knob + " = " + value));
    TauComparison cmp;
    THINSLAB_RETURN_IF_ERROR(CompareTauWithTruth(maps.tau, truth, min_tau, max_tau, &cmp));
    SweepPoint p;
    p.method = "tau";
    p.knob = knob;
    p.value = value;
    p.seconds = plain ? summary.plain_s : summary.total_s;
    const TauAccuracy& a = plain ? cmp.plain : cmp.refined;
    p.error = a.rms_relative;
    p.truth_error = a.mean_relative_bias;
    p.parameters = static_cast<int>(summary.pixels_fitted);
    std::fprintf(stderr, "  tau %s = %s: %.2f s, RMS rel %.4f, bias %+.4f\n", knob.c_str(), value.c_str(), p.seconds,
                 p.error, p.truth_error);
    points->push_back(p);
    return Status::Ok();
  };
  const TauFitOptions& d = options.defaults;
  THINSLAB_RETURN_IF_ERROR(run("default", "-", d, false));
  {
    TauFitOptions o = d;
    o.refine_scattering = false;
    THINSLAB_RETURN_IF_ERROR(run("model", "plain Eq. 7", o, true));
  }
  for (int cap : options.outer_iteration_caps) {
    if (cap == d.max_outer_iterations) continue;
    TauFitOptions o = d;
    o.max_outer_iterations = cap;
    THINSLAB_RETURN_IF_ERROR(run("max_outer_iterations", std::to_string(cap), o, false));
  }
  for (double s : options.smoothness_sigmas) {
    if (s == d.smoothness_sigma_tau) continue;
    TauFitOptions o = d;
    o.smoothness_sigma_tau = s;
    THINSLAB_RETURN_IF_ERROR(run("smoothness_sigma_tau", Number(s), o, false));
  }
  for (double a : options.kernel_max_angles_deg) {
    if (a == d.kernel_max_angle_deg) continue;
    TauFitOptions o = d;
    o.kernel_max_angle_deg = a;
    THINSLAB_RETURN_IF_ERROR(run("kernel_max_angle_deg", Number(a), o, false));
  }
  MarkParetoFront(points);
  return Status::Ok();
}

Status SweepPhaseKnobs(const LaserLobeImages& images, double g_true, const PhaseSweepOptions& options,
                       std::vector<SweepPoint>* points) {
  std::string error;
  if (!options.defaults.Check(&error)) return Status::Error("phase sweep defaults: " + error);
  auto run = [&](const std::string& knob, const std::string& value, const PhaseFitOptions& o) -> Status {
    std::vector<LaserRing> rings;
    PhaseFitSummary summary;
    THINSLAB_RETURN_IF_ERROR(FitPhase(o, images, &rings, &summary).WithContext("knob " + knob + " = " + value));
    SweepPoint p;
    p.method = "phase";
    p.knob = knob;
    p.value = value;
    p.seconds = summary.total_s;
    p.error = summary.IsUsable() ? std::abs(summary.g - g_true) : -1;
    p.truth_error = summary.IsUsable() ? summary.sigma_g : -1;
    p.parameters = o.tau_free ? 3 : 2;
    std::fprintf(stderr, "  phase %s = %s: %.4f s, %s, g %.4f (true %.4f) +- %.4f, %d rings\n", knob.c_str(),
                 value.c_str(), p.seconds, summary.ResultName().c_str(), summary.g, g_true, summary.sigma_g,
                 summary.num_rings);
    points->push_back(p);
    return Status::Ok();
  };
  const PhaseFitOptions& d = options.defaults;
  THINSLAB_RETURN_IF_ERROR(run("default", "-", d));
  auto sweep = [&](const std::string& knob, const std::vector<double>& values, double PhaseFitOptions::*field) {
    for (double v : values) {
      const bool fixes_theta = field == &PhaseFitOptions::max_theta_deg;
      if (v == d.*field && !(fixes_theta && d.max_theta_auto)) continue;
      PhaseFitOptions o = d;
      o.*field = v;
      if (fixes_theta) o.max_theta_auto = false;  // A fixed outermost angle instead of the choice.
      THINSLAB_RETURN_IF_ERROR(run(knob, Number(v), o));
    }
    return Status::Ok();
  };
  THINSLAB_RETURN_IF_ERROR(sweep("ring_width_px", options.ring_widths_px, &PhaseFitOptions::ring_width_px));
  THINSLAB_RETURN_IF_ERROR(sweep("max_theta_deg", options.max_thetas_deg, &PhaseFitOptions::max_theta_deg));
  THINSLAB_RETURN_IF_ERROR(sweep("core_beam_radii", options.core_beam_radii, &PhaseFitOptions::core_beam_radii));
  THINSLAB_RETURN_IF_ERROR(sweep("huber_scale", options.huber_scales, &PhaseFitOptions::huber_scale));
  if (options.tau_free && !d.tau_free) {
    PhaseFitOptions o = d;
    o.tau_free = true;
    THINSLAB_RETURN_IF_ERROR(run("tau_free", "true", o));
  }
  MarkParetoFront(points);
  return Status::Ok();
}

std::string SweepCsv(const std::vector<SweepPoint>& points) {
  // Labels are quoted when they hold a comma or a quote (RFC 4180).
  auto field = [](const std::string& text) {
    if (text.find_first_of(",\"") == std::string::npos) return text;
    std::string quoted = "\"";
    for (char c : text) quoted += c == '"' ? std::string("\"\"") : std::string(1, c);
    return quoted + "\"";
  };
  std::ostringstream csv;
  csv << "method,knob,value,seconds,error,truth_error,parameters,fitted_points,pareto\n";
  for (const SweepPoint& p : points) {
    csv << p.method << "," << field(p.knob) << "," << field(p.value) << "," << p.seconds << "," << p.error << "," << p.truth_error
        << "," << p.parameters << "," << p.fitted_points << "," << (p.pareto ? 1 : 0) << "\n";
  }
  return csv.str();
}

Status WriteSweepChart(const std::string& path, const std::vector<SweepPoint>& points, const std::string& method,
                       const std::string& title, const std::string& error_label) {
  static const int kColors[] = {0x000000, 0x1f77b4, 0xd62728, 0x2ca02c, 0x9467bd, 0x8c564b, 0xe377c2, 0xff7f0e};
  std::map<std::string, PlotSeries> by_knob;
  std::vector<std::string> order;
  std::vector<const SweepPoint*> front;
  for (const SweepPoint& p : points) {
    if (p.method != method || p.error < 0 || !(p.seconds > 0)) continue;
    if (!by_knob.count(p.knob)) {
      order.push_back(p.knob);
      PlotSeries& s = by_knob[p.knob];
      s.label = p.knob;
      s.color_bgr = kColors[(order.size() - 1) % (sizeof(kColors) / sizeof(kColors[0]))];
    }
    PlotSeries& s = by_knob[p.knob];
    s.x.push_back(p.seconds);
    s.y.push_back(p.error);
    s.point_labels.push_back(!p.pareto ? "" : p.knob == "default" ? "default" : p.value);
    if (p.pareto) front.push_back(&p);
  }
  if (order.empty()) return Status::Error(path + ": no scored " + method + " configurations to chart");
  std::sort(front.begin(), front.end(), [](const SweepPoint* a, const SweepPoint* b) { return a->seconds < b->seconds; });
  PlotPanel panel;
  panel.y_label = error_label;
  PlotSeries pareto;
  pareto.label = "Pareto front";
  pareto.line = true;
  pareto.color_bgr = 0xbbbbbb;
  for (const SweepPoint* p : front) {
    pareto.x.push_back(p->seconds);
    pareto.y.push_back(p->error);
  }
  panel.series.push_back(pareto);
  for (const std::string& knob : order) panel.series.push_back(by_knob[knob]);
  PlotOptions plot;
  plot.title = title;
  plot.x_label = "fit time [s] (log)";
  plot.log_x = true;
  plot.width_px = 1000;
  plot.height_px = 640;
  return WritePlotPng(path, {panel}, plot);
}

}  // namespace thinslab
