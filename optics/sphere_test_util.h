// SPDX-License-Identifier: Apache-2.0
// Test-only numerics shared by optics/microfacet_test.cc and optics/walter_btdf_test.cc:
// adaptive Gauss-Kronrod quadrature (1D and nested 2D, with break points at known peaks), the
// regularized upper incomplete gamma function Q(a, x) for chi-square p-values, and a pooled
// chi-square goodness-of-fit statistic (pbrt-v4 bsdfs_test.cpp Chi2Test: cells with expected
// count below a minimum are merged).
#pragma once

#include <glog/logging.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <string>
#include <vector>

#include "thinslab/core/math.h"

namespace thinslab {
namespace testing {

// Gauss-Kronrod 7-15 nodes and weights on [-1, 1] (QUADPACK qk15).
struct GaussKronrod15 {
  static constexpr double kNodes[8] = {0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
                                       0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
                                       0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
                                       0.207784955007898467600689403773245, 0.0};
  static constexpr double kKronrodWeights[8] = {
      0.022935322010529224963732008058970, 0.063092092629978553290700663189204, 0.104790010322250183839876322541518,
      0.140653259715525918745189590510238, 0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
      0.204432940075298892414161999234649, 0.209482141084727828012999174891714};
  // Gauss 7-point weights at kNodes[1], [3], [5], [7].
  static constexpr double kGaussWeights[4] = {0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
                                              0.381830050505118944950369775488975, 0.417959183673469387755102040816327};
};

// One Gauss-Kronrod step on [a, b]: returns the Kronrod estimate and |Kronrod - Gauss|.
inline double GaussKronrodStep(const std::function<double(double)>& f, double a, double b, double* error) {
  const double center = 0.5 * (a + b), half = 0.5 * (b - a);
  double kronrod = 0, gauss = 0;
  for (int k = 0; k < 8; ++k) {
    const double x = GaussKronrod15::kNodes[k];
    const double fx = (k == 7) ? f(center) : f(center - half * x) + f(center + half * x);
    kronrod += GaussKronrod15::kKronrodWeights[k] * fx;
    if (k % 2 == 1) gauss += GaussKronrod15::kGaussWeights[k / 2] * fx;
  }
  *error = std::abs(kronrod - gauss) * half;
  return kronrod * half;
}

inline double AdaptiveGaussKronrodRecursive(const std::function<double(double)>& f, double a, double b, double whole,
                                            double error, double tolerance, int depth) {
  if (error <= tolerance || depth >= 40 || std::abs(b - a) < 1e-13) return whole;
  const double mid = 0.5 * (a + b);
  double error_left, error_right;
  const double left = GaussKronrodStep(f, a, mid, &error_left);
  const double right = GaussKronrodStep(f, mid, b, &error_right);
  return AdaptiveGaussKronrodRecursive(f, a, mid, left, error_left, 0.5 * tolerance, depth + 1) +
         AdaptiveGaussKronrodRecursive(f, mid, b, right, error_right, 0.5 * tolerance, depth + 1);
}

// Integral of f over [a, b] split at the break points inside (a, b) (put them at peaks and
// kinks), each piece bisected until |Kronrod - Gauss| <= its share of
// max(abs_tolerance, rel_tolerance |integral|).
inline double Integrate1D(const std::function<double(double)>& f, double a, double b, std::vector<double> breaks,
                          double abs_tolerance, double rel_tolerance) {
  std::vector<double> edges = {a};
  std::sort(breaks.begin(), breaks.end());
  for (double x : breaks) {
    if (x > edges.back() + 1e-12 && x < b - 1e-12) edges.push_back(x);
  }
  edges.push_back(b);
  const int pieces = static_cast<int>(edges.size()) - 1;
  std::vector<double> values(pieces), errors(pieces);
  double total = 0;
  for (int p = 0; p < pieces; ++p) {
    values[p] = GaussKronrodStep(f, edges[p], edges[p + 1], &errors[p]);
    total += values[p];
  }
  const double tolerance = std::max(abs_tolerance, rel_tolerance * std::abs(total));
  double sum = 0;
  for (int p = 0; p < pieces; ++p) {
    sum += AdaptiveGaussKronrodRecursive(f, edges[p], edges[p + 1], values[p], errors[p], tolerance / pieces, 0);
  }
  return sum;
}

// Integral of f(x, y) over [x0, x1] x [y0, y1] as nested 1D integrals (y inner), with break
// points in each variable.
inline double Integrate2D(const std::function<double(double, double)>& f, double x0, double x1, double y0, double y1,
                          const std::vector<double>& x_breaks, const std::vector<double>& y_breaks,
                          double abs_tolerance, double rel_tolerance) {
  const double inner_abs_tolerance = 0.1 * abs_tolerance / std::max(1e-12, x1 - x0);
  const auto inner = [&](double x) {
    return Integrate1D([&](double y) { return f(x, y); }, y0, y1, y_breaks, inner_abs_tolerance, 0.1 * rel_tolerance);
  };
  return Integrate1D(inner, x0, x1, x_breaks, abs_tolerance, rel_tolerance);
}

// Regularized upper incomplete gamma function Q(a, x) = Gamma(a, x) / Gamma(a) (series for
// x < a + 1, Lentz continued fraction otherwise; Numerical Recipes 3rd ed., Sec. 6.2).
inline double RegularizedGammaQ(double a, double x) {
  CHECK_GT(a, 0.0);
  CHECK_GE(x, 0.0);
  if (x == 0) return 1.0;
  const double log_prefactor = -x + a * std::log(x) - std::lgamma(a);
  constexpr double kEps = 1e-15;
  if (x < a + 1) {
    double term = 1.0 / a, sum = term, ap = a;
    for (int n = 0; n < 100000; ++n) {
      ap += 1;
      term *= x / ap;
      sum += term;
      if (std::abs(term) < std::abs(sum) * kEps) break;
    }
    return std::max(0.0, 1.0 - sum * std::exp(log_prefactor));
  }
  constexpr double kTiny = 1e-300;
  double b = x + 1 - a, c = 1 / kTiny, d = 1 / b, h = d;
  for (int i = 1; i < 100000; ++i) {
    const double an = -i * (i - a);
    b += 2;
    d = an * d + b;
    if (std::abs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::abs(c) < kTiny) c = kTiny;
    d = 1 / d;
    const double delta = d * c;
    h *= delta;
    if (std::abs(delta - 1) < kEps) break;
  }
  return std::exp(log_prefactor) * h;
}

// P(X >= chi2) for X chi-square distributed with dof degrees of freedom.
inline double ChiSquarePValue(double chi2, int dof) { return RegularizedGammaQ(0.5 * dof, 0.5 * chi2); }

struct ChiSquareResult {
  double chi2 = 0;
  int dof = 0;
  double p_value = 0;
  // Samples that fell in cells whose expected count is exactly zero (must be 0).
  double observed_in_empty_cells = 0;
  std::string ToString() const {
    return "chi2=" + std::to_string(chi2) + " dof=" + std::to_string(dof) + " p=" + std::to_string(p_value) +
           " observed_in_empty_cells=" + std::to_string(observed_in_empty_cells);
  }
};

// Pearson chi-square of observed against expected counts; cells with expected count below
// min_expected are pooled (in order of increasing expected count) until the pool reaches it.
inline ChiSquareResult PooledChiSquare(const std::vector<double>& observed, const std::vector<double>& expected,
                                       double min_expected = 5.0) {
  CHECK_EQ(observed.size(), expected.size());
  std::vector<int> order(observed.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int a, int b) { return expected[a] < expected[b]; });
  ChiSquareResult result;
  double pooled_observed = 0, pooled_expected = 0;
  int cells = 0;
  for (int idx : order) {
    if (expected[idx] == 0) {
      result.observed_in_empty_cells += observed[idx];
    } else if (expected[idx] < min_expected || (pooled_expected > 0 && pooled_expected < min_expected)) {
      pooled_observed += observed[idx];
      pooled_expected += expected[idx];
    } else {
      result.chi2 += Sqr(observed[idx] - expected[idx]) / expected[idx];
      ++cells;
    }
  }
  if (pooled_expected > 0) {
    result.chi2 += Sqr(pooled_observed - pooled_expected) / pooled_expected;
    ++cells;
  }
  result.dof = cells - 1;
  result.p_value = result.dof > 0 ? ChiSquarePValue(result.chi2, result.dof) : 0.0;
  return result;
}

}  // namespace testing
}  // namespace thinslab
