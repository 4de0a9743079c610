// SPDX-License-Identifier: Apache-2.0
#include "thinslab/optics/thin_slab.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>

#include "thinslab/core/math.h"

namespace thinslab {
namespace {

// Hemispherical integrals of BSDF * mu for a beam at mu0 (flux fractions), midpoint rule in
// (mu, phi); phi is measured from the azimuth of the direction towards the light.
struct Albedos {
  double reflected = 0;
  double transmitted = 0;
};
Albedos Integrate(const ThinSlab<double>& slab, double mu0, int n_mu = 400, int n_phi = 256) {
  Albedos out;
  for (int i = 0; i < n_mu; ++i) {
    const double mu = (i + 0.5) / n_mu;
    for (int j = 0; j < n_phi; ++j) {
      const double dphi = (j + 0.5) * 2 * kPi / n_phi;
      const double dw = (1.0 / n_mu) * (2 * kPi / n_phi);
      out.reflected += slab.ReflectedBsdf(mu0, mu, slab.ScatterCosineReflected(mu0, mu, dphi)) * mu * dw;
      out.transmitted +=
          slab.TransmittedBsdf(mu0, mu, slab.ScatterCosineTransmitted(mu0, mu, dphi)) * mu * dw;
    }
  }
  return out;
}

// Energy: single-scattered + directly transmitted flux never exceeds the incident flux, and
// the scattered flux is at most what the beam loses to scattering, omega0 (1 - e^{-tau1/mu0})
// (every scattered photon either leaves, counted here, or would scatter again, which the
// single-scatter model drops). For tau1 -> 0 nothing is dropped: the ratio tends to 1.
TEST(ThinSlab, EnergyBounds) {
  for (double g : {0.0, 0.6, -0.3}) {
    for (double mu0 : {1.0, 0.7, 0.3}) {
      for (double tau1 : {0.005, 0.1, 0.5, 2.0}) {
        ThinSlab<double> slab;
        slab.tau1 = tau1;
        slab.albedo = 1.0;
        slab.g = g;
        const Albedos a = Integrate(slab, mu0);
        const double direct = slab.DirectTransmittance(mu0);
        const double lost_by_beam = 1.0 - direct;
        const double scattered = a.reflected + a.transmitted;
        SCOPED_TRACE(slab.ToString() + " mu0=" + std::to_string(mu0));
        EXPECT_GE(a.reflected, 0.0);
        EXPECT_GE(a.transmitted, 0.0);
        EXPECT_LE(scattered + direct, 1.0 + 2e-3);
        EXPECT_LE(scattered, lost_by_beam * (1.0 + 2e-3));
        if (tau1 <= 0.005) {
          EXPECT_NEAR(scattered / lost_by_beam, 1.0, 0.03);
        }
      }
    }
  }
}

// Eq. 5 at mu = mu0 is 0/0 as printed; the implementation gives the limit
// Lambda p tau1 e^{-tau1/mu0} / mu0, and is continuous there (matches the printed formula a
// little away from mu0, where the printed form is well conditioned).
TEST(ThinSlab, Eq5LimitAtMuEqualsMu0) {
  ThinSlab<double> slab;
  slab.tau1 = 0.3;
  slab.albedo = 0.7;
  slab.g = 0.4;
  const double cos_s = 0.9;
  const double p = slab.Phase(cos_s);
  for (double mu0 : {1.0, 0.6, 0.2}) {
    const double at = slab.TransmittedRadiance(mu0, mu0, cos_s);
    ASSERT_TRUE(std::isfinite(at));
    EXPECT_NEAR(at, p * slab.tau1 * std::exp(-slab.tau1 / mu0) / mu0, 1e-14);
    for (double h : {1e-9, 1e-6, 1e-3, 1e-2}) {
      const double mu = mu0 - h;
      const double printed =
          p * mu0 / (mu - mu0) * (std::exp(-slab.tau1 / mu) - std::exp(-slab.tau1 / mu0));
      const double impl = slab.TransmittedRadiance(mu0, mu, cos_s);
      // Printed form loses ~1e-16 / h relative accuracy to cancellation.
      EXPECT_NEAR(impl / printed, 1.0, 1e-14 + 3e-15 / h) << "mu0=" << mu0 << " h=" << h;
      // Continuity: first-order change around the limit.
      EXPECT_NEAR(impl, at, 10 * h * at / (mu0 * mu0)) << "mu0=" << mu0 << " h=" << h;
    }
  }
}

// tau1 -> 0: both Eq. 4 and Eq. 5 tend to Lambda p tau1 / mu (one scattering in a layer of
// slant optical thickness tau1 / mu), with a relative error that is first order in tau1.
TEST(ThinSlab, FirstOrderInTau) {
  for (double mu0 : {1.0, 0.5}) {
    for (double mu : {0.9, 0.5, 0.2}) {
      double prev_err_r = 0, prev_err_t = 0;
      for (double tau1 : {1e-3, 5e-4, 2.5e-4}) {
        ThinSlab<double> slab;
        slab.tau1 = tau1;
        slab.albedo = 0.8;
        slab.g = 0.5;
        const double cos_s = 0.3;
        const double first_order = slab.Phase(cos_s) * tau1 / mu;
        const double err_r = slab.ReflectedRadiance(mu0, mu, cos_s) / first_order - 1;
        const double err_t = slab.TransmittedRadiance(mu0, mu, cos_s) / first_order - 1;
        // Both errors are -tau1 (1/mu + 1/mu0) / 2 + O(tau1^2).
        EXPECT_NEAR(err_r, -tau1 * (1 / mu + 1 / mu0) / 2, 2 * Sqr(tau1 * (1 / mu + 1 / mu0)));
        EXPECT_NEAR(err_t, -tau1 * (1 / mu + 1 / mu0) / 2, 2 * Sqr(tau1 * (1 / mu + 1 / mu0)));
        if (prev_err_r != 0) {
          EXPECT_NEAR(prev_err_r / err_r, 2.0, 0.01);
          EXPECT_NEAR(prev_err_t / err_t, 2.0, 0.01);
        }
        prev_err_r = err_r;
        prev_err_t = err_t;
      }
    }
  }
}

// Helmholtz reciprocity: the BSDF forms (per unit surface irradiance) are symmetric in
// mu0 <-> mu; the radiance forms per beam-normal irradiance are not (they differ by mu0).
TEST(ThinSlab, BsdfReciprocity) {
  ThinSlab<double> slab;
  slab.tau1 = 0.4;
  slab.albedo = 0.9;
  slab.g = 0.7;
  for (double a : {0.95, 0.6, 0.15}) {
    for (double b : {0.8, 0.33}) {
      const double cos_s = 0.25;
      EXPECT_NEAR(slab.ReflectedBsdf(a, b, cos_s), slab.ReflectedBsdf(b, a, cos_s), 1e-13);
      EXPECT_NEAR(slab.TransmittedBsdf(a, b, cos_s), slab.TransmittedBsdf(b, a, cos_s), 1e-13);
      // The propagation-direction cosines are reciprocal too.
      EXPECT_NEAR(slab.ScatterCosineReflected(a, b, 1.0), slab.ScatterCosineReflected(b, a, 1.0),
                  1e-15);
    }
  }
  // Straight through and straight back.
  EXPECT_NEAR(ThinSlab<double>::ScatterCosineTransmitted(0.6, 0.6, kPi), 1.0, 1e-15);
  EXPECT_NEAR(ThinSlab<double>::ScatterCosineReflected(0.6, 0.6, 0.0), -1.0, 1e-15);
}

// Templated on T for Ceres: the tau1 derivative through the mu = mu0 branch matches a
// central difference.
TEST(ThinSlab, JetDerivative) {
  using Jet = ceres::Jet<double, 1>;
  ThinSlab<Jet> slab;
  slab.tau1 = Jet(0.2, 0);
  slab.albedo = Jet(0.5);
  slab.g = Jet(0.3);
  for (double mu : {0.6, 0.6 + 1e-7, 0.3}) {
    const Jet v = slab.TransmittedRadiance(Jet(0.6), Jet(mu), Jet(0.8));
    ThinSlab<double> plus{0.2 + 1e-6, 0.5, 0.3}, minus{0.2 - 1e-6, 0.5, 0.3};
    const double fd = (plus.TransmittedRadiance(0.6, mu, 0.8) - minus.TransmittedRadiance(0.6, mu, 0.8)) / 2e-6;
    EXPECT_NEAR(v.v[0], fd, 1e-6 * std::abs(fd)) << "mu=" << mu;
  }
  EXPECT_NE(slab.ToString().find("tau1=0.2"), std::string::npos);
}

TEST(ThinSlab, ParameterList) {
  const auto params = ThinSlab<double>::Parameters();
  ASSERT_EQ(params.size(), 3u);
  EXPECT_EQ(params[0].name, "tau1");
  EXPECT_EQ(params[1].name, "albedo");
  EXPECT_EQ(params[2].name, "g");
  for (const auto& p : params) EXPECT_LT(p.min, p.max) << p.name;
}

}  // namespace
}  // namespace thinslab
