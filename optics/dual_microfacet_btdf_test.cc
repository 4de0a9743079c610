// SPDX-License-Identifier: Apache-2.0
// Laws of the dual-microfacet BTDF (optics/dual_microfacet_btdf.h, Dai et al. 2009): the half
// vectors of Eqs. 4 and 7 satisfy Snell's law along the virtual paths, the Jacobians (Eqs. 5
// and 9) equal finite-difference solid-angle ratios of the half-vector maps, Eq. 11 has the
// right endpoints, the tabulated NDF reproduces an analytic one and is normalised, and no
// virtual configuration transmits more than it receives.
#include "thinslab/optics/dual_microfacet_btdf.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <random>

#include "thinslab/core/math.h"
#include "thinslab/optics/fresnel.h"
#include "thinslab/optics/microfacet.h"
#include "thinslab/optics/sphere_test_util.h"

namespace thinslab {
namespace {

using testing::Integrate2D;

Eigen::Vector3d SphericalDirection(double theta, double phi) {
  return Eigen::Vector3d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi), std::cos(theta));
}

double Deg(double degrees) { return degrees * kPi / 180.0; }

using GgxBtdf = DualMicrofacetBtdf<GgxDistribution>;

GgxBtdf MakeGgx(double alpha, double eta) { return GgxBtdf(GgxDistribution(alpha), GgxDistribution(alpha), eta); }

// Random (i, o) pairs with i above (theta_i < 75 deg) and o below (theta_o < 75 deg) for which
// the virtual path exists (rho > 0).
struct Pair {
  Eigen::Vector3d i, o;
};

std::vector<Pair> RandomPairs(int count, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  std::vector<Pair> pairs;
  for (int k = 0; k < count; ++k) {
    const Eigen::Vector3d i = SphericalDirection(Deg(75) * uni(rng), 2 * kPi * uni(rng));
    Eigen::Vector3d o = SphericalDirection(Deg(75) * uni(rng), 2 * kPi * uni(rng));
    o.z() = -o.z();
    pairs.push_back({i, o});
  }
  return pairs;
}

TEST(DualMicrofacet, TopHalfVectorRefractsIntoTheVirtualInternalDirection) {
  const GgxBtdf btdf = MakeGgx(0.5, 1.5);
  int checked = 0;
  for (const Pair& p : RandomPairs(2000, 1)) {
    if (!(btdf.EvalTop(p.i, p.o) > 0)) continue;
    ++checked;
    const Eigen::Vector3d h = btdf.TopHalfVector(p.i, p.o);
    EXPECT_NEAR(h.norm(), 1.0, 1e-12);
    EXPECT_GT(h.z(), 0.0);
    // Snell about h_t (air -> slab): i refracts into w = o_m / eta ...
    const Eigen::Vector3d w = btdf.OutgoingMomentum(p.o) / btdf.eta;
    Eigen::Vector3d wt;
    ASSERT_TRUE(Refract(p.i, h, btdf.eta, &wt));
    EXPECT_NEAR((wt - w).norm(), 0.0, 1e-10);
    // ... and w leaves the flat bottom (slab -> air) as o. Refract takes directions pointing
    // away from the surface: -w points back into the slab side, which +z points to.
    Eigen::Vector3d out;
    ASSERT_TRUE(Refract(Eigen::Vector3d(-w), Eigen::Vector3d(0, 0, 1), 1 / btdf.eta, &out));
    EXPECT_NEAR((out - p.o).norm(), 0.0, 1e-10);
  }
  EXPECT_GT(checked, 1000);
}

