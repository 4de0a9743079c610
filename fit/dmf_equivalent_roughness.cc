// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/dmf_equivalent_roughness.h"

#include <algorithm>
#include <cmath>

#include "thinslab/core/math.h"

namespace thinslab {
namespace {

// A cell of the NDF grid by what isotropic distributions depend on: tan^2 theta_m and
// cos^4 theta_m, with the tabulated D there.
struct CellSample {
  double tan2, cos4, d;
};

// Walter et al. 2007, Eq. 33 (GGX) and Eq. 25 (Beckmann), isotropic.
struct IsotropicGgx {
  static double D(double alpha, const CellSample& c) {
    const double a2 = alpha * alpha;
    return a2 / (kPi * c.cos4 * (a2 + c.tan2) * (a2 + c.tan2));
  }
};
struct IsotropicBeckmann {
  static double D(double alpha, const CellSample& c) {
    const double a2 = alpha * alpha;
    return std::exp(-c.tan2 / a2) / (kPi * a2 * c.cos4);
  }
};

// Misfit of the family at roughness alpha with the best scale (closed form).
template <typename Family>
double Misfit(const std::vector<CellSample>& cells, double alpha, double sum_d2) {
  double fd = 0, ff = 0;
  for (const CellSample& c : cells) {
    const double f = Family::D(alpha, c);
    fd += f * c.d;
    ff += f * f;
  }
  if (!(ff > 0)) return 1;
  // sum (s f - d)^2 = sum d^2 - fd^2 / ff at the best s = fd / ff.
  return std::sqrt(std::max(0.0, sum_d2 - fd * fd / ff) / sum_d2);
}

// Best roughness in [0.01, 1.5] by a log-spaced scan and a golden-section refinement of the
// bracket around the scan's best (the misfit can have a shallow second minimum at large alpha).
template <typename MisfitOf>
void MinimiseOverRoughness(const MisfitOf& misfit_of, double* alpha, double* misfit) {
  constexpr int kScan = 24;
  const double lo = std::log(0.01), hi = std::log(1.5), step = (hi - lo) / (kScan - 1);
  int best = 0;
  double best_misfit = 1e300;
  for (int k = 0; k < kScan; ++k) {
    const double m = misfit_of(std::exp(lo + k * step));
    if (m < best_misfit) best_misfit = m, best = k;
  }
  constexpr double kInvPhi = 0.6180339887498949;
  double a = lo + std::max(0, best - 1) * step, b = lo + std::min(kScan - 1, best + 1) * step;
  double c = b - kInvPhi * (b - a), d = a + kInvPhi * (b - a);
  double fc = misfit_of(std::exp(c)), fd = misfit_of(std::exp(d));
  while (b - a > 1e-3) {
    if (fc < fd) {
      b = d, d = c, fd = fc, c = b - kInvPhi * (b - a), fc = misfit_of(std::exp(c));
    } else {
      a = c, c = d, fc = fd, d = a + kInvPhi * (b - a), fd = misfit_of(std::exp(d));
    }
  }
  const double refined = misfit_of(std::exp(0.5 * (a + b)));
  *alpha = refined <= best_misfit ? std::exp(0.5 * (a + b)) : std::exp(lo + best * step);
  *misfit = std::min(refined, best_misfit);
}

template <typename Family>
void FitFamily(const std::vector<CellSample>& cells, double sum_d2, double* alpha, double* misfit) {
  MinimiseOverRoughness([&](double a) { return Misfit<Family>(cells, a, sum_d2); }, alpha, misfit);
}

// The same in logarithms: the RMS of ln d - ln (s f) at the best s (the mean log ratio, written
// to *log_scale), which weighs a cell at the lobe's edge as much as the peak.
template <typename Family>
double LogMisfit(const std::vector<CellSample>& cells, double alpha, double* log_scale) {
  double sum = 0, sum2 = 0;
  for (const CellSample& c : cells) {
    const double f = Family::D(alpha, c);
    // A narrow Beckmann lobe underflows to 0 at a wide measured cell: no fit at that roughness.
    if (!(f > 0)) return 1e300;
    const double r = std::log(c.d / f);
    sum += r;
    sum2 += r * r;
  }
  const double mean = sum / cells.size();
  if (log_scale != nullptr) *log_scale = mean;
  return std::sqrt(std::max(0.0, sum2 / cells.size() - mean * mean));
}

template <typename Family>
void FitFamilyInLogarithms(const std::vector<CellSample>& cells, double* alpha, double* scale) {
  double misfit = 0, log_scale = 0;
  MinimiseOverRoughness([&](double a) { return LogMisfit<Family>(cells, a, nullptr); }, alpha, &misfit);
  *scale = LogMisfit<Family>(cells, *alpha, &log_scale) < 1e300 ? std::exp(log_scale) : 0;
}

}  // namespace

const char* NdfFamilyName(NdfFamily family) {
  switch (family) {
    case NdfFamily::kGgx: return "ggx";
    case NdfFamily::kBeckmann: return "beckmann";
    case NdfFamily::kUndecided: return "undecided";
  }
  return "unknown";
}

std::vector<std::string> NdfFamilyNames() { return {"ggx", "beckmann", "undecided"}; }

const char* RoughFaceName(RoughFace face) {
  switch (face) {
    case RoughFace::kTop: return "top";
    case RoughFace::kBottom: return "bottom";
    case RoughFace::kBoth: return "both";
  }
  return "unknown";
}

std::vector<std::string> RoughFaceNames() { return {"top", "bottom", "both"}; }

namespace {

CellSample SampleOfCell(const DmfNdfGrid& grid, int cell, double d) {
  const double x = grid.CellCentre(cell % grid.n()), y = grid.CellCentre(cell / grid.n());
  const double r2 = x * x + y * y, cos2 = 1 - r2;
  return {r2 / cos2, cos2 * cos2, d};
}

// The cells of `log_d` inside the disk, with `use` (all when empty) and D at least
// min_relative_d of their peak.
std::vector<CellSample> FittedCells(const std::vector<double>& log_d, const DmfNdfGrid& grid,
                                    const std::vector<bool>& use, double min_relative_d, double* sum_d2) {
  std::vector<CellSample> cells;
  *sum_d2 = 0;
  auto used = [&](int cell) { return grid.InDisk(cell) && (use.empty() || use[cell]); };
  double peak = 0;
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    if (used(cell)) peak = std::max(peak, std::exp(log_d[cell]));
  }
  if (!(peak > 0)) return cells;
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    const double d = std::exp(log_d[cell]);
    if (!used(cell) || d < min_relative_d * peak) continue;
    cells.push_back(SampleOfCell(grid, cell, d));
    *sum_d2 += d * d;
  }
  return cells;
}

}  // namespace

