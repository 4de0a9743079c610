// SPDX-License-Identifier: Apache-2.0
#include "thinslab/optics/shadow_map_model.h"

#include <gtest/gtest.h>

#include <random>

#include "thinslab/core/math.h"
#include "thinslab/optics/dirty_glass.h"

namespace thinslab {
namespace {

// Flux conservation: a Lambertian exit lobe R = c puts c * pi * sin^2(theta_max) of
// irradiance-times-area on the board (the integral of R mu over the cone).
TEST(BoardKernel, ConservesFluxOfLambertianLobe) {
  BoardGeometry geometry;
  geometry.distance_m = 1e-3;
  geometry.pixel_pitch_m = 50e-6;
  geometry.max_angle_deg = 60;
  const Image kernel = BuildBoardKernel([](double) { return 2.0; }, geometry);
  double sum = 0;
  for (float v : kernel.data()) sum += v;
  EXPECT_NEAR(sum / (2.0 * kPi * Sqr(std::sin(kPi / 3))), 1.0, 0.01);
}

// The node expansion against brute-force summation of Gu Eq. 6 over every source pixel.
TEST(ScatterKernelBank, MatchesDirectSummationOfEq6) {
  const double albedo = 0.3, g = 0.8;
  BoardGeometry geometry;
  geometry.distance_m = 0.6e-3;
  geometry.pixel_pitch_m = 0.1e-3;
  geometry.max_angle_deg = 75;
  auto per_tau = [&](double t, double mu) {
    if (t < 1e-9) return albedo * HenyeyGreenstein(mu, g) / mu;
    return LayerSingleScatterRadiance(t, mu, albedo, g) / t;
  };
  const ScatterKernelBank bank(ScatterKernelBank::DefaultNodes(), per_tau, geometry);

  const int n = 20;
  Image tau(n, n), e0(n, n, 1.0f);
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> uni(0.0f, 2.0f);
  for (auto& v : tau.data()) v = uni(rng);
  const Image fast = bank.Scattered(e0, tau);

  // Brute force with the kernel of each source's own tau (same pixel integration).
  Image slow(n, n);
  for (int sy = 0; sy < n; ++sy) {
    for (int sx = 0; sx < n; ++sx) {
      const double t = tau.at(sx, sy);
      const Image k = BuildBoardKernel(
          [&](double mu) { return LayerSingleScatterRadiance(t, mu, albedo, g); }, geometry);
      const int r = k.width() / 2;
      for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
          const int kx = x - sx + r, ky = y - sy + r;
          if (kx < 0 || ky < 0 || kx >= k.width() || ky >= k.height()) continue;
          slow.at(x, y) += k.at(kx, ky);
        }
      }
    }
  }
  double max_rel = 0;
  for (int y = 0; y < n; ++y) {
    for (int x = 0; x < n; ++x) {
      max_rel = std::max(max_rel, static_cast<double>(std::abs(fast.at(x, y) - slow.at(x, y)) / slow.at(x, y)));
    }
  }
  EXPECT_LT(max_rel, 0.01);
}

}  // namespace
}  // namespace thinslab
