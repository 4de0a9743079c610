// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/dmf_model_ladder.h"

#include "thinslab/fit/ladder_choice.h"
#include "thinslab/fit/small_dense_solve.h"

#include <ceres/ceres.h>

#include <chrono>
#include <cmath>

#include "thinslab/core/math.h"
#include "thinslab/optics/dual_microfacet_btdf.h"
#include "thinslab/optics/microfacet.h"

namespace thinslab {
namespace {

// The weight stays strictly inside (0, 1) where Eq. 11 is smooth.
constexpr double kMinWeight = 1e-3, kMaxWeight = 1 - 1e-3;

template <template <typename> class Distribution>
struct AnalyticDmfResidual {
  Eigen::Vector3d i, o;
  double log_value, eta;
  template <typename T>
  bool operator()(const T* log_alpha_ndf, const T* weight, const T* log_k, T* residual) const {
    using std::exp;
    using std::log;
    const Distribution<T> ndf(exp(log_alpha_ndf[0]));
    const DualMicrofacetBtdf<Distribution<T>> btdf(ndf, ndf, T(eta));
    const T rho = btdf.Eval(i.cast<T>(), o.cast<T>(), weight[0]);
    residual[0] = rho > T(0) ? T(log_value) - log_k[0] - log(rho) : T(10.0);
    return true;
  }
};

// One family from one start of the weight: the final cost (1e300 when nothing was fitted).
template <template <typename> class Distribution>
double FitAnalyticOnce(const DmfSlice& slice, const std::vector<int>& used, double eta, double start_alpha_ndf,
                       double start_weight, AnalyticDmfFit* fit) {
  double log_alpha = std::log(start_alpha_ndf), weight = start_weight, log_k = 0;
  ceres::Problem problem;
  using Residual = AnalyticDmfResidual<Distribution>;
  for (int q : used) {
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<Residual, 1, 1, 1, 1>(
                                 new Residual{slice.i[q], slice.o, std::log(slice.value[q] - slice.rho_d), eta}),
                             nullptr, &log_alpha, &weight, &log_k);
  }
  problem.SetParameterLowerBound(&log_alpha, 0, std::log(kMinMicrofacetAlpha));
  problem.SetParameterUpperBound(&log_alpha, 0, std::log(kMaxMicrofacetAlpha));
  problem.SetParameterLowerBound(&weight, 0, kMinWeight);
  problem.SetParameterUpperBound(&weight, 0, kMaxWeight);
  const double cost = SolveSmallDenseProblem(&problem, 50);
  fit->alpha_ndf = std::exp(log_alpha);
  fit->alpha = weight;
  fit->k_s = std::exp(log_k);
  return cost;
}

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

}  // namespace

AnalyticDmfFit FitAnalyticDualMicrofacet(const DmfSlice& slice, const DmfPointFitOptions& options) {
  AnalyticDmfFit best;
  best.rho_d = slice.rho_d;
  const std::vector<int> used = UsableTrainingDots(slice, options);
  if (static_cast<int>(used.size()) < options.min_measurements) return best;
  double best_cost = 1e300;
  auto keep_if_better = [&](const AnalyticDmfFit& fit, double cost) {
    if (cost < best_cost) {
      best_cost = cost;
      best = fit;
      best.ok = true;
      best.log_rms_residual = std::sqrt(2 * cost / used.size());
    }
  };
  // GGX from three starts of the weight; Beckmann (whose Smith term, with erfc, costs about 3x
  // per residual) once, from the best GGX solution: the two families' lobes of one roughness
  // are alike near the peak, so the weight and roughness carry over.
  for (double start : {0.2, 0.5, 0.8}) {
    AnalyticDmfFit fit = best;
    fit.family = MicrofacetFamily::kGgx;
    keep_if_better(fit, FitAnalyticOnce<GgxDistributionT>(slice, used, options.eta, 0.2, start, &fit));
  }
  if (best.ok) {
    AnalyticDmfFit fit = best;
    fit.family = MicrofacetFamily::kBeckmann;
    keep_if_better(fit, FitAnalyticOnce<BeckmannDistributionT>(slice, used, options.eta, best.alpha_ndf, best.alpha,
                                                                &fit));
  }
  return best;
}

double PredictAnalyticDualMicrofacet(const AnalyticDmfFit& fit, double eta, const Eigen::Vector3d& i,
                                     const Eigen::Vector3d& o) {
  if (!fit.ok) return fit.rho_d;
  if (fit.family == MicrofacetFamily::kBeckmann) {
    const BeckmannDistribution ndf(fit.alpha_ndf);
    return fit.rho_d + fit.k_s * MakeDualMicrofacetBtdf(ndf, ndf, eta).Eval(i, o, fit.alpha);
  }
  const GgxDistribution ndf(fit.alpha_ndf);
  return fit.rho_d + fit.k_s * MakeDualMicrofacetBtdf(ndf, ndf, eta).Eval(i, o, fit.alpha);
}

DmfPointFitOptions AnalyticRungOptions(const LadderOptions& options) {
  DmfPointFitOptions analytic = options.point;
  analytic.min_relative_value = std::max(analytic.min_relative_value, options.lobe_fraction);
  return analytic;
}

