// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/dmf_equivalent_roughness.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

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
