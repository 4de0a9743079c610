// SPDX-License-Identifier: Apache-2.0
// Laws of the microfacet distributions (Walter et al. 2007, Sec. 3): D normalisation, the
// projected-area identity of the Smith G1, and sampling of m by D(m) |m . n|
// (Sec. 5.3) checked by a chi-square test.
#include "thinslab/optics/microfacet.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <random>
#include <vector>

#include "thinslab/optics/sphere_test_util.h"

namespace thinslab {
namespace {

using testing::Integrate1D;
using testing::PooledChiSquare;

Eigen::Vector3d SphericalDirection(double theta, double phi) {
  return Eigen::Vector3d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
}

// Polar-angle break points around the peak of a distribution of width alpha.
std::vector<double> ThetaBreaks(double alpha) {
  std::vector<double> breaks;
  for (double s : {0.1, 0.3, 1.0, 3.0, 10.0, 30.0}) breaks.push_back(std::atan(alpha * s));
  return breaks;
}

const std::vector<double> kQuadrantBreaks = {0.5 * kPi, kPi, 1.5 * kPi};

// Integral over the upper hemisphere of g(m) d omega_m, integrated in (theta_m, phi_m) with
// break points resolving a peak of width alpha at the normal.
template <typename G>
double HemisphereIntegral(const G& g, double alpha, std::vector<double> phi_breaks = kQuadrantBreaks) {
  const auto over_phi = [&](double theta) {
    return std::sin(theta) * Integrate1D([&](double phi) { return g(SphericalDirection(theta, phi)); }, 0.0, 2.0 * kPi,
                                         phi_breaks, 1e-11, 1e-10);
  };
  return Integrate1D(over_phi, 0.0, 0.5 * kPi, ThetaBreaks(alpha), 1e-9, 1e-9);
}

// Walter et al. 2007, Sec. 3: integral of D(m) (m . n) d omega_m = 1.
template <typename Distribution>
double NormalizationError(const Distribution& dist, double alpha) {
  const double integral = HemisphereIntegral([&](const Eigen::Vector3d& wm) { return dist.D(wm) * wm.z(); }, alpha);
  return integral - 1.0;
}

TEST(Microfacet, NdfIsNormalized) {
  double max_error = 0;
  const auto check = [&](const auto& dist, double alpha) {
    const double error = NormalizationError(dist, alpha);
    max_error = std::max(max_error, std::abs(error));
    EXPECT_LT(std::abs(error), 1e-3) << dist.ToString();
    std::printf("  %-50s  int D cos = 1 %+.2e\n", dist.ToString().c_str(), error);
  };
  for (double alpha : {0.02, 0.1, 0.5, 1.0}) {
    check(GgxDistribution(alpha), alpha);
    check(BeckmannDistribution(alpha), alpha);
  }
  check(GgxDistribution(0.1, 0.4), 0.1);
  check(BeckmannDistribution(0.1, 0.4), 0.1);
  check(GgxDistribution(0.4, 0.02), 0.02);
  check(BeckmannDistribution(0.4, 0.02), 0.02);
  for (double exponent : {10.0, 100.0}) check(PhongDistribution(exponent), BeckmannAlphaFromPhongExponent(exponent));
  std::printf("  max |normalisation error| = %.2e\n", max_error);
}

// Walter et al. 2007, Sec. 3 (projected area of the microsurface onto a plane perpendicular to
// v equals that of the macro-surface): integral of G1(v, m) max(0, v . m) D(m) d omega_m = v . n.
template <typename Distribution>
double ProjectedArea(const Distribution& dist, const Eigen::Vector3d& v, double alpha) {
  const double theta_v = std::acos(v.z()), phi_v = std::atan2(v.y(), v.x());
  const auto over_phi = [&](double theta) {
    // Kinks of max(0, v . m) in phi: cos(phi - phi_v) = -cot(theta) cot(theta_v).
    std::vector<double> breaks = kQuadrantBreaks;
    if (theta_v > 0 && theta > 0) {
      const double c = -1.0 / (std::tan(theta) * std::tan(theta_v));
      if (std::abs(c) < 1) {
        for (double sign : {-1.0, 1.0}) {
          breaks.push_back(std::fmod(phi_v + sign * std::acos(c) + 4.0 * kPi, 2.0 * kPi));
        }
      }
    }
    const auto integrand = [&](double phi) {
      const Eigen::Vector3d wm = SphericalDirection(theta, phi);
      return dist.G1(v, wm) * std::max(0.0, v.dot(wm)) * dist.D(wm);
    };
    return std::sin(theta) * Integrate1D(integrand, 0.0, 2.0 * kPi, breaks, 1e-11, 1e-10);
  };
  std::vector<double> theta_breaks = ThetaBreaks(alpha);
  theta_breaks.push_back(0.5 * kPi - theta_v);  // Where the kink curve reaches phi = phi_v + pi.
  return Integrate1D(over_phi, 0.0, 0.5 * kPi, theta_breaks, 1e-9, 1e-9);
}

TEST(Microfacet, SmithG1SatisfiesProjectedAreaIdentity) {
  double max_error = 0;
  const auto check = [&](const auto& dist, double alpha, double tolerance) {
    for (double theta_v_deg : {0.0, 30.0, 60.0, 80.0, 89.0}) {
      for (double phi_v : {0.0, 1.0}) {
        const Eigen::Vector3d v = SphericalDirection(theta_v_deg * kPi / 180.0, phi_v);
        const double error = ProjectedArea(dist, v, alpha) - v.z();
        EXPECT_LT(std::abs(error), tolerance) << dist.ToString() << " theta_v=" << theta_v_deg << " phi_v=" << phi_v;
        if (tolerance <= 1e-3) max_error = std::max(max_error, std::abs(error));
      }
    }
  };
  for (double alpha : {0.02, 0.1, 0.5, 1.0}) {
    check(GgxDistribution(alpha), alpha, 1e-3);
    check(BeckmannDistribution(alpha), alpha, 1e-3);
  }
  check(GgxDistribution(0.1, 0.4), 0.1, 1e-3);
  check(BeckmannDistribution(0.1, 0.4), 0.1, 1e-3);
  std::printf("  max |projected-area error| (GGX, Beckmann) = %.2e\n", max_error);
  // Phong borrows the Beckmann Lambda (Walter Sec. 5.2), so the identity is approximate.
  for (double exponent : {10.0, 100.0}) {
    const PhongDistribution phong(exponent);
    const Eigen::Vector3d v = SphericalDirection(80.0 * kPi / 180.0, 0.3);
    const double error = ProjectedArea(phong, v, BeckmannAlphaFromPhongExponent(exponent)) - v.z();
    std::printf("  Phong alpha_p=%g projected-area error at 80 deg: %+.2e (approximate Lambda)\n", exponent, error);
    EXPECT_LT(std::abs(error), 2e-2);
  }
}

TEST(Microfacet, MaskingLimits) {
  const GgxDistribution ggx(0.3, 0.1);
  const BeckmannDistribution beckmann(0.3, 0.1);
  const Eigen::Vector3d n(0, 0, 1);
  EXPECT_DOUBLE_EQ(ggx.G1(n, n), 1.0);
  EXPECT_DOUBLE_EQ(beckmann.G1(n, n), 1.0);
  // Masking grows towards grazing, and a facet facing away is masked.
  EXPECT_GT(ggx.G1(SphericalDirection(0.5, 0.2), n), ggx.G1(SphericalDirection(1.4, 0.2), n));
  EXPECT_GT(beckmann.G1(SphericalDirection(0.5, 0.2), n), beckmann.G1(SphericalDirection(1.4, 0.2), n));
  EXPECT_EQ(ggx.G1(SphericalDirection(1.2, 0.0), SphericalDirection(0.6, kPi)), 0.0);
  // Rougher along x masks more along x.
  EXPECT_LT(ggx.G1(SphericalDirection(1.3, 0.0), n), ggx.G1(SphericalDirection(1.3, 0.5 * kPi), n));
  // Height-correlated G2 lies between the separable product and the smaller G1.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (int k = 0; k < 1000; ++k) {
    const Eigen::Vector3d wi = SphericalDirection(std::acos(uni(rng)), 2 * kPi * uni(rng));
    const Eigen::Vector3d wo = SphericalDirection(std::acos(uni(rng)), 2 * kPi * uni(rng));
    const Eigen::Vector3d wm = (wi + wo).normalized();
    for (const double g2 : {ggx.GHeightCorrelatedReflection(wi, wo, wm), ggx.G(wi, wo, wm)}) {
      EXPECT_LE(g2, std::min(ggx.G1(wi, wm), ggx.G1(wo, wm)) + 1e-15);
    }
    EXPECT_GE(ggx.GHeightCorrelatedReflection(wi, wo, wm), ggx.G(wi, wo, wm) - 1e-15);
  }
}

// Walter Eq. 27 (rational approximation of the Beckmann G1, quoted as accurate to better than
// ~1 %) against the exact erf form used here.
TEST(Microfacet, BeckmannG1AgreesWithWalterRationalApproximation) {
  for (double alpha : {0.05, 0.3, 1.0}) {
    const BeckmannDistribution beckmann(alpha);
    for (double theta = 0.05; theta < 1.56; theta += 0.05) {
      const double a = 1.0 / (alpha * std::tan(theta));
      const double approx = a < 1.6 ? (3.535 * a + 2.181 * a * a) / (1 + 2.276 * a + 2.577 * a * a) : 1.0;
      const Eigen::Vector3d v = SphericalDirection(theta, 0.7);
      EXPECT_NEAR(beckmann.G1(v, Eigen::Vector3d(0, 0, 1)), approx, 5e-3) << "alpha=" << alpha << " theta=" << theta;
    }
  }
}

// Walter Sec. 5.2: alpha_p = 2 alpha_b^-2 - 2 matches the Phong and Beckmann peaks exactly
// (D(n) = (alpha_p + 2) / (2 pi) = 1 / (pi alpha_b^2)) and their curvature there.
TEST(Microfacet, PhongBeckmannExponentRelation) {
  for (double alpha_b : {0.05, 0.2, 0.5}) {
    const double alpha_p = PhongExponentFromBeckmannAlpha(alpha_b);
    EXPECT_NEAR(BeckmannAlphaFromPhongExponent(alpha_p), alpha_b, 1e-14);
    const PhongDistribution phong(alpha_p);
    const BeckmannDistribution beckmann(alpha_b);
    const Eigen::Vector3d n(0, 0, 1);
    EXPECT_NEAR(phong.D(n) / beckmann.D(n), 1.0, 1e-12);
    const Eigen::Vector3d m = SphericalDirection(0.2 * alpha_b, 0.4);
    // ln(D_phong / D_beckmann) = -theta^2 + O(theta^4) near the normal.
    EXPECT_NEAR(phong.D(m) / beckmann.D(m), 1.0, 0.05 * alpha_b * alpha_b) << "alpha_b=" << alpha_b;
  }
}

// Chi-square test of Sample() against D(m) m.z: 20 bins in t = atan(tan(theta_m) / alpha),
// which resolves the peak for any alpha, times 40 bins in phi_m; 1e5 samples.
template <typename Distribution>
void CheckNormalSampling(const Distribution& dist, double alpha, uint64_t seed) {
  constexpr int kThetaBins = 20, kPhiBins = 40, kSamples = 100000;
  std::vector<double> observed(kThetaBins * kPhiBins, 0.0), expected(kThetaBins * kPhiBins, 0.0);
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  for (int s = 0; s < kSamples; ++s) {
    const Eigen::Vector3d wm = dist.Sample(uni(rng), uni(rng));
    ASSERT_NEAR(wm.norm(), 1.0, 1e-12);
    ASSERT_GE(wm.z(), 0.0);
    const double t = std::atan(std::sqrt(Sqr(wm.x()) + Sqr(wm.y())) / (alpha * wm.z()));
    double phi = std::atan2(wm.y(), wm.x());
    if (phi < 0) phi += 2 * kPi;
    const int i = std::min(kThetaBins - 1, static_cast<int>(t / (0.5 * kPi) * kThetaBins));
    const int j = std::min(kPhiBins - 1, static_cast<int>(phi / (2 * kPi) * kPhiBins));
    observed[i * kPhiBins + j] += 1;
  }
  for (int i = 0; i < kThetaBins; ++i) {
    const double theta0 = std::atan(alpha * std::tan(0.5 * kPi * i / kThetaBins));
    const double theta1 =
        i + 1 == kThetaBins ? 0.5 * kPi : std::atan(alpha * std::tan(0.5 * kPi * (i + 1) / kThetaBins));
    for (int j = 0; j < kPhiBins; ++j) {
      const double phi0 = 2 * kPi * j / kPhiBins, phi1 = 2 * kPi * (j + 1) / kPhiBins;
      const auto over_phi = [&](double theta) {
        return std::sin(theta) * Integrate1D(
                                     [&](double phi) {
                                       const Eigen::Vector3d wm = SphericalDirection(theta, phi);
                                       return dist.D(wm) * wm.z();
                                     },
                                     phi0, phi1, {}, 1e-12, 1e-10);
      };
      expected[i * kPhiBins + j] = kSamples * Integrate1D(over_phi, theta0, theta1, {}, 1e-11, 1e-10);
    }
  }
  const auto result = PooledChiSquare(observed, expected);
  std::printf("  %-50s  %s\n", dist.ToString().c_str(), result.ToString().c_str());
  EXPECT_EQ(result.observed_in_empty_cells, 0.0) << dist.ToString();
  EXPECT_GT(result.p_value, 0.01) << dist.ToString() << " " << result.ToString();
}

TEST(Microfacet, NormalSamplingMatchesDTimesCosineChiSquare) {
  uint64_t seed = 11;
  for (double alpha : {0.02, 0.1, 0.5, 1.0}) {
    CheckNormalSampling(GgxDistribution(alpha), alpha, ++seed);
    CheckNormalSampling(BeckmannDistribution(alpha), alpha, ++seed);
  }
  CheckNormalSampling(GgxDistribution(0.1, 0.4), 0.2, ++seed);
  CheckNormalSampling(BeckmannDistribution(0.1, 0.4), 0.2, ++seed);
  for (double exponent : {10.0, 100.0}) {
    CheckNormalSampling(PhongDistribution(exponent), BeckmannAlphaFromPhongExponent(exponent), ++seed);
  }
}

// D, Lambda and G1 are differentiable in alpha with Ceres Jets (what fits use).
TEST(Microfacet, JetDerivativesMatchFiniteDifferences) {
  using Jet = ceres::Jet<double, 2>;
  const Eigen::Vector3d wm_d = SphericalDirection(0.3, 0.8), w_d = SphericalDirection(1.1, 2.0);
  const Vector3T<Jet> wm = wm_d.cast<Jet>(), w = w_d.cast<Jet>();
  const double ax = 0.25, ay = 0.4, h = 1e-6;
  const Jet jax(ax, 0), jay(ay, 1);
  {
    const GgxDistributionT<Jet> jet_dist(jax, jay);
    const auto fd = [&](double dx, double dy) { return GgxDistribution(ax + dx, ay + dy); };
    EXPECT_NEAR(jet_dist.D(wm).v[0], (fd(h, 0).D(wm_d) - fd(-h, 0).D(wm_d)) / (2 * h), 1e-6);
    EXPECT_NEAR(jet_dist.D(wm).v[1], (fd(0, h).D(wm_d) - fd(0, -h).D(wm_d)) / (2 * h), 1e-6);
    EXPECT_NEAR(jet_dist.G1(w, wm).v[0], (fd(h, 0).G1(w_d, wm_d) - fd(-h, 0).G1(w_d, wm_d)) / (2 * h), 1e-6);
  }
  {
    const BeckmannDistributionT<Jet> jet_dist(jax, jay);
    const auto fd = [&](double dx, double dy) { return BeckmannDistribution(ax + dx, ay + dy); };
    EXPECT_NEAR(jet_dist.D(wm).v[1], (fd(0, h).D(wm_d) - fd(0, -h).D(wm_d)) / (2 * h), 1e-6);
    EXPECT_NEAR(jet_dist.Lambda(w).v[0], (fd(h, 0).Lambda(w_d) - fd(-h, 0).Lambda(w_d)) / (2 * h), 1e-6);
    EXPECT_NEAR(jet_dist.G1(w, wm).v[1], (fd(0, h).G1(w_d, wm_d) - fd(0, -h).G1(w_d, wm_d)) / (2 * h), 1e-6);
  }
}

TEST(Microfacet, ParameterListsAndPrinting) {
  EXPECT_EQ(GgxDistribution::Params().size(), 2u);
  EXPECT_STREQ(BeckmannDistribution::Params()[1].name, "alpha_y");
  EXPECT_EQ(PhongDistribution::Params()[0].unit, std::string("1"));
  EXPECT_EQ(GgxDistribution(0.1, 0.2).ToString(), "GgxDistribution(alpha_x=0.1, alpha_y=0.2)");
}

}  // namespace
}  // namespace thinslab
