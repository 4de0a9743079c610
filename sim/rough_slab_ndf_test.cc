// SPDX-License-Identifier: Apache-2.0
// Beckmann and anisotropic faces of the rough-slab photon tracer (sim/rough_slab_photon_tracer.h):
// visible-normal sampling against its density (chi-square), and single-rough-face lobes against
// Walter's rough dielectric composed with a flat face (Dai's rho_t / rho_b,
// optics/dual_microfacet_btdf.h).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "thinslab/core/math.h"
#include "thinslab/optics/dual_microfacet_btdf.h"
#include "thinslab/optics/microfacet.h"
#include "thinslab/sim/rough_slab_photon_tracer.h"
#include "thinslab/sim/rough_slab_test_util.h"

namespace thinslab {
namespace {

using namespace testing_util;

constexpr double kEta = 1.5;
constexpr double kAlpha = 0.3;

// Visible-normal samplers (both kinds, anisotropic) against their density
// D_wi(m) = G1(wi) max(0, wi . m) D(m) / wi.z: chi-square over a 24 x 24 grid of the projected
// normal disk (m.x, m.y), where d omega_m = dm_x dm_y / m.z; cells with < 5 expected samples
// are pooled into one bin (see below).
template <typename Dist>
double VisibleNormalChiSquarePerDof(RoughSlabNdf kind, const Dist& dist, const Eigen::Vector3d& wi, int* dof) {
  constexpr int kBins = 24, kSub = 8;
  constexpr int64_t kSamples = 400000;
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::vector<double> observed(kBins * kBins, 0.0), expected(kBins * kBins, 0.0);
  for (int64_t k = 0; k < kSamples; ++k) {
    const double u1 = uni(rng), u2 = uni(rng);
    const Eigen::Vector3d m = SampleVisibleNormal(kind, dist.alpha_x, dist.alpha_y, wi, u1, u2);
    EXPECT_NEAR(m.norm(), 1.0, 1e-9);
    const int col = std::clamp(static_cast<int>((m.x() + 1) / 2 * kBins), 0, kBins - 1);
    const int row = std::clamp(static_cast<int>((m.y() + 1) / 2 * kBins), 0, kBins - 1);
    observed[row * kBins + col] += 1;
  }
  const double h = 2.0 / kBins, hs = h / kSub;
  double total = 0;
  for (int row = 0; row < kBins; ++row) {
    for (int col = 0; col < kBins; ++col) {
      double sum = 0;
      for (int j = 0; j < kSub; ++j) {
        for (int i = 0; i < kSub; ++i) {
          const double x = -1 + col * h + (i + 0.5) * hs, y = -1 + row * h + (j + 0.5) * hs;
          const double s = 1 - x * x - y * y;
          if (s <= 1e-12) continue;
          const Eigen::Vector3d m(x, y, std::sqrt(s));
          sum += dist.G1(wi, m) * std::max(0.0, wi.dot(m)) * dist.D(m) / wi.z() / m.z();
        }
      }
      expected[row * kBins + col] = sum * hs * hs * kSamples;
      total += expected[row * kBins + col];
    }
  }
  EXPECT_NEAR(total / kSamples, 1.0, 0.01);  // The density integrates to 1 (midpoint rule).
  // Cells touching the rim (where D_wi / m.z has an integrable singularity for GGX and the
  // midpoint rule is poor) and cells with < 5 expected samples form one pooled bin whose
  // expectation is the exact remainder kSamples - sum of the individual expectations.
  double chi2 = 0, used_obs = 0, used_exp = 0;
  *dof = 0;
  for (int row = 0; row < kBins; ++row) {
    for (int col = 0; col < kBins; ++col) {
      const double x0 = -1 + col * h, y0 = -1 + row * h;
      const double fx = std::max(x0 * x0, Sqr(x0 + h)), fy = std::max(y0 * y0, Sqr(y0 + h));
      const int c = row * kBins + col;
      if (fx + fy >= 1 || expected[c] < 5) continue;
      chi2 += Sqr(observed[c] - expected[c]) / expected[c];
      used_obs += observed[c];
      used_exp += expected[c];
      ++*dof;
    }
  }
  const double pooled_exp = kSamples - used_exp, pooled_obs = kSamples - used_obs;
  if (pooled_exp >= 5) {
    chi2 += Sqr(pooled_obs - pooled_exp) / pooled_exp;
    ++*dof;
  }
  return chi2 / *dof;
}

TEST(RoughSlabPhotonTracer, VisibleNormalSamplingMatchesItsDensity) {
  // chi^2 / dof of a correct sampler is 1 +- sqrt(2 / dof) (~0.06 here) plus the midpoint-rule
  // error of the expected counts; 1.3 fails a sampler of the plain D(m) m.z density by far.
  for (double theta_deg : {0.0, 40.0, 75.0}) {
    for (double phi : {0.0, 1.0}) {
      const Eigen::Vector3d wi = SphericalDirection(Deg(theta_deg), phi);
      int dof = 0;
      const double b = VisibleNormalChiSquarePerDof(RoughSlabNdf::kBeckmann, BeckmannDistribution(0.2, 0.45), wi, &dof);
      std::printf("Beckmann (0.2, 0.45) theta_i=%2.0f phi=%.1f: chi2/dof %.3f (dof %d)\n", theta_deg, phi, b, dof);
      EXPECT_LT(b, 1.3);
      const double bi = VisibleNormalChiSquarePerDof(RoughSlabNdf::kBeckmann, BeckmannDistribution(0.6, 0.6), wi, &dof);
      std::printf("Beckmann 0.6 theta_i=%2.0f phi=%.1f: chi2/dof %.3f (dof %d)\n", theta_deg, phi, bi, dof);
      EXPECT_LT(bi, 1.3);
      const double g = VisibleNormalChiSquarePerDof(RoughSlabNdf::kGgx, GgxDistribution(0.45, 0.2), wi, &dof);
      std::printf("GGX (0.45, 0.2) theta_i=%2.0f phi=%.1f: chi2/dof %.3f (dof %d)\n", theta_deg, phi, g, dof);
      EXPECT_LT(g, 1.3);
    }
  }
}

constexpr int64_t kNewLobePhotons = 2000000;

TEST(RoughSlabVsDualMicrofacet, BeckmannRoughTopOnlyMatchesWalterThroughAFlatFace) {
  // Dai's rho_t (Eq. 6) with a Beckmann D is Walter's f_t of the rough top composed with the
  // flat bottom's Fresnel transmission and refraction Jacobian, so the one-rough-face slab must
  // match it up to the multi-bounce light and noise (kSingleFaceRelRms, as for GGX). Energy:
  // the fractions still sum to 1.
  const auto btdf = MakeDualMicrofacetBtdf(BeckmannDistribution(kAlpha), BeckmannDistribution(kAlpha), kEta);
  const auto ggx = MakeDualMicrofacetBtdf(GgxDistribution(kAlpha), GgxDistribution(kAlpha), kEta);
  for (double theta_deg : {0.0, 30.0}) {
    RoughSlabPhotonTracerOptions options;
    options.eta = kEta;
    options.ndf_top = RoughSlabNdf::kBeckmann;
    options.alpha_top = kAlpha;
    options.alpha_bottom = 0.001;
    options.wi = SphericalDirection(Deg(theta_deg), 0.0);
    options.num_photons = kNewLobePhotons;
    options.seed = 31;
    const RoughSlabPhotonTracerResult r = TraceRoughSlab(options);
    EXPECT_NEAR(r.reflected + r.transmitted + r.masked + r.capped, 1.0, 1e-12);
    const LobeComparison c = CompareLobe(r, [&](const Eigen::Vector3d& o) { return btdf.Eval(options.wi, o, 1.0); });
    const LobeComparison cg = CompareLobe(r, [&](const Eigen::Vector3d& o) { return ggx.Eval(options.wi, o, 1.0); });
    std::printf(
        "Beckmann rough top %.2f, theta_i=%2.0f: rel RMS %.4f (noise %.4f, %d cells); GGX model would give %.4f; "
        "T %.4f R %.4f masked %.4f\n",
        kAlpha, theta_deg, c.rel_rms, c.noise_rel_rms, c.cells, cg.rel_rms, r.transmitted, r.reflected, r.masked);
    EXPECT_LT(c.rel_rms, kSingleFaceRelRms);
    EXPECT_GT(cg.rel_rms, 2 * kSingleFaceRelRms);  // The comparison tells the NDFs apart.
    EXPECT_GT(c.cells, 50);
  }
}

TEST(RoughSlabVsDualMicrofacet, AnisotropicLobeIsElongatedAlongTheRoughAxis) {
  // GGX (alpha_x, alpha_y) = (0.15, 0.4) on the bottom face only, normal and oblique incidence
  // along x: the lobe matches rho_b of the same anisotropic GGX, and its spread (second moment
  // of (o.x, o.y) about the mean) is larger along y than along x; swapping the alphas swaps it.
  for (bool swap : {false, true}) {
    const double ax = swap ? 0.4 : 0.15, ay = swap ? 0.15 : 0.4;
    const auto btdf = MakeDualMicrofacetBtdf(GgxDistribution(ax, ay), GgxDistribution(ax, ay), kEta);
    for (double theta_deg : {0.0, 30.0}) {
      RoughSlabPhotonTracerOptions options;
      options.eta = kEta;
      options.alpha_top = 0.001;
      options.alpha_bottom = ax;
      options.alpha_bottom_y = ay;
      options.wi = SphericalDirection(Deg(theta_deg), 0.0);
      options.num_photons = kNewLobePhotons;
      options.seed = 32;
      const RoughSlabPhotonTracerResult r = TraceRoughSlab(options);
      const LobeComparison c = CompareLobe(r, [&](const Eigen::Vector3d& o) { return btdf.Eval(options.wi, o, 0.0); });
      double n = 0, mx = 0, my = 0, sxx = 0, syy = 0;
      for (int row = 0; row < r.num_bins; ++row) {
        for (int col = 0; col < r.num_bins; ++col) {
          const double w = static_cast<double>(r.transmitted_counts[row * r.num_bins + col]);
          const double x = r.CellCentre(col), y = r.CellCentre(row);
          n += w;
          mx += w * x;
          my += w * y;
          sxx += w * x * x;
          syy += w * y * y;
        }
      }
      mx /= n;
      my /= n;
      const double var_x = sxx / n - mx * mx, var_y = syy / n - my * my;
      std::printf(
          "anisotropic GGX bottom (%.2f, %.2f), theta_i=%2.0f: rho_b rel RMS %.4f (noise %.4f, %d cells); spread "
          "sd_x %.4f sd_y %.4f\n",
          ax, ay, theta_deg, c.rel_rms, c.noise_rel_rms, c.cells, std::sqrt(var_x), std::sqrt(var_y));
      EXPECT_LT(c.rel_rms, kSingleFaceRelRms);
      if (swap) {
        EXPECT_GT(var_x, 2 * var_y);
      } else {
        EXPECT_GT(var_y, 2 * var_x);
      }
    }
  }
}

}  // namespace
}  // namespace thinslab
