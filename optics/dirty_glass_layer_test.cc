// SPDX-License-Identifier: Apache-2.0
#include "thinslab/optics/dirty_glass_layer.h"

#include <ceres/jet.h>
#include <gtest/gtest.h>

#include <cmath>

#include "thinslab/core/math.h"
#include "thinslab/optics/dirty_glass.h"
#include "thinslab/optics/fresnel.h"

namespace thinslab {
namespace {

using Vec3 = Eigen::Vector3d;

Vec3 Dir(double theta, double phi, double z_sign) {
  return Vec3(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
              z_sign * std::cos(theta));
}

DirtyGlassLayer<double> Layer(double tau, double albedo, double g, double n2, double n3,
                              bool thin_slab = false) {
  DirtyGlassLayer<double> layer;
  layer.tau = tau;
  layer.albedo = albedo;
  layer.g = g;
  layer.n1 = 1.0;
  layer.n2 = n2;
  layer.n3 = n3;
  layer.thin_slab = thin_slab;
  return layer;
}

// Flux fractions scattered to the +z and -z hemispheres: integral of f |cos| dw (midpoint
// rule in (mu, phi)).
void IntegrateDiffuse(const DirtyGlassLayer<double>& layer, const Vec3& wi, double* up,
                      double* down) {
  const int n_mu = 300, n_phi = 200;
  *up = *down = 0;
  for (int i = 0; i < n_mu; ++i) {
    const double mu = (i + 0.5) / n_mu;
    for (int j = 0; j < n_phi; ++j) {
      const double phi = (j + 0.5) * 2 * kPi / n_phi;
      const double dw = (1.0 / n_mu) * (2 * kPi / n_phi);
      const double theta = std::acos(mu);
      *up += layer.Bsdf(wi, Dir(theta, phi, 1)) * mu * dw;
      *down += layer.Bsdf(wi, Dir(theta, phi, -1)) * mu * dw;
    }
  }
}

// n1 = n2 = n3 = 1, normal incidence: the BTDF is optics/dirty_glass.h's
// LayerSingleScatterRadiance (Gu Eq. 6 / mu_i with mu_i = 1) and the unscattered term is
// LayerDirectTransmittance, lit from either side; nothing is mirror-reflected.
TEST(DirtyGlassLayer, ReducesToDirtyGlassAtNormalIncidence) {
  const DirtyGlassLayer<double> layer = Layer(0.35, 0.6, 0.7, 1.0, 1.0);
  for (double z_sign : {1.0, -1.0}) {
    const Vec3 wi(0, 0, z_sign);
    const DirtyGlassLayerSpecular<double> spec = layer.Specular(wi);
    EXPECT_NEAR(spec.transmittance, LayerDirectTransmittance(layer.tau), 1e-15);
    EXPECT_EQ(spec.reflectance, 0.0);
    EXPECT_NEAR((spec.transmitted_dir + wi).norm(), 0.0, 1e-15);
    for (double theta : {0.0, 0.2, 0.7, 1.2, 1.5}) {
      const double mu = std::cos(theta);
      const double expected = LayerSingleScatterRadiance(layer.tau, mu, layer.albedo, layer.g);
      const double got = layer.Bsdf(wi, Dir(theta, 0.4, -z_sign));
      EXPECT_NEAR(got, expected, 1e-13 * expected) << "theta=" << theta << " z=" << z_sign;
    }
  }
}

// Helmholtz reciprocity with refraction: f(wi -> wo) / n_o^2 = f(wo -> wi) / n_i^2.
// Eq. 3 and Eq. 6 are reciprocal on their own; Eq. 4 is not (Gu keep "mirror, then scatter"
// but not its reverse "scatter, then mirror"), so the whole BRDF is reciprocal only when the
// far face does not reflect (n2 = n3 on a semi-infinite glass lit from the air, n2 = n1 lit
// from the glass).
TEST(DirtyGlassLayer, Reciprocity) {
  const double n3 = 1.52;
  for (bool slab : {false, true}) {
    for (double n2 : {1.0, 1.33, 1.52, 1.7}) {
      const DirtyGlassLayer<double> layer = Layer(0.3, 0.8, 0.6, n2, n3, slab);
      SCOPED_TRACE(layer.ToString());
      const double n_below = slab ? 1.0 : n3;
      for (double ti : {0.1, 0.6, 1.2}) {
        for (double to : {0.3, 0.9, 1.4}) {
          for (double zi : {1.0, -1.0}) {
            const Vec3 wi = Dir(ti, 0.0, zi);
            // Transmission.
            const Vec3 wt = Dir(to, 2.5, -zi);
            const double n_i = zi > 0 ? 1.0 : n_below, n_t = zi > 0 ? n_below : 1.0;
            const double f_fwd = layer.Bsdf(wi, wt), f_rev = layer.Bsdf(wt, wi);
            EXPECT_NEAR(f_fwd / Sqr(n_t), f_rev / Sqr(n_i), 1e-12 * (f_fwd + 1e-300))
                << "ti=" << ti << " to=" << to << " zi=" << zi;
            // Reflection, Eq. 3 alone.
            const Vec3 wr = Dir(to, 2.5, zi);
            EXPECT_NEAR(layer.Diffuse(wi, wr).scatter_incident,
                        layer.Diffuse(wr, wi).scatter_incident, 1e-12);
            const bool far_face_matched = zi > 0 ? (!slab && n2 == n3) : n2 == 1.0;
            if (far_face_matched) {
              EXPECT_NEAR(layer.Bsdf(wi, wr), layer.Bsdf(wr, wi), 1e-12);
            }
          }
        }
      }
    }
  }
}

// Energy: with albedo 1 and any incidence, mirror + unscattered transmission + single-scatter
// flux on both sides stays <= 1 (the model drops light, it never creates it), and for a
// vanishing layer the specular terms alone reach the clean-glass first-order sum.
TEST(DirtyGlassLayer, EnergyBound) {
  for (bool slab : {false, true}) {
    for (double tau : {0.05, 0.5, 2.0}) {
      for (double g : {0.0, 0.8}) {
        const DirtyGlassLayer<double> layer = Layer(tau, 1.0, g, 1.4, 1.52, slab);
        for (double theta : {0.0, 0.8, 1.3}) {
          for (double zi : {1.0, -1.0}) {
            const Vec3 wi = Dir(theta, 0.0, zi);
            const DirtyGlassLayerSpecular<double> spec = layer.Specular(wi);
            double up = 0, down = 0;
            IntegrateDiffuse(layer, wi, &up, &down);
            const double total = spec.reflectance + spec.transmittance + up + down;
            EXPECT_LE(total, 1.0 + 2e-3) << layer.ToString() << " theta=" << theta << " zi=" << zi;
            EXPECT_GE(up, 0.0);
            EXPECT_GE(down, 0.0);
          }
        }
      }
    }
  }
}

// tau = 0: no scattering; with one effective interface (n2 = n1 or n2 = n3) the mirror term
// is the Fresnel reflectance of that interface and the transmitted term is 1 - F. With two
// interfaces, Eqs. 1, 2, 5 keep one pass: 1 - R - T is exactly the first neglected path,
// T12 F23 F21 (once in, mirrored at glass, mirrored back at the air face).
TEST(DirtyGlassLayer, FresnelConsistencyAtZeroTau) {
  const double n3 = 1.52;
  for (double theta : {0.0, 0.5, 1.0, 1.4}) {
    const double c = std::cos(theta);
    const Vec3 wi = Dir(theta, 0.0, 1.0);
    const double f13 = FresnelDielectricWalterEq22(c, n3);  // Independent form.
    for (double n2 : {1.0, n3}) {
      const DirtyGlassLayer<double> layer = Layer(0.0, 0.7, 0.5, n2, n3);
      const DirtyGlassLayerSpecular<double> spec = layer.Specular(wi);
      EXPECT_NEAR(spec.reflectance, f13, 1e-12) << "n2=" << n2 << " theta=" << theta;
      EXPECT_NEAR(spec.transmittance, 1.0 - f13, 1e-12);
      EXPECT_EQ(layer.Bsdf(wi, Dir(0.3, 1.0, 1.0)), 0.0);
      EXPECT_EQ(layer.Bsdf(wi, Dir(0.3, 1.0, -1.0)), 0.0);
      // Snell: n1 sin(theta_i) = n3 sin(theta_t).
      const Vec3& wt = spec.transmitted_dir;
      EXPECT_NEAR(n3 * std::hypot(wt.x(), wt.y()), std::sin(theta), 1e-12);
      EXPECT_NEAR(wt.norm(), 1.0, 1e-12);
      EXPECT_LT(wt.z(), 0.0);
    }
    const double n2 = 1.33;
    const DirtyGlassLayer<double> layer = Layer(0.0, 0.7, 0.5, n2, n3);
    const DirtyGlassLayerSpecular<double> spec = layer.Specular(wi);
    const double f12 = FresnelDielectricWalterEq22(c, n2);
    const double c2 = std::sqrt(1 - Sqr(std::sin(theta) / n2));
    const double f23 = FresnelDielectricWalterEq22(c2, n3 / n2);
    EXPECT_NEAR(spec.reflectance, f12 + Sqr(1 - f12) * f23, 1e-12);
    EXPECT_NEAR(1.0 - spec.reflectance - spec.transmittance, (1 - f12) * f23 * f12, 1e-12);
    // Thin slab, n2 = n3: Appendix F23 + T23 T32 F31 with F23 = 0, times T31 on the way out.
    const DirtyGlassLayer<double> slab = Layer(0.0, 0.7, 0.5, n3, n3, true);
    const DirtyGlassLayerSpecular<double> s = slab.Specular(wi);
    EXPECT_NEAR(s.reflectance, f13 + Sqr(1 - f13) * f13, 1e-12);
    EXPECT_NEAR(s.transmittance, Sqr(1 - f13), 1e-12);
    EXPECT_NEAR((s.transmitted_dir + wi).norm(), 0.0, 1e-12);  // Parallel faces: undeviated.
  }
}

// From the glass side beyond the critical angle of a lower-index layer, nothing enters the
// layer: total reflection, no transmission, no scattering.
TEST(DirtyGlassLayer, TotalInternalReflectionFromGlass) {
  const DirtyGlassLayer<double> layer = Layer(0.2, 0.9, 0.5, 1.33, 1.52);
  const double theta_c = std::asin(1.33 / 1.52);
  const Vec3 wi = Dir(theta_c + 0.05, 0.0, -1.0);
  const DirtyGlassLayerSpecular<double> spec = layer.Specular(wi);
  EXPECT_EQ(spec.reflectance, 1.0);
  EXPECT_EQ(spec.transmittance, 0.0);
  EXPECT_EQ(layer.Bsdf(wi, Dir(0.2, 0.0, 1.0)), 0.0);
  EXPECT_EQ(layer.Bsdf(wi, Dir(0.2, 0.0, -1.0)), 0.0);
  // Just inside it light enters and scatters, but cannot leave into air (n3 sin > n1): the
  // air face reflects it totally, so only attenuation keeps the mirror term below 1.
  const Vec3 wi_in = Dir(theta_c - 0.05, 0.0, -1.0);
  const DirtyGlassLayerSpecular<double> spec_in = layer.Specular(wi_in);
  EXPECT_EQ(spec_in.transmittance, 0.0);
  EXPECT_LT(spec_in.reflectance, 1.0);
  EXPECT_GT(layer.Bsdf(wi_in, Dir(0.2, 0.0, -1.0)), 0.0);
  // Below the air critical angle it is transmitted.
  EXPECT_GT(layer.Specular(Dir(std::asin(1 / 1.52) - 0.05, 0.0, -1.0)).transmittance, 0.0);
}

// The printed radiometry of Eqs. 3, 4, 6 differs from the flux-consistent form by exactly
// (n2 / n_out)^2 mu'_i / mu_i; both agree for an index-matched layer.
TEST(DirtyGlassLayer, PrintedRadiometryFactor) {
  DirtyGlassLayer<double> consistent = Layer(0.2, 0.5, 0.6, 1.4, 1.52);
  DirtyGlassLayer<double> printed = consistent;
  printed.as_printed = true;
  const double theta = 0.9;
  const Vec3 wi = Dir(theta, 0.0, 1.0);
  const double mu_i = std::cos(theta), mu_l = std::sqrt(1 - Sqr(std::sin(theta) / 1.4));
  const Vec3 wr = Dir(0.4, 2.0, 1.0), wt = Dir(0.4, 2.0, -1.0);
  EXPECT_NEAR(printed.Bsdf(wi, wr) / consistent.Bsdf(wi, wr), Sqr(1.4) * mu_l / mu_i, 1e-12);
  EXPECT_NEAR(printed.Bsdf(wi, wt) / consistent.Bsdf(wi, wt), Sqr(1.4 / 1.52) * mu_l / mu_i,
              1e-12);
  DirtyGlassLayer<double> matched = Layer(0.2, 0.5, 0.6, 1.0, 1.0);
  DirtyGlassLayer<double> matched_printed = matched;
  matched_printed.as_printed = true;
  EXPECT_NEAR(matched_printed.Bsdf(wi, wt), matched.Bsdf(wi, wt), 1e-14);
}

// Templated on T for Ceres.
TEST(DirtyGlassLayer, JetDerivative) {
  using Jet = ceres::Jet<double, 1>;
  using JVec3 = Eigen::Matrix<Jet, 3, 1>;
  DirtyGlassLayer<Jet> layer;
  layer.tau = Jet(0.25, 0);
  layer.n2 = Jet(1.4);
  layer.n3 = Jet(1.52);
  const Vec3 wi = Dir(0.5, 0.0, 1.0), wo = Dir(0.7, 2.0, 1.0);
  const Jet f = layer.Bsdf(wi.cast<Jet>(), wo.cast<Jet>());
  const JVec3 wi_j = wi.cast<Jet>();
  (void)layer.Specular(wi_j);
  DirtyGlassLayer<double> plus = Layer(0.25 + 1e-6, 0.3, 0.8, 1.4, 1.52);
  DirtyGlassLayer<double> minus = Layer(0.25 - 1e-6, 0.3, 0.8, 1.4, 1.52);
  const double fd = (plus.Bsdf(wi, wo) - minus.Bsdf(wi, wo)) / 2e-6;
  EXPECT_NEAR(f.v[0], fd, 1e-6 * std::abs(fd));
}

}  // namespace
}  // namespace thinslab
