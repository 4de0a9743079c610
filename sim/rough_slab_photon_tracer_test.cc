// SPDX-License-Identifier: Apache-2.0
// Laws of the rough-slab photon tracer (sim/rough_slab_photon_tracer.h) and the comparison of
// the dual-microfacet BTDF (optics/dual_microfacet_btdf.h, Dai et al. 2009, Eqs. 6, 10, 11)
// against it, as in Dai et al. Fig. 3.
#include "thinslab/sim/rough_slab_photon_tracer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "thinslab/core/math.h"
#include "thinslab/optics/dual_microfacet_btdf.h"
#include "thinslab/optics/fresnel.h"
#include "thinslab/optics/microfacet.h"
#include "thinslab/sim/rough_slab_test_util.h"

namespace thinslab {
namespace {

using namespace testing_util;

TEST(RoughSlabPhotonTracer, FractionsSumToOne) {
  for (int max_interactions : {3, 64}) {
    RoughSlabPhotonTracerOptions options;
    options.alpha_top = 0.5;
    options.alpha_bottom = 0.8;
    options.wi = SphericalDirection(Deg(60), 0.3);
    options.num_photons = 200000;
    options.max_interactions = max_interactions;
    const RoughSlabPhotonTracerResult r = TraceRoughSlab(options);
    std::printf("max_interactions=%d: R %.5f T %.5f masked %.5f capped %.5f\n", max_interactions, r.reflected,
                r.transmitted, r.masked, r.capped);
    EXPECT_NEAR(r.reflected + r.transmitted + r.masked + r.capped, 1.0, 1e-12);
    int64_t binned = 0;
    for (int64_t c : r.transmitted_counts) binned += c;
    EXPECT_NEAR(static_cast<double>(binned), r.transmitted * options.num_photons, 0.5);
    if (max_interactions == 3) {
      EXPECT_GT(r.capped, 0.0);  // Internal TIR paths do get cut.
    }
    EXPECT_GT(r.masked, 0.0);  // Rough faces mask some light.
  }
}

TEST(RoughSlabPhotonTracer, NearlySmoothSlabIsTheFresnelSeries) {
  // Flat slab, incoherent: T = (1 - F)^2 sum_k F^(2k) = (1 - F) / (1 + F), F = F(theta_i),
  // equal at both faces for the refraction pair; light leaves along -wi.
  constexpr double kEta = 1.5;
  constexpr int64_t kPhotons = 1000000;
  for (double theta_deg : {0.0, 31.0, 70.0}) {
    RoughSlabPhotonTracerOptions options;
    options.eta = kEta;
    options.alpha_top = options.alpha_bottom = 0.001;
    options.wi = SphericalDirection(Deg(theta_deg), 0.0);
    options.num_photons = kPhotons;
    options.seed = 11;
    const RoughSlabPhotonTracerResult r = TraceRoughSlab(options);
    const double f = FresnelDielectric(options.wi.z(), kEta);
    const double expected = (1 - f) / (1 + f);
    const double sigma = std::sqrt(expected * (1 - expected) / kPhotons);
    std::printf("theta_i=%2.0f: T_mc %.5f T_fresnel %.5f (sigma %.1e) masked %.2e\n", theta_deg, r.transmitted,
                expected, sigma, r.masked);
    EXPECT_NEAR(r.transmitted, expected, 5 * sigma + 1e-4);
    // Straight through: the transmitted photons fall in the 3 x 3 cells around o = -wi, except
    // for GGX's long tail: a fraction alpha^2 / (alpha^2 + t^2) of facets has tan theta_m > t
    // (Walter Eq. 35), and leaving the block takes t ~ cell / (eta - 1) ~ 0.06, i.e. ~3e-4 per
    // face at alpha = 0.001 (more near grazing). 2e-3 bounds both faces.
    const double h = r.CellWidth();
    const int col = static_cast<int>((-options.wi.x() + 1) / h), row = static_cast<int>((-options.wi.y() + 1) / h);
    int64_t near = 0;
    for (int dr = -1; dr <= 1; ++dr) {
      for (int dc = -1; dc <= 1; ++dc) {
        const int rr = row + dr, cc = col + dc;
        if (rr < 0 || cc < 0 || rr >= r.num_bins || cc >= r.num_bins) continue;
        near += r.transmitted_counts[rr * r.num_bins + cc];
      }
    }
    const double outside = 1 - near / (r.transmitted * kPhotons);
    std::printf("  transmitted outside the 3x3 cells around -wi: %.2e\n", outside);
    EXPECT_LT(outside, 2e-3);
  }
}


// The lateral offsets through a flat slab of unit thickness (issue #23 section 5): once through,
// tan of the refraction angle along the propagation; after k internal reflection pairs, (2k + 1)
// times that; the share that crosses once is 1 / sum F^(2k) = 1 - F^2 of the transmitted light.
TEST(RoughSlabPhotonTracer, FlatSlabOffsetsAreTheRefractedRayCrossings) {
  constexpr double kEta = 1.5;
  constexpr int64_t kPhotons = 400000;
  for (double theta_deg : {20.0, 60.0}) {
    RoughSlabPhotonTracerOptions options;
    options.eta = kEta;
    options.alpha_top = options.alpha_bottom = 0.001;
    options.wi = SphericalDirection(Deg(theta_deg), 0.0);
    options.num_photons = kPhotons;
    options.seed = 5;
    const RoughSlabPhotonTracerResult r = TraceRoughSlab(options);
    const double sin_t = std::sin(Deg(theta_deg)) / kEta;
    const double tan_t = sin_t / std::sqrt(1 - sin_t * sin_t);
    int64_t once = 0;
    double sum_x = 0, sum_y = 0;
    for (size_t c = 0; c < r.transmitted_counts.size(); ++c) {
      once += r.transmitted_once_counts[c];
      sum_x += r.once_offset_x[c];
      sum_y += r.once_offset_y[c];
    }
    const int64_t transmitted = static_cast<int64_t>(std::llround(r.transmitted * kPhotons));
    const double f = FresnelDielectric(options.wi.z(), kEta);
    std::printf("theta_i=%2.0f: once offset (%.4f, %.4f) for (-%.4f, 0), share once %.4f for %.4f, %zu several\n",
                theta_deg, sum_x / once, sum_y / once, tan_t, static_cast<double>(once) / transmitted, 1 - f * f,
                r.multiple_offsets.size());
    // wi points to the light along +x: the photon travels towards -x.
    EXPECT_NEAR(sum_x / once, -tan_t, 2e-3);
    EXPECT_NEAR(sum_y / once, 0, 2e-3);
    EXPECT_NEAR(static_cast<double>(once) / transmitted, 1 - f * f, 5e-3);
    // 3, 5, 7, ... crossings; GGX's long tail tilts a few facets even at alpha 0.001, so 90 %.
    ASSERT_FALSE(r.multiple_offsets.empty());
    int odd = 0;
    for (const Eigen::Vector2f& offset : r.multiple_offsets) {
      const double crossings = -offset.x() / tan_t;
      odd += crossings > 2.5 && std::abs(crossings - (2 * std::round((crossings - 1) / 2) + 1)) < 0.05;
    }
    EXPECT_GT(odd, 0.9 * r.multiple_offsets.size());
  }
}


constexpr double kEta = 1.5;
constexpr double kAlpha = 0.3;
constexpr int64_t kLobePhotons = 4000000;

RoughSlabPhotonTracerResult TraceLobe(double alpha_top, double alpha_bottom, double theta_deg, uint64_t seed) {
  RoughSlabPhotonTracerOptions options;
  options.eta = kEta;
  options.alpha_top = alpha_top;
  options.alpha_bottom = alpha_bottom;
  options.wi = SphericalDirection(Deg(theta_deg), 0.0);
  options.num_photons = kLobePhotons;
  options.num_bins = 64;
  options.seed = seed;
  return TraceRoughSlab(options);
}

double MultiBounceFraction(const RoughSlabPhotonTracerResult& r) {
  int64_t total = 0, multi = 0;
  for (size_t k = 0; k < r.transmitted_by_hits.size(); ++k) {
    total += r.transmitted_by_hits[k];
    if (k > 2) multi += r.transmitted_by_hits[k];
  }
  return static_cast<double>(multi) / total;
}

TEST(RoughSlabVsDualMicrofacet, RoughTopOnlyMatchesRhoT) {
  const auto btdf = MakeDualMicrofacetBtdf(GgxDistribution(kAlpha), GgxDistribution(kAlpha), kEta);
  const auto tab_btdf = MakeDualMicrofacetBtdf(TabulatedNdf::FromDistribution(GgxDistribution(kAlpha), 64),
                                               GgxDistribution(kAlpha), kEta);
  for (double theta_deg : {0.0, 30.0, 50.0}) {
    const RoughSlabPhotonTracerResult r = TraceLobe(kAlpha, 0.001, theta_deg, 21);
    const Eigen::Vector3d wi = SphericalDirection(Deg(theta_deg), 0.0);
    const LobeComparison c = CompareLobe(r, [&](const Eigen::Vector3d& o) { return btdf.Eval(wi, o, 1.0); });
    const LobeComparison cb = CompareLobe(r, [&](const Eigen::Vector3d& o) { return btdf.Eval(wi, o, 0.0); });
    const LobeComparison ctab = CompareLobe(r, [&](const Eigen::Vector3d& o) { return tab_btdf.Eval(wi, o, 1.0); });
    std::printf("  with D tabulated (64 x 64 TabulatedNdf of the same GGX): rel RMS %.4f\n", ctab.rel_rms);
    EXPECT_LT(ctab.rel_rms, kSingleFaceRelRms);
    std::printf(
        "rough top only, theta_i=%2.0f: rho_t rel RMS %.4f (noise %.4f, %d cells, multi-bounce %.4f); "
        "rho_b would give %.4f; MC T %.4f R %.4f masked %.4f\n",
        theta_deg, c.rel_rms, c.noise_rel_rms, c.cells, MultiBounceFraction(r), cb.rel_rms, r.transmitted, r.reflected,
        r.masked);
    EXPECT_LT(c.rel_rms, kSingleFaceRelRms);
    EXPECT_GT(c.cells, 50);
  }
}

TEST(RoughSlabVsDualMicrofacet, RoughBottomOnlyMatchesRhoB) {
  const auto btdf = MakeDualMicrofacetBtdf(GgxDistribution(kAlpha), GgxDistribution(kAlpha), kEta);
  for (double theta_deg : {0.0, 30.0, 50.0}) {
    const RoughSlabPhotonTracerResult r = TraceLobe(0.001, kAlpha, theta_deg, 22);
    const Eigen::Vector3d wi = SphericalDirection(Deg(theta_deg), 0.0);
    const LobeComparison c = CompareLobe(r, [&](const Eigen::Vector3d& o) { return btdf.Eval(wi, o, 0.0); });
    const LobeComparison ct = CompareLobe(r, [&](const Eigen::Vector3d& o) { return btdf.Eval(wi, o, 1.0); });
    std::printf(
        "rough bottom only, theta_i=%2.0f: rho_b rel RMS %.4f (noise %.4f, %d cells, multi-bounce %.4f); "
        "rho_t would give %.4f; MC T %.4f R %.4f masked %.4f\n",
        theta_deg, c.rel_rms, c.noise_rel_rms, c.cells, MultiBounceFraction(r), ct.rel_rms, r.transmitted, r.reflected,
        r.masked);
    EXPECT_LT(c.rel_rms, kSingleFaceRelRms);
    EXPECT_GT(c.cells, 50);
  }
}

TEST(RoughSlabVsDualMicrofacet, BothRoughBestAlphaBeatsASingleRoughInterface) {
  // Both faces GGX(alpha_face); the model uses one NDF. Dai et al. fit D per point (Sec. 4.2);
  // here D is GGX with the roughness alpha_model scanned, and alpha of Eq. 11 in steps of 0.1.
  // The single-interface model is the best endpoint (alpha = 0 or 1: one rough face, the other
  // flat) over the same roughness scan. Dai et al. Fig. 5: at oblique incidence the
  // interpolated dual model fits a two-sided rough slab better than any single rough interface.
  // At normal incidence the two configurations coincide, so only 30 deg is asserted.
  constexpr double kFace = 0.2;
  for (double theta_deg : {0.0, 30.0}) {
    const RoughSlabPhotonTracerResult r = TraceLobe(kFace, kFace, theta_deg, 23);
    const Eigen::Vector3d wi = SphericalDirection(Deg(theta_deg), 0.0);
    double best = 1e9, best_alpha = -1, best_rough = -1, best_single = 1e9;
    for (double rough : {0.2, 0.25, 0.3, 0.35, 0.4}) {
      const auto btdf = MakeDualMicrofacetBtdf(GgxDistribution(rough), GgxDistribution(rough), kEta);
      std::printf("both rough %.2f, theta_i=%2.0f, model GGX %.2f: rel RMS by alpha", kFace, theta_deg, rough);
      for (int a = 0; a <= 10; ++a) {
        const double alpha = 0.1 * a;
        const LobeComparison c = CompareLobe(r, [&](const Eigen::Vector3d& o) { return btdf.Eval(wi, o, alpha); });
        std::printf(" %.3f", c.rel_rms);
        if (a == 0 || a == 10) best_single = std::min(best_single, c.rel_rms);
        if (c.rel_rms < best) {
          best = c.rel_rms;
          best_alpha = alpha;
          best_rough = rough;
        }
      }
      std::printf("\n");
    }
    std::printf(
        "both rough %.2f, theta_i=%2.0f: best rel RMS %.4f at alpha=%.1f, model roughness %.2f; best single rough "
        "interface %.4f (ratio %.2f)\n",
        kFace, theta_deg, best, best_alpha, best_rough, best_single, best / best_single);
    EXPECT_GT(best_alpha, -1.0);
    const double max_error_ratio = 0.7;
    if (theta_deg > 0) {
      EXPECT_LT(best / best_single, max_error_ratio);
    }
  }
}

}  // namespace
}  // namespace thinslab