const char* LadderRungName(int rung_index) {
  static const char* const kNames[kNumLadderRungs] = {"single_interface", "dual_microfacet_analytic",
                                                      "dual_microfacet_tabulated"};
  return rung_index >= 0 && rung_index < kNumLadderRungs ? kNames[rung_index] : "none";
}

LadderResult FitLadder(const DmfSlice& slice, const DmfNdfGrid& grid, const LadderOptions& options) {
  LadderResult r;
  const double eta = options.point.eta;
  const DmfStatus precheck = PrecheckSlice(slice, options.point);
  if (precheck == DmfStatus::kSpecular || precheck == DmfStatus::kNoLobe) {
    r.specular = true;
    return r;
  }
  // Rungs 3 and 4 on the lobe's training dots, or all usable ones where the lobe has too few.
  DmfPointFitOptions analytic_options = AnalyticRungOptions(options);
  if (static_cast<int>(UsableTrainingDots(slice, analytic_options).size()) < analytic_options.min_measurements) {
    analytic_options = options.point;
  }
  auto t = std::chrono::steady_clock::now();
  r.single = FitSingleInterface(slice, analytic_options);
  r.seconds[0] = Seconds(t);
  t = std::chrono::steady_clock::now();
  r.analytic = FitAnalyticDualMicrofacet(slice, analytic_options);
  r.seconds[1] = Seconds(t);
  t = std::chrono::steady_clock::now();
  r.tabulated = FitDualMicrofacetPoint(slice, grid, options.point);
  r.seconds[2] = Seconds(t);
  r.parameters = {2, 3, grid.num_unknowns() + 3};

  const bool fitted[kNumLadderRungs] = {r.single.ok, r.analytic.ok, !r.tabulated.log_ndf.empty()};
  auto predict = [&](int rung, int q) {
    if (rung == 0) return PredictSingleInterface(r.single, eta, slice.i[q], slice.o);
    if (rung == 1) return PredictAnalyticDualMicrofacet(r.analytic, eta, slice.i[q], slice.o);
    return PredictDualMicrofacet(r.tabulated, grid, eta, slice.i[q], slice.o);
  };

  // The scored dots: held out and in the lobe (as HeldOutRelativeRms), with each rung's squared
  // prediction error per dot.
  double peak = 0;
  for (int q = 0; q < slice.num_dots(); ++q) {
    if (!slice.train[q]) peak = std::max(peak, slice.value[q] - slice.rho_d);
  }
  std::vector<int> scored;
  double noise = 0, signal = 0;
  for (int q = 0; q < slice.num_dots(); ++q) {
    if (slice.train[q] || slice.value[q] - slice.rho_d < options.lobe_fraction * peak) continue;
    scored.push_back(q);
    noise += slice.sigma.empty() ? 0 : Sqr(slice.sigma[q]);
    signal += Sqr(slice.value[q] - slice.rho_d);
  }
  if (scored.empty() || !(signal > 0)) return r;
  r.noise_floor = std::sqrt(noise / signal);
  std::array<std::vector<double>, kNumLadderRungs>& sq = r.squared_errors;
  r.signal = signal;
  for (int q : scored) r.noise_variances.push_back(slice.sigma.empty() ? 0.0 : Sqr(slice.sigma[q]));
  for (int k = 0; k < kNumLadderRungs; ++k) {
    if (!fitted[k]) continue;
    double sum = 0;
    for (int q : scored) {
      sq[k].push_back(Sqr(predict(k, q) - slice.value[q]));
      sum += sq[k].back();
    }
    r.held_out[k] = std::sqrt(sum / signal);
  }

  // BIC of every rung on the same training dots (those rungs 3-4 were fitted on): the Eq. 15
  // log residuals ln(R - rho_d) - ln(prediction - rho_d).
  const std::vector<int> bic_dots = UsableTrainingDots(slice, analytic_options);
  const int n = static_cast<int>(bic_dots.size());
  double best_bic = 1e300;
  for (int k = 0; k < kNumLadderRungs; ++k) {
    if (!fitted[k] || r.held_out[k] < 0) continue;
    double rss = 0;
    for (int q : bic_dots) {
      const double model = predict(k, q) - slice.rho_d;
      rss += model > 0 ? Sqr(std::log((slice.value[q] - slice.rho_d) / model)) : 100.0;
    }
    r.bic[k] = n * std::log(std::max(1e-12, rss / std::max(1, n))) + r.parameters[k] * std::log(std::max(1, n));
    if (r.bic[k] < best_bic) {
      best_bic = r.bic[k];
      r.chosen_by_bic = k;
    }
  }
  r.chosen = ChooseLadderRung({&r}, options.significance_sigmas, options.criterion);
  return r;
}

