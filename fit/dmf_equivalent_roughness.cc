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
template <typename Family>
void FitFamily(const std::vector<CellSample>& cells, double sum_d2, double* alpha, double* misfit) {
  constexpr int kScan = 24;
  const double lo = std::log(0.01), hi = std::log(1.5), step = (hi - lo) / (kScan - 1);
  int best = 0;
  double best_misfit = 2;
  for (int k = 0; k < kScan; ++k) {
    const double m = Misfit<Family>(cells, std::exp(lo + k * step), sum_d2);
    if (m < best_misfit) best_misfit = m, best = k;
  }
  constexpr double kInvPhi = 0.6180339887498949;
  double a = lo + std::max(0, best - 1) * step, b = lo + std::min(kScan - 1, best + 1) * step;
  double c = b - kInvPhi * (b - a), d = a + kInvPhi * (b - a);
  double fc = Misfit<Family>(cells, std::exp(c), sum_d2), fd = Misfit<Family>(cells, std::exp(d), sum_d2);
  while (b - a > 1e-3) {
    if (fc < fd) {
      b = d, d = c, fd = fc, c = b - kInvPhi * (b - a), fc = Misfit<Family>(cells, std::exp(c), sum_d2);
    } else {
      a = c, c = d, fc = fd, d = a + kInvPhi * (b - a), fd = Misfit<Family>(cells, std::exp(d), sum_d2);
    }
  }
  const double refined = Misfit<Family>(cells, std::exp(0.5 * (a + b)), sum_d2);
  *alpha = refined <= best_misfit ? std::exp(0.5 * (a + b)) : std::exp(lo + best * step);
  *misfit = std::min(refined, best_misfit);
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

EquivalentRoughness FitEquivalentRoughness(const std::vector<double>& log_ndf, const DmfNdfGrid& grid,
                                           const EquivalentRoughnessOptions& options) {
  EquivalentRoughness out;
  out.ggx_misfit = out.beckmann_misfit = 1;
  if (static_cast<int>(log_ndf.size()) != grid.num_cells()) return out;
  double peak = 0;
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    if (grid.InDisk(cell)) peak = std::max(peak, std::exp(log_ndf[cell]));
  }
  if (!(peak > 0)) return out;
  std::vector<CellSample> cells;
  double sum_d2 = 0;
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    const double d = std::exp(log_ndf[cell]);
    if (!grid.InDisk(cell) || d < options.min_relative_d * peak) continue;
    const double x = grid.CellCentre(cell % grid.n()), y = grid.CellCentre(cell / grid.n());
    const double r2 = x * x + y * y, cos2 = 1 - r2;
    cells.push_back({r2 / cos2, cos2 * cos2, d});
    sum_d2 += d * d;
  }
  FitFamily<IsotropicGgx>(cells, sum_d2, &out.ggx_alpha, &out.ggx_misfit);
  FitFamily<IsotropicBeckmann>(cells, sum_d2, &out.beckmann_alpha, &out.beckmann_misfit);
  DecideFamily(options, &out);
  return out;
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
