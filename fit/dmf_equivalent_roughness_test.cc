// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/dmf_equivalent_roughness.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "thinslab/core/math.h"
#include "thinslab/optics/microfacet.h"

namespace thinslab {
namespace {

// ln D of `dist` on the grid, normalised to unit projected integral as the fit's NDFs are.
template <typename Distribution>
std::vector<double> Tabulate(const Distribution& dist, const DmfNdfGrid& grid, double noise = 0, uint32_t seed = 1) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> gauss(0, noise);
  std::vector<double> log_d(grid.num_cells(), DmfNdfGrid::kLogEpsilon);
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    if (!grid.InDisk(cell)) continue;
    const double x = grid.CellCentre(cell % grid.n()), y = grid.CellCentre(cell / grid.n());
    const double d = dist.D(Eigen::Vector3d(x, y, std::sqrt(1 - x * x - y * y)));
    log_d[cell] = std::log(std::max(d, 1e-6)) + (noise > 0 ? gauss(rng) : 0);
  }
  const double log_k = std::log(grid.ProjectedIntegral(log_d));
  for (double& v : log_d) v -= log_k;
  return log_d;
}

TEST(EquivalentRoughness, RecoversFamilyAndRoughnessOfAnalyticNdfs) {
  const DmfNdfGrid grid(32);
  for (double alpha : {0.1, 0.2, 0.3, 0.5, 0.8}) {
    const EquivalentRoughness ggx = FitEquivalentRoughness(Tabulate(GgxDistribution(alpha), grid), grid);
    EXPECT_EQ(ggx.family, NdfFamily::kGgx) << alpha;
    EXPECT_NEAR(ggx.roughness, alpha, 0.03 * alpha) << alpha;
    const EquivalentRoughness beckmann = FitEquivalentRoughness(Tabulate(BeckmannDistribution(alpha), grid), grid);
    EXPECT_EQ(beckmann.family, NdfFamily::kBeckmann) << alpha;
    EXPECT_NEAR(beckmann.roughness, alpha, 0.03 * alpha) << alpha;
  }
}

// The tail beyond the measured cells (DmfPointFitOptions::ndf_tail "family"): from the cells of a
// level-2 table within a disk of radius 0.35 (what the dots of one point may reach), the family,
// roughness and level come back, so the projected integral of measured cells plus tail is 2.
TEST(EquivalentRoughness, FamilyTailFromTheMeasuredCellsRestoresTheIntegral) {
  const DmfNdfGrid grid(32);
  std::vector<bool> measured(grid.num_cells(), false);
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    measured[cell] = std::hypot(grid.CellCentre(cell % grid.n()), grid.CellCentre(cell / grid.n())) < 0.35;
  }
  for (NdfFamily family : {NdfFamily::kGgx, NdfFamily::kBeckmann}) {
    std::vector<double> log_d =
        family == NdfFamily::kGgx ? Tabulate(GgxDistribution(0.3), grid) : Tabulate(BeckmannDistribution(0.3), grid);
    for (double& v : log_d) v += std::log(2.0);
    const FamilyTail tail = FitFamilyTail(log_d, grid, measured);
    EXPECT_EQ(tail.family, family);
    EXPECT_NEAR(tail.alpha, 0.3, 0.01);
    EXPECT_NEAR(tail.scale, 2.0, 0.05);
    EXPECT_LT(tail.misfit, 0.05);
    std::vector<double> filled = log_d;
    double unmeasured_mass = 0;
    for (int cell = 0; cell < grid.num_cells(); ++cell) {
      if (!grid.InDisk(cell) || measured[cell]) continue;
      unmeasured_mass += std::exp(log_d[cell]);
      filled[cell] = std::log(std::max(FamilyTailD(tail, grid, cell), 1e-300));
    }
    // A GGX tail outside radius 0.35 holds a large share of the mass, which is why it matters.
    if (family == NdfFamily::kGgx) {
      EXPECT_GT(unmeasured_mass * Sqr(grid.cell_width()), 0.5);
    }
    EXPECT_NEAR(grid.ProjectedIntegral(filled), grid.ProjectedIntegral(log_d), 0.02 * grid.ProjectedIntegral(log_d));
  }
  // Too few cells: no tail (scale 0).
  EXPECT_EQ(FitFamilyTail(Tabulate(GgxDistribution(0.3), grid), grid, std::vector<bool>(grid.num_cells(), false)).scale,
            0.0);
}

// 10 % log-normal cell noise (the tabulated fit's scatter) moves the roughness by little.
TEST(EquivalentRoughness, NoisyTableKeepsRoughness) {
  const DmfNdfGrid grid(32);
  const EquivalentRoughness r = FitEquivalentRoughness(Tabulate(GgxDistribution(0.3), grid, 0.1), grid);
  EXPECT_NEAR(r.roughness, 0.3, 0.015);
  EXPECT_NE(r.family, NdfFamily::kBeckmann);
}

// Mixtures w GGX + (1 - w) Beckmann of the same width: GGX at w = 1, Beckmann at w = 0, and in
// between an undecided stretch, never Beckmann after GGX as w grows.
TEST(EquivalentRoughness, MixturesPassThroughUndecided) {
  const DmfNdfGrid grid(32);
  const std::vector<double> g = Tabulate(GgxDistribution(0.3), grid), b = Tabulate(BeckmannDistribution(0.27), grid);
  int undecided = 0;
  NdfFamily previous = NdfFamily::kBeckmann;
  for (int k = 0; k <= 20; ++k) {
    const double w = k / 20.0;
    std::vector<double> mix(g.size());
    for (size_t c = 0; c < g.size(); ++c) mix[c] = std::log(w * std::exp(g[c]) + (1 - w) * std::exp(b[c]));
    const EquivalentRoughness r = FitEquivalentRoughness(mix, grid);
    if (k == 0) {
      EXPECT_EQ(r.family, NdfFamily::kBeckmann);
    }
    if (k == 20) {
      EXPECT_EQ(r.family, NdfFamily::kGgx);
    }
    if (previous == NdfFamily::kGgx) {
      EXPECT_EQ(r.family, NdfFamily::kGgx) << w;
    }
    if (previous == NdfFamily::kUndecided) {
      EXPECT_NE(r.family, NdfFamily::kBeckmann) << w;
    }
    undecided += r.family == NdfFamily::kUndecided;
    EXPECT_GT(r.roughness, 0.25) << w;
    EXPECT_LT(r.roughness, 0.33) << w;
    previous = r.family;
  }
  EXPECT_GE(undecided, 1);
}

TEST(EquivalentRoughness, EmptyNdf) {
  const EquivalentRoughness r = FitEquivalentRoughness({}, DmfNdfGrid(32));
  EXPECT_EQ(r.roughness, 0);
  EXPECT_EQ(r.family, NdfFamily::kUndecided);
}

TEST(EquivalentRoughness, RoughFaceFromAlpha) {
  EXPECT_EQ(RoughFaceOf(0.9), RoughFace::kTop);
  EXPECT_EQ(RoughFaceOf(0.75), RoughFace::kTop);
  EXPECT_EQ(RoughFaceOf(0.5), RoughFace::kBoth);
  EXPECT_EQ(RoughFaceOf(0.1), RoughFace::kBottom);
}

}  // namespace
}  // namespace thinslab