TEST(DualMicrofacet, BottomHalfVectorRefractsTheInternalDirectionIntoO) {
  const GgxBtdf btdf = MakeGgx(0.5, 1.5);
  int checked = 0;
  for (const Pair& p : RandomPairs(2000, 2)) {
    if (!(btdf.EvalBottom(p.i, p.o) > 0)) continue;
    ++checked;
    const Eigen::Vector3d h = btdf.BottomHalfVector(p.i, p.o);
    EXPECT_NEAR(h.norm(), 1.0, 1e-12);
    EXPECT_GT(h.z(), 0.0);
    // Flat top (air -> slab): i refracts into the propagation direction -i', i' = i_m / eta
    // (Eq. 8).
    Eigen::Vector3d d;
    ASSERT_TRUE(Refract(p.i, Eigen::Vector3d(0, 0, 1), btdf.eta, &d));
    const Eigen::Vector3d ip = btdf.IncidentMomentum(p.i) / btdf.eta;
    EXPECT_NEAR((d + ip).norm(), 0.0, 1e-12);
    // Snell about h_b (slab -> air): i' refracts into o.
    Eigen::Vector3d out;
    ASSERT_TRUE(Refract(ip, h, 1 / btdf.eta, &out));
    EXPECT_NEAR((out - p.o).norm(), 0.0, 1e-10);
  }
  EXPECT_GT(checked, 1000);
}

// |d omega_h / d omega_o| by central differences: o(u, v) = normalize(o + u t1 + v t2) has
// d omega_o = du dv at u = v = 0, and d omega_h = |dh/du x dh/dv| du dv.
template <typename HalfVector>
double FiniteDifferenceJacobian(const Eigen::Vector3d& o, const HalfVector& half_vector) {
  const Eigen::Vector3d t1 = o.unitOrthogonal(), t2 = o.cross(t1);
  constexpr double kStep = 1e-6;
  const auto h = [&](double u, double v) { return half_vector(Eigen::Vector3d((o + u * t1 + v * t2).normalized())); };
  const Eigen::Vector3d dhu = (h(kStep, 0) - h(-kStep, 0)) / (2 * kStep);
  const Eigen::Vector3d dhv = (h(0, kStep) - h(0, -kStep)) / (2 * kStep);
  return dhu.cross(dhv).norm();
}

TEST(DualMicrofacet, JacobiansMatchFiniteDifferencesOfTheHalfVectorMaps) {
  for (double eta : {1.33, 1.5, 2.0}) {
    const GgxBtdf btdf = MakeGgx(0.5, eta);
    double max_top = 0, max_bottom = 0, max_seed_eq5 = 0;
    for (const Pair& p : RandomPairs(500, 3)) {
      if (btdf.EvalTop(p.i, p.o) > 0) {
        const double fd =
            FiniteDifferenceJacobian(p.o, [&](const Eigen::Vector3d& o) { return btdf.TopHalfVector(p.i, o); });
        const double rel = std::abs(btdf.TopJacobian(p.i, p.o) / fd - 1);
        max_top = std::max(max_top, rel);
        EXPECT_LT(rel, 1e-6) << "top eta=" << eta << " i=" << p.i.transpose() << " o=" << p.o.transpose();
        // The seed text's Eq. 5, |o . o_m| |o_m . h_t| / (eta^2 (i . h_t + o_m . h_t)^2), for the record.
        const Eigen::Vector3d om = btdf.OutgoingMomentum(p.o), h = btdf.TopHalfVector(p.i, p.o);
        const double seed = std::abs(p.o.dot(om)) * std::abs(om.dot(h)) / (eta * eta * Sqr(p.i.dot(h) + om.dot(h)));
        max_seed_eq5 = std::max(max_seed_eq5, std::abs(seed / fd - 1));
      }
      if (btdf.EvalBottom(p.i, p.o) > 0) {
        const double fd =
            FiniteDifferenceJacobian(p.o, [&](const Eigen::Vector3d& o) { return btdf.BottomHalfVector(p.i, o); });
        const double rel = std::abs(btdf.BottomJacobian(p.i, p.o) / fd - 1);
        max_bottom = std::max(max_bottom, rel);
        EXPECT_LT(rel, 1e-6) << "bottom eta=" << eta << " i=" << p.i.transpose() << " o=" << p.o.transpose();
      }
    }
    std::printf("eta=%.2f max rel error vs finite differences: Eq.5 (derived) %.2e, Eq.9 %.2e; seed-text Eq.5 %.2e\n",
                eta, max_top, max_bottom, max_seed_eq5);
  }
}