int ChooseLadderRung(const std::vector<const LadderResult*>& group, double significance_sigmas,
                     LadderCriterion criterion) {
  // Per-dot squared errors relative to their point's signal, pooled over the group; and the
  // group's BIC per rung. A rung counts only where it was fitted and scored on every point.
  std::vector<std::vector<double>> pooled(kNumLadderRungs);
  std::vector<double> noise;
  std::array<double, kNumLadderRungs> bic{{0, 0, 0}};
  std::array<bool, kNumLadderRungs> available{{true, true, true}};
  int points = 0;
  for (const LadderResult* r : group) {
    if (r->specular || r->signal <= 0) continue;
    ++points;
    for (int k = 0; k < kNumLadderRungs; ++k) {
      if (r->squared_errors[k].empty()) available[k] = false;
      bic[k] += r->bic[k];
      for (double e : r->squared_errors[k]) pooled[k].push_back(e / r->signal);
    }
    for (double v : r->noise_variances) noise.push_back(v / r->signal);
  }
  if (points == 0) return -1;
  if (criterion == LadderCriterion::kBic) {
    int best = -1;
    for (int k = 0; k < kNumLadderRungs; ++k) {
      if (available[k] && (best < 0 || bic[k] < bic[best])) best = k;
    }
    return best;
  }
  for (int k = 0; k < kNumLadderRungs; ++k) {
    if (!available[k]) pooled[k].clear();
  }
  return SimplestRungWithinNoise(pooled, significance_sigmas, noise);
}

namespace {

// ln D at the centres of the cells inside the disk; ln epsilon outside, as the tabulated fit has.
template <typename Distribution>
void SampleLogNdf(const Distribution& ndf, const DmfNdfGrid& grid, std::vector<double>* log_ndf) {
  const int n = grid.n();
  log_ndf->assign(grid.num_cells(), DmfNdfGrid::kLogEpsilon);
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    if (!grid.InDisk(cell)) continue;
    const double x = grid.CellCentre(cell % n), y = grid.CellCentre(cell / n);
    const double d = ndf.D(Eigen::Vector3d(x, y, std::sqrt(std::max(0.0, 1 - x * x - y * y))));
    (*log_ndf)[cell] = std::max(DmfNdfGrid::kLogEpsilon, std::log(std::max(d, 1e-300)));
  }
}

// `out` holds a shape (alpha, log_ndf, smith_alpha): its k_s on this point's training dots, the
// residual, the transmittance (`transmittance_per_k_s` of the refracted part when known, else
// integrated) and the status.
bool ScaleLadderShape(const DmfSlice& slice, const DmfNdfGrid& grid, const DmfPointFitOptions& options,
                      double transmittance_per_k_s, DmfPointFit* out) {
  const int used = ScaleShapeToSlice(slice, grid, options, out);
  if (used == 0) return false;
  out->num_used = used;
  out->alpha_iterations = 0;
  out->transmittance = transmittance_per_k_s >= 0 ? kPi * out->rho_d + out->k_s * transmittance_per_k_s
                                                  : DirectionalTransmittance(*out, grid, options.eta, slice.o);
  if (options.Unphysical(out->transmittance, out->k_s)) {
    out->status = DmfStatus::kUnphysical;
  } else if (out->status != DmfStatus::kInterpolated) {
    out->status = DmfStatus::kOk;  // Not undersampled or unconverged: those describe the tabulated fit.
  }
  return true;
}

}  // namespace

bool ReplaceWithLadderRung(const LadderResult& shape, int rung_index, const DmfSlice& slice, const DmfNdfGrid& grid,
                           const DmfPointFitOptions& options, DmfPointFit* fit) {
  DmfPointFit out = *fit;
  MicrofacetFamily family = MicrofacetFamily::kGgx;
  double roughness = 0;
  if (rung_index == 0 && shape.single.ok) {
    family = shape.single.family;
    roughness = shape.single.alpha;
    out.alpha = shape.single.rough_top ? 1 : 0;
  } else if (rung_index == 1 && shape.analytic.ok) {
    family = shape.analytic.family;
    roughness = shape.analytic.alpha_ndf;
    out.alpha = shape.analytic.alpha;
  } else {
    return false;
  }
  if (family == MicrofacetFamily::kBeckmann) {
    SampleLogNdf(BeckmannDistribution(roughness), grid, &out.log_ndf);
  } else {
    SampleLogNdf(GgxDistribution(roughness), grid, &out.log_ndf);
  }
  out.smith_alpha = roughness;
  out.roughness = FitEquivalentRoughness(out.log_ndf, grid, options.roughness);
  if (!ScaleLadderShape(slice, grid, options, -1, &out)) return false;
  *fit = std::move(out);
  return true;
}

bool AdoptLadderShape(const DmfPointFit& replaced, const DmfSlice& slice, const DmfNdfGrid& grid,
                      const DmfPointFitOptions& options, DmfPointFit* fit) {
  if (replaced.log_ndf.empty() || !(replaced.k_s > 0)) return false;
  DmfPointFit out = *fit;
  out.alpha = replaced.alpha;
  out.smith_alpha = replaced.smith_alpha;
  out.log_ndf = replaced.log_ndf;
  out.roughness = replaced.roughness;
  const double per_k_s = std::max(0.0, replaced.transmittance - kPi * replaced.rho_d) / replaced.k_s;
  if (!ScaleLadderShape(slice, grid, options, per_k_s, &out)) return false;
  *fit = std::move(out);
  return true;
}

}  // namespace thinslab
