// SPDX-License-Identifier: Apache-2.0
// Laws of the rough dielectric of Walter et al. 2007 (optics/walter_btdf.h) and of the Fresnel
// and Snell helpers (optics/fresnel.h): chi-square of the importance sampler against its pdf,
// energy conservation, the smooth limit, reciprocity (with the eta^2 rule for transmission).
#include "thinslab/optics/walter_btdf.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cstdio>
#include <random>
#include <string>
#include <vector>

#include "thinslab/optics/fresnel.h"
#include "thinslab/optics/microfacet.h"
#include "thinslab/optics/sphere_test_util.h"

namespace thinslab {
namespace {

using testing::Integrate1D;
using testing::Integrate2D;
using testing::PooledChiSquare;

Eigen::Vector3d SphericalDirection(double theta, double phi) {
  return Eigen::Vector3d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
}

double PhiOf(const Eigen::Vector3d& w) {
  const double phi = std::atan2(w.y(), w.x());
  return phi < 0 ? phi + 2 * kPi : phi;
}

double Deg(double degrees) { return degrees * kPi / 180.0; }

// ---------------------------------------------------------------------------------------------
// Fresnel and Snell.

TEST(Fresnel, NormalIncidenceGlassIsFourPercent) {
  EXPECT_NEAR(FresnelDielectric(1.0, 1.5), 0.04, 1e-15);
  EXPECT_NEAR(FresnelDielectric(-1.0, 1.0 / 1.5), 0.04, 1e-15);  // Same interface, from below.
  EXPECT_NEAR(FresnelDielectric(1.0, 1.0 / 1.5), 0.04, 1e-15);
  EXPECT_NEAR(FresnelDielectric(0.0, 1.5), 1.0, 1e-15);  // Grazing.
}

TEST(Fresnel, AgreesWithWalterEq22) {
  for (double eta : {1.33, 1.5, 1 / 1.5, 2.4}) {
    for (double c = -1.0; c <= 1.0; c += 0.01) {
      EXPECT_NEAR(FresnelDielectric(c, eta), FresnelDielectricWalterEq22(c, eta), 1e-12) << c << " " << eta;
    }
  }
}

TEST(Fresnel, TotalInternalReflectionBeyondCriticalAngle) {
  const double eta = 1 / 1.5;  // Light inside glass (index 1.5) meeting air.
  const double critical = std::asin(eta);
  EXPECT_NEAR(critical, Deg(41.8103149), 1e-7);
  const Eigen::Vector3d n(0, 0, 1);
  Eigen::Vector3d wt;
  for (double theta : {critical + 1e-6, Deg(45), Deg(60), Deg(89)}) {
    EXPECT_EQ(FresnelDielectric(std::cos(theta), eta), 1.0);
    EXPECT_FALSE(Refract(SphericalDirection(theta, 0.3), n, eta, &wt));
  }
  for (double theta : {Deg(10), Deg(40), critical - 1e-6}) {
    EXPECT_LT(FresnelDielectric(std::cos(theta), eta), 1.0);
    EXPECT_TRUE(Refract(SphericalDirection(theta, 0.3), n, eta, &wt));
  }
}

TEST(Fresnel, SnellRoundTripAndSymmetry) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const Eigen::Vector3d n = Eigen::Vector3d(0.2, -0.3, 1.0).normalized();
  for (double eta : {1.5, 1 / 1.5, 2.4}) {
    for (int k = 0; k < 1000; ++k) {
      Eigen::Vector3d wi = SphericalDirection(std::acos(2 * uni(rng) - 1), 2 * kPi * uni(rng));
      Eigen::Vector3d wt;
      const bool ok = Refract(wi, n, eta, &wt);
      const double cos_i = wi.dot(n);
      const double eta_rel = cos_i > 0 ? eta : 1 / eta;
      const double sin_i = std::sqrt(std::max(0.0, 1 - cos_i * cos_i));
      ASSERT_EQ(ok, sin_i / eta_rel < 1) << wi.transpose();
      if (!ok) continue;
      EXPECT_NEAR(wt.norm(), 1.0, 1e-12);
      EXPECT_LT(wt.dot(n) * cos_i, 0.0);                        // Other side.
      EXPECT_NEAR(wi.cross(n).dot(wt), 0.0, 1e-12);             // Plane of incidence.
      EXPECT_NEAR(sin_i, eta_rel * wt.cross(n).norm(), 1e-12);  // eta_i sin_i = eta_t sin_t.
      // Near the critical angle cos_theta_t -> 0 amplifies round-off (d theta_t / d theta_i ~
      // 1 / cos_theta_t), hence 1e-9 rather than 1e-12 for the round trip and the symmetry.
      Eigen::Vector3d wi_back;
      ASSERT_TRUE(Refract(wt, n, eta, &wi_back));
      EXPECT_NEAR((wi_back - wi).norm(), 0.0, 1e-9);
      // Fresnel reflectance is the same from both sides of a refraction pair.
      EXPECT_NEAR(FresnelDielectric(cos_i, eta), FresnelDielectric(wt.dot(n), eta), 1e-9);
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Sampling: chi-square of the sampled wo against the pdf integrated over (cos theta_o, phi_o)
// bins, and the sampler's pdf and weight against Pdf() and Eval() at every sample.

struct SamplingStats {
  double max_pdf_rel_error = 0;
  double max_weight_rel_error = 0;
  int accepted = 0;
};

template <typename Distribution>
testing::ChiSquareResult CheckSampling(const WalterRoughDielectric<Distribution>& bsdf, const Eigen::Vector3d& wi,
                                       int samples, uint64_t seed, SamplingStats* stats) {
  constexpr int kCosBins = 20, kPhiBins = 40;
  std::vector<double> observed(kCosBins * kPhiBins, 0.0), expected(kCosBins * kPhiBins, 0.0);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (int s = 0; s < samples; ++s) {
    const double u_lobe = uni(rng), u1 = uni(rng), u2 = uni(rng);
    WalterBsdfSample<double> sample;
    if (!bsdf.Sample(wi, u_lobe, u1, u2, &sample)) continue;
    ++stats->accepted;
    const Eigen::Vector3d& wo = sample.wo;
    EXPECT_NEAR(wo.norm(), 1.0, 1e-12);
    EXPECT_EQ(sample.is_reflection, wo.z() * wi.z() > 0);
    const double pdf = bsdf.Pdf(wi, wo);
    stats->max_pdf_rel_error = std::max(stats->max_pdf_rel_error, std::abs(sample.pdf - pdf) / pdf);
    const double weight = bsdf.Eval(wi, wo) * std::abs(wo.z()) / pdf;
    stats->max_weight_rel_error =
        std::max(stats->max_weight_rel_error, std::abs(sample.weight - weight) / std::max(weight, 1e-300));
    const int i = std::min(kCosBins - 1, static_cast<int>((wo.z() + 1) / 2 * kCosBins));
    const int j = std::min(kPhiBins - 1, static_cast<int>(PhiOf(wo) / (2 * kPi) * kPhiBins));
    observed[i * kPhiBins + j] += 1;
  }
  // Break points at the specular reflection and refraction directions, where narrow lobes peak.
  std::vector<double> theta_breaks = {std::acos(wi.z())}, phi_breaks;
  const Eigen::Vector3d reflected(-wi.x(), -wi.y(), wi.z());
  phi_breaks.push_back(PhiOf(reflected));
  theta_breaks.push_back(std::acos(reflected.z()));
  Eigen::Vector3d refracted;
  if (Refract(wi, Eigen::Vector3d(0, 0, 1), bsdf.eta, &refracted)) {
    theta_breaks.push_back(std::acos(Clamp(refracted.z(), -1.0, 1.0)));
    phi_breaks.push_back(PhiOf(refracted));
  }
  for (int i = 0; i < kCosBins; ++i) {
    const double theta0 = std::acos(-1.0 + 2.0 * (i + 1) / kCosBins), theta1 = std::acos(-1.0 + 2.0 * i / kCosBins);
    for (int j = 0; j < kPhiBins; ++j) {
      const double phi0 = 2 * kPi * j / kPhiBins, phi1 = 2 * kPi * (j + 1) / kPhiBins;
      const auto integrand = [&](double theta, double phi) {
        return bsdf.Pdf(wi, SphericalDirection(theta, phi)) * std::sin(theta);
      };
      expected[i * kPhiBins + j] =
          samples * Integrate2D(integrand, theta0, theta1, phi0, phi1, theta_breaks, phi_breaks, 1e-8, 1e-6);
    }
  }
  return PooledChiSquare(observed, expected);
}

template <typename Distribution>
void RunSamplingCases(const Distribution& dist, uint64_t* seed, double* min_p_value) {
  constexpr int kSamples = 200000;
  for (double eta : {1.5, 1 / 1.5}) {
    const WalterRoughDielectric<Distribution> bsdf(dist, eta);
    // From above at 30 deg, and from below at 70 deg (TIR side for eta = 1.5).
    for (const Eigen::Vector3d& wi : {SphericalDirection(Deg(30), 0.3), SphericalDirection(Deg(180 - 70), 2.0)}) {
      SamplingStats stats;
      const auto result = CheckSampling(bsdf, wi, kSamples, ++*seed, &stats);
      const std::string where = bsdf.ToString() + " theta_i=" + std::to_string(std::acos(wi.z()) * 180 / kPi);
      std::printf("  %-72s %s accepted=%.3f\n", where.c_str(), result.ToString().c_str(),
                  stats.accepted / static_cast<double>(kSamples));
      EXPECT_EQ(result.observed_in_empty_cells, 0.0) << where;
      EXPECT_GT(result.p_value, 0.01) << where << " " << result.ToString();
      EXPECT_LT(stats.max_pdf_rel_error, 1e-6) << where;
      EXPECT_LT(stats.max_weight_rel_error, 1e-6) << where;
      *min_p_value = std::min(*min_p_value, result.p_value);
    }
  }
}

TEST(WalterRoughDielectric, GgxSamplingMatchesPdfChiSquare) {
  uint64_t seed = 100;
  double min_p_value = 1;
  for (double alpha : {0.02, 0.1, 0.5}) RunSamplingCases(GgxDistribution(alpha), &seed, &min_p_value);
  RunSamplingCases(GgxDistribution(0.1, 0.4), &seed, &min_p_value);
  std::printf("  GGX: min p-value %.3f\n", min_p_value);
}

TEST(WalterRoughDielectric, BeckmannSamplingMatchesPdfChiSquare) {
  uint64_t seed = 200;
  double min_p_value = 1;
  for (double alpha : {0.02, 0.1, 0.5}) RunSamplingCases(BeckmannDistribution(alpha), &seed, &min_p_value);
  RunSamplingCases(BeckmannDistribution(0.1, 0.4), &seed, &min_p_value);
  std::printf("  Beckmann: min p-value %.3f\n", min_p_value);
}

// ---------------------------------------------------------------------------------------------
// Energy.

struct Albedo {
  double reflected = 0, transmitted = 0, standard_error = 0;
};

// Reflected and transmitted albedo, integral of f |cos theta_o| d omega_o over each side,
// estimated with the sampler's weights. u_lobe is stratified over the samples (which removes
// the lobe-selection noise; the estimate stays unbiased).
template <typename Distribution>
Albedo EstimateAlbedo(const WalterRoughDielectric<Distribution>& bsdf, const Eigen::Vector3d& wi, int samples,
                      std::mt19937_64* rng) {
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  Albedo albedo;
  double sum2 = 0;
  for (int s = 0; s < samples; ++s) {
    WalterBsdfSample<double> sample;
    if (!bsdf.Sample(wi, (s + 0.5) / samples, uni(*rng), uni(*rng), &sample)) continue;
    (sample.is_reflection ? albedo.reflected : albedo.transmitted) += sample.weight;
    sum2 += sample.weight * sample.weight;
  }
  albedo.reflected /= samples;
  albedo.transmitted /= samples;
  const double mean = albedo.reflected + albedo.transmitted;
  albedo.standard_error = std::sqrt(std::max(0.0, sum2 / samples - mean * mean) / samples);
  return albedo;
}

// Walter Eq. 41 weights average to R + T <= 1 (the projected-area identity bounds it with the
// separable G; the deficit is the single-scattering energy loss that grows with alpha).
TEST(WalterRoughDielectric, AlbedoIsAtMostOne) {
  std::mt19937_64 rng(17);
  double max_albedo = 0, max_z = -1e300;
  std::string max_where;
  const auto check = [&](const auto& dist) {
    for (double eta : {1.5, 1 / 1.5}) {
      const WalterRoughDielectric<std::decay_t<decltype(dist)>> bsdf(dist, eta);
      for (double theta_deg : {0.0, 15.0, 30.0, 45.0, 60.0, 70.0, 80.0, 85.0, 89.0}) {
        for (double side : {1.0, -1.0}) {
          const Eigen::Vector3d wi = SphericalDirection(Deg(theta_deg), 0.7) * side;
          const Albedo a = EstimateAlbedo(bsdf, wi, 10000, &rng);
          const double total = a.reflected + a.transmitted;
          const std::string where =
              bsdf.ToString() + " theta_i=" + std::to_string(theta_deg) + (side > 0 ? " above" : " below");
          EXPECT_LE(total, 1.0 + 4 * a.standard_error + 1e-9)
              << where << " R=" << a.reflected << " T=" << a.transmitted;
          EXPECT_GT(total, 0.0) << where;
          max_z = std::max(max_z, (total - 1.0) / a.standard_error);
          if (total > max_albedo) {
            max_albedo = total;
            max_where = where;
          }
        }
      }
    }
  };
  for (double alpha : {0.01, 0.1, 0.3, 0.5, 1.0, 2.0}) {
    check(GgxDistribution(alpha));
    check(BeckmannDistribution(alpha));
  }
  check(GgxDistribution(0.05, 0.5));
  check(BeckmannDistribution(0.05, 0.5));
  std::printf("  max R + T = %.5f (%s); max (R + T - 1) / standard error = %.2f\n", max_albedo, max_where.c_str(),
              max_z);
}

// As alpha -> 0 the surface becomes a smooth interface: R -> F(cos theta_i), T -> 1 - F.
// Convergence is slow next to the critical angle (41.8 deg from the dense side): GGX's heavy
// tail puts a fraction ~ alpha^2 / (theta_c - theta_i)^2 of the facets across it (at 41 deg
// and alpha = 1e-3 that shifts R by 2.4e-3), so the angles here stay >= 1.8 deg away.
TEST(WalterRoughDielectric, SmoothLimitReflectsFresnel) {
  std::mt19937_64 rng(23);
  double max_error = 0;
  const auto check = [&](const auto& dist) {
    for (double eta : {1.5, 1 / 1.5}) {
      const WalterRoughDielectric<std::decay_t<decltype(dist)>> bsdf(dist, eta);
      for (double theta_deg : {0.0, 20.0, 40.0, 43.6, 50.0, 60.0, 70.0, 80.0}) {
        for (double side : {1.0, -1.0}) {
          const Eigen::Vector3d wi = SphericalDirection(Deg(theta_deg), 1.1) * side;
          const double fresnel = FresnelDielectric(wi.z(), eta);
          const Albedo a = EstimateAlbedo(bsdf, wi, 50000, &rng);
          const std::string where =
              bsdf.ToString() + " theta_i=" + std::to_string(theta_deg) + (side > 0 ? " above" : " below");
          EXPECT_NEAR(a.reflected, fresnel, 2e-3) << where;
          EXPECT_NEAR(a.transmitted, 1 - fresnel, 2e-3) << where;
          max_error = std::max({max_error, std::abs(a.reflected - fresnel), std::abs(a.transmitted - 1 + fresnel)});
        }
      }
    }
  };
  check(GgxDistribution(1e-3));
  check(BeckmannDistribution(1e-3));
  std::printf("  alpha=1e-3: max |R - F|, |T - (1 - F)| = %.2e\n", max_error);
}

// The same albedo by quadrature of Eval (independent of the sampler), and the integral of Pdf
// equals the fraction of samples the sampler accepts.
TEST(WalterRoughDielectric, QuadratureAlbedoAndPdfMassAgreeWithSampler) {
  std::mt19937_64 rng(31);
  for (double eta : {1.5, 1 / 1.5}) {
    for (double alpha : {0.3, 0.8}) {
      const WalterRoughDielectric<GgxDistribution> bsdf(GgxDistribution(alpha, 0.7 * alpha), eta);
      for (const Eigen::Vector3d& wi : {SphericalDirection(Deg(40), 0.4), SphericalDirection(Deg(180 - 75), 1.9)}) {
        const auto over = [&](auto value) {
          return [&, value](double theta, double phi) {
            const Eigen::Vector3d wo = SphericalDirection(theta, phi);
            return value(wo) * std::sin(theta);
          };
        };
        const auto albedo_integrand =
            over([&](const Eigen::Vector3d& wo) { return bsdf.Eval(wi, wo) * std::abs(wo.z()); });
        const auto pdf_integrand = over([&](const Eigen::Vector3d& wo) { return bsdf.Pdf(wi, wo); });
        const std::vector<double> theta_breaks = {0.5 * kPi}, phi_breaks = {kPi};
        const double albedo_quadrature =
            Integrate2D(albedo_integrand, 0, kPi, 0, 2 * kPi, theta_breaks, phi_breaks, 1e-6, 1e-6);
        const double pdf_mass = Integrate2D(pdf_integrand, 0, kPi, 0, 2 * kPi, theta_breaks, phi_breaks, 1e-6, 1e-6);
        const int samples = 100000;
        int accepted = 0;
        double sum = 0, sum2 = 0;
        std::uniform_real_distribution<double> uni(0.0, 1.0);
        for (int s = 0; s < samples; ++s) {
          WalterBsdfSample<double> sample;
          if (!bsdf.Sample(wi, uni(rng), uni(rng), uni(rng), &sample)) continue;
          ++accepted;
          sum += sample.weight;
          sum2 += sample.weight * sample.weight;
        }
        const double mean = sum / samples;
        const double standard_error = std::sqrt((sum2 / samples - mean * mean) / samples);
        const double fraction = accepted / static_cast<double>(samples);
        const double fraction_error = std::sqrt(fraction * (1 - fraction) / samples) + 1e-7;
        std::printf("  %s theta_i=%.0f: albedo quadrature %.5f sampled %.5f +- %.5f; pdf mass %.5f accepted %.5f\n",
                    bsdf.ToString().c_str(), std::acos(wi.z()) * 180 / kPi, albedo_quadrature, mean, standard_error,
                    pdf_mass, fraction);
        EXPECT_NEAR(albedo_quadrature, mean, 5 * standard_error);
        EXPECT_LE(albedo_quadrature, 1.0);
        EXPECT_NEAR(pdf_mass, fraction, 5 * fraction_error);
      }
    }
  }
}

// ---------------------------------------------------------------------------------------------
// Reciprocity: f_r(i, o) = f_r(o, i); f_t(i, o) / eta_o^2 = f_t(o, i) / eta_i^2 (Walter Sec. 4.2).

template <typename Distribution>
void CheckReciprocity(const Distribution& dist, double eta) {
  const WalterRoughDielectric<Distribution> bsdf(dist, eta);
  std::mt19937_64 rng(41);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  int reflection_pairs = 0, transmission_pairs = 0;
  for (int k = 0; k < 20000; ++k) {
    const Eigen::Vector3d wi = SphericalDirection(std::acos(2 * uni(rng) - 1), 2 * kPi * uni(rng));
    const Eigen::Vector3d wo = SphericalDirection(std::acos(2 * uni(rng) - 1), 2 * kPi * uni(rng));
    const double forward = bsdf.Eval(wi, wo), backward = bsdf.Eval(wo, wi);
    if (wi.z() * wo.z() > 0) {
      EXPECT_NEAR(forward, backward, 1e-12 * std::max(1.0, forward)) << bsdf.ToString();
      if (forward > 0) ++reflection_pairs;
    } else {
      const double eta_i = wi.z() > 0 ? 1.0 : eta, eta_o = wi.z() > 0 ? eta : 1.0;
      EXPECT_NEAR(forward / (eta_o * eta_o), backward / (eta_i * eta_i), 1e-12 * std::max(1.0, forward))
          << bsdf.ToString() << " wi=" << wi.transpose() << " wo=" << wo.transpose();
      EXPECT_EQ(forward > 0, backward > 0);
      if (forward > 0) ++transmission_pairs;
    }
  }
  EXPECT_GT(reflection_pairs, 5000) << bsdf.ToString();
  EXPECT_GT(transmission_pairs, 1000) << bsdf.ToString();
}

TEST(WalterRoughDielectric, ReflectionIsReciprocalAndTransmissionObeysEtaSquaredRule) {
  for (double eta : {1.5, 1 / 1.5}) {
    CheckReciprocity(GgxDistribution(0.3), eta);
    CheckReciprocity(GgxDistribution(0.1, 0.6), eta);
    CheckReciprocity(BeckmannDistribution(0.3), eta);
    CheckReciprocity(BeckmannDistribution(0.6, 0.1), eta);
  }
}

// The BSDF is differentiable with Ceres Jets in alpha and eta.
TEST(WalterRoughDielectric, JetDerivativesMatchFiniteDifferences) {
  using Jet = ceres::Jet<double, 2>;
  const double alpha = 0.3, eta = 1.5, h = 1e-6;
  const Eigen::Vector3d wi = SphericalDirection(Deg(35), 0.2);
  for (const Eigen::Vector3d& wo : {SphericalDirection(Deg(50), 3.0), SphericalDirection(Deg(160), 3.5)}) {
    const WalterRoughDielectric<GgxDistributionT<Jet>> jet_bsdf(GgxDistributionT<Jet>(Jet(alpha, 0)), Jet(eta, 1));
    const Jet value = jet_bsdf.Eval(wi.cast<Jet>(), wo.cast<Jet>());
    const auto f = [&](double a, double e) {
      return WalterRoughDielectric<GgxDistribution>(GgxDistribution(a), e).Eval(wi, wo);
    };
    EXPECT_NEAR(value.a, f(alpha, eta), 1e-13 * std::abs(value.a));
    EXPECT_NEAR(value.v[0], (f(alpha + h, eta) - f(alpha - h, eta)) / (2 * h), 1e-5 * std::abs(value.v[0]) + 1e-8);
    EXPECT_NEAR(value.v[1], (f(alpha, eta + h) - f(alpha, eta - h)) / (2 * h), 1e-5 * std::abs(value.v[1]) + 1e-8);
  }
}

TEST(WalterRoughDielectric, ParametersAndPrinting) {
  const auto params = WalterRoughDielectric<GgxDistribution>::Params();
  ASSERT_EQ(params.size(), 3u);
  EXPECT_STREQ(params[2].name, "eta");
  EXPECT_EQ(WalterRoughDielectric<BeckmannDistribution>(BeckmannDistribution(0.2), 1.5).ToString(),
            "WalterRoughDielectric(BeckmannDistribution(alpha_x=0.2, alpha_y=0.2), eta=1.5)");
}

TEST(ChiSquareHelpers, IncompleteGammaMatchesKnownValues) {
  EXPECT_NEAR(testing::RegularizedGammaQ(1.0, 2.0), std::exp(-2.0), 1e-14);
  EXPECT_NEAR(testing::RegularizedGammaQ(1.0, 0.1), std::exp(-0.1), 1e-14);
  // Critical values of the chi-square distribution at significance 0.01.
  EXPECT_NEAR(testing::ChiSquarePValue(36.191, 19), 0.01, 1e-4);
  EXPECT_NEAR(testing::ChiSquarePValue(6.635, 1), 0.01, 1e-4);
  EXPECT_NEAR(testing::ChiSquarePValue(863.0, 799), 0.0556, 2e-3);  // Normal approx. ~0.056.
  EXPECT_NEAR(testing::ChiSquarePValue(799.0, 799), 0.4930, 2e-3);
}

}  // namespace
}  // namespace thinslab