TEST(DualMicrofacet, Eq11EndpointsAndGeometricMean) {
  const GgxBtdf btdf = MakeGgx(0.4, 1.5);
  int both = 0;
  for (const Pair& p : RandomPairs(500, 4)) {
    const double rho_t = btdf.EvalTop(p.i, p.o), rho_b = btdf.EvalBottom(p.i, p.o);
    EXPECT_EQ(btdf.Eval(p.i, p.o, 1.0), rho_t);
    EXPECT_EQ(btdf.Eval(p.i, p.o, 0.0), rho_b);
    if (rho_t > 0 && rho_b > 0) {
      ++both;
      EXPECT_NEAR(btdf.Eval(p.i, p.o, 0.5) / std::sqrt(rho_t * rho_b), 1.0, 1e-12);
      // ln rho is affine in alpha.
      const double l25 = std::log(btdf.Eval(p.i, p.o, 0.25)), l75 = std::log(btdf.Eval(p.i, p.o, 0.75));
      EXPECT_NEAR(0.5 * (l25 + l75), std::log(btdf.Eval(p.i, p.o, 0.5)), 1e-12);
    }
  }
  EXPECT_GT(both, 200);
}

// Integral of f(m) (m . n) d omega over the hemisphere, in (theta, phi).
template <typename F>
double ProjectedIntegral(const F& f, double peak_theta_break) {
  return Integrate2D(
      [&](double theta, double phi) { return f(SphericalDirection(theta, phi)) * std::cos(theta) * std::sin(theta); },
      0, kPi / 2, 0, 2 * kPi, {peak_theta_break}, {}, 1e-7, 1e-6);
}

TEST(TabulatedNdf, ReproducesGgxAndIsNormalised) {
  // 64 x 64 cells: cell side 1/32 in the projected disk, about 10 cells per alpha = 0.3.
  // Bilinear error is about h^2 / 8 |D''| / D ~ 2% at the GGX peak (|D''| / D = 12 / alpha^2).
  constexpr int kN = 64;
  constexpr double kAlpha = 0.3, kRelTolerance = 0.03;
  const GgxDistribution ggx(kAlpha);
  const TabulatedNdf table = TabulatedNdf::FromDistribution(ggx, kN);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const double peak = ggx.D(Eigen::Vector3d(0, 0, 1));
  double max_rel = 0;
  for (int k = 0; k < 20000; ++k) {
    const Eigen::Vector3d m = SphericalDirection(std::acos(uni(rng)), 2 * kPi * uni(rng));
    const double d = ggx.D(m);
    if (d < 0.01 * peak) continue;
    max_rel = std::max(max_rel, std::abs(table.D(m) / d - 1));
  }
  std::printf("TabulatedNdf %dx%d of GGX(%.2f): max rel error where D >= 1%% of peak: %.4f\n", kN, kN, kAlpha, max_rel);
  EXPECT_LT(max_rel, kRelTolerance);
  const double integral = ProjectedIntegral([&](const Eigen::Vector3d& m) { return table.D(m); }, 0.3);
  std::printf("TabulatedNdf integral of D (m.n) d omega = %.6f\n", integral);
  EXPECT_NEAR(integral, 1.0, 1e-3);
  EXPECT_EQ(table.D(Eigen::Vector3d(0.6, 0, -0.8)), 0.0);
}

TEST(TabulatedNdf, RawConstantValuesGiveTheUniformCosineNdf) {
  // Constant D normalised: D = 1 / pi (integral of cos over the hemisphere is pi).
  const TabulatedNdf table(32, std::vector<double>(32 * 32, 5.0));
  EXPECT_NEAR(table.D(Eigen::Vector3d(0, 0, 1)) * kPi, 1.0, 1e-3);
  EXPECT_NEAR(ProjectedIntegral([&](const Eigen::Vector3d& m) { return table.D(m); }, 0.5), 1.0, 1e-3);
}