EquivalentRoughness FitEquivalentRoughness(const std::vector<double>& log_ndf, const DmfNdfGrid& grid,
                                           const EquivalentRoughnessOptions& options) {
  EquivalentRoughness out;
  out.ggx_misfit = out.beckmann_misfit = 1;
  if (static_cast<int>(log_ndf.size()) != grid.num_cells()) return out;
  double sum_d2 = 0;
  const std::vector<CellSample> cells = FittedCells(log_ndf, grid, {}, options.min_relative_d, &sum_d2);
  if (cells.empty()) return out;
  FitFamily<IsotropicGgx>(cells, sum_d2, &out.ggx_alpha, &out.ggx_misfit);
  FitFamily<IsotropicBeckmann>(cells, sum_d2, &out.beckmann_alpha, &out.beckmann_misfit);
  DecideFamily(options, &out);
  return out;
}

FamilyTail FitFamilyTail(const std::vector<double>& log_d, const DmfNdfGrid& grid, const std::vector<bool>& use,
                         const EquivalentRoughnessOptions& options) {
  FamilyTail tail;
  double sum_d2 = 0;
  const std::vector<CellSample> cells = FittedCells(log_d, grid, use, options.min_relative_d, &sum_d2);
  if (cells.size() < 3) return tail;
  double ggx_alpha = 0, ggx_misfit = 1, beckmann_alpha = 0, beckmann_misfit = 1;
  FitFamily<IsotropicGgx>(cells, sum_d2, &ggx_alpha, &ggx_misfit);
  FitFamily<IsotropicBeckmann>(cells, sum_d2, &beckmann_alpha, &beckmann_misfit);
  // The family by the same (linear) misfit as FitEquivalentRoughness; its roughness and level in
  // logarithms: the tail continues the lobe's edge, which a linear fit, led by the peak, leaves
  // to the peak's width (on the simulated rig a smeared peak made the tail 10-15 % heavy).
  tail.family = beckmann_misfit < ggx_misfit ? NdfFamily::kBeckmann : NdfFamily::kGgx;
  tail.misfit = std::min(beckmann_misfit, ggx_misfit);
  if (tail.family == NdfFamily::kBeckmann) {
    FitFamilyInLogarithms<IsotropicBeckmann>(cells, &tail.alpha, &tail.scale);
  } else {
    FitFamilyInLogarithms<IsotropicGgx>(cells, &tail.alpha, &tail.scale);
  }
  if (!std::isfinite(tail.scale)) tail.scale = 0;
  return tail;
}

double FamilyTailD(const FamilyTail& tail, const DmfNdfGrid& grid, int cell) {
  if (!grid.InDisk(cell) || !(tail.alpha > 0)) return 0;
  const CellSample c = SampleOfCell(grid, cell, 0);
  return tail.scale *
         (tail.family == NdfFamily::kBeckmann ? IsotropicBeckmann::D(tail.alpha, c) : IsotropicGgx::D(tail.alpha, c));
}

void DecideFamily(const EquivalentRoughnessOptions& options, EquivalentRoughness* r) {
  if (r->beckmann_misfit * options.family_ratio < r->ggx_misfit) {
    r->family = NdfFamily::kBeckmann;
    r->roughness = r->beckmann_alpha;
  } else {
    r->family = r->ggx_misfit * options.family_ratio < r->beckmann_misfit ? NdfFamily::kGgx : NdfFamily::kUndecided;
    r->roughness = r->ggx_alpha;
  }
}

RoughFace RoughFaceOf(double top_face_weight, const EquivalentRoughnessOptions& options) {
  if (top_face_weight >= options.one_face_alpha) return RoughFace::kTop;
  if (top_face_weight <= 1 - options.one_face_alpha) return RoughFace::kBottom;
  return RoughFace::kBoth;
}

}  // namespace thinslab