// Transmitted albedo integral rho(i, o) |o . n| d omega_o = integral rho dx dy over the
// projected disk of o (midpoint rule, cells of side 2 / n).
template <typename Rho>
double TransmittedAlbedo(const Rho& rho, int n) {
  const double h = 2.0 / n;
  double sum = 0;
  for (int r = 0; r < n; ++r) {
    const double y = -1 + (r + 0.5) * h;
    for (int c = 0; c < n; ++c) {
      const double x = -1 + (c + 0.5) * h;
      const double s = 1 - x * x - y * y;
      if (s <= 0) continue;
      sum += rho(Eigen::Vector3d(x, y, -std::sqrt(s)));
    }
  }
  return sum * h * h;
}

TEST(DualMicrofacet, VirtualConfigurationsDoNotCreateEnergy) {
  constexpr double kEta = 1.5;
  constexpr int kGrid = 800;
  for (double alpha : {0.1, 0.3, 0.6, 1.0}) {
    const GgxBtdf btdf = MakeGgx(alpha, kEta);
    const auto tab_btdf = MakeDualMicrofacetBtdf(TabulatedNdf::FromDistribution(GgxDistribution(alpha), 64),
                                                 GgxDistribution(alpha), kEta);
    for (double theta_deg : {0.0, 30.0, 60.0, 80.0}) {
      const Eigen::Vector3d i = SphericalDirection(Deg(theta_deg), 0.4);
      const double a_t = TransmittedAlbedo([&](const Eigen::Vector3d& o) { return btdf.EvalTop(i, o); }, kGrid);
      const double a_b = TransmittedAlbedo([&](const Eigen::Vector3d& o) { return btdf.EvalBottom(i, o); }, kGrid);
      const double a_tab = TransmittedAlbedo([&](const Eigen::Vector3d& o) { return tab_btdf.EvalTop(i, o); }, kGrid);
      std::printf("alpha=%.2f theta_i=%2.0f: albedo rho_t %.4f rho_b %.4f rho_t(tabulated) %.4f\n", alpha, theta_deg,
                  a_t, a_b, a_tab);
      EXPECT_LE(a_t, 1.0);
      EXPECT_LE(a_b, 1.0);
      EXPECT_LE(a_tab, 1.0);
      EXPECT_GT(a_t, 0.0);
      EXPECT_GT(a_b, 0.0);
    }
  }
}

TEST(DualMicrofacet, NearlySmoothSlabTransmitsTheTwoFresnelFactors) {
  // alpha -> 0: both configurations become the flat slab, albedo (1 - F(i)) (1 - F(i')) with
  // F(i') = F(i) for the refraction pair; G -> 1. Residual 1% covers the lobe's spread of F.
  constexpr double kEta = 1.5;
  const GgxBtdf btdf = MakeGgx(0.02, kEta);
  for (double theta_deg : {0.0, 30.0, 50.0}) {
    const Eigen::Vector3d i = SphericalDirection(Deg(theta_deg), 1.0);
    const double expected = Sqr(1 - FresnelDielectric(i.z(), kEta));
    const double a_t = TransmittedAlbedo([&](const Eigen::Vector3d& o) { return btdf.EvalTop(i, o); }, 2000);
    const double a_b = TransmittedAlbedo([&](const Eigen::Vector3d& o) { return btdf.EvalBottom(i, o); }, 2000);
    std::printf("alpha=0.02 theta_i=%2.0f: (1-F)^2 %.4f rho_t %.4f rho_b %.4f\n", theta_deg, expected, a_t, a_b);
    EXPECT_NEAR(a_t / expected, 1.0, 0.01);
    EXPECT_NEAR(a_b / expected, 1.0, 0.01);
  }
}

}  // namespace
}  // namespace thinslab
