// SPDX-License-Identifier: Apache-2.0
// Microfacet normal distributions D(m), Smith masking G1 / Lambda, and sampling of microfacet
// normals proportionally to D(m) |m . n|, after Walter, Marschner, Li and Torrance 2007,
// "Microfacet Models for Refraction through Rough Surfaces" (Sec. 5.2), with the anisotropic
// forms and Lambda of Heitz 2014, "Understanding the Masking-Shadowing Function in
// Microfacet-Based BRDFs" (Sec. 5). The seed text of Walter et al. is garbled; the formulas
// here are the published ones.
//
// Local shading frame: the macro-surface normal is n = +z, tangents x and y; every direction
// is a unit vector. Microfacet normals m have m.z > 0. Roughnesses alpha are unitless (alpha is
// the RMS-slope-like width of Walter's Beckmann and GGX forms; alpha_x, alpha_y along x, y).
// Models are templated on T so that Ceres Jets can differentiate D, Lambda and G with respect
// to alpha; sampling takes double uniforms.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "thinslab/core/math.h"

namespace thinslab {

template <typename T>
using Vector3T = Eigen::Matrix<T, 3, 1>;

// One fitted/printed parameter of an optics model: name, bounds and unit ("1" = unitless).
struct ModelParameter {
  const char* name;
  double min;
  double max;
  const char* unit;
};

// Largest roughness the models are documented for (Walter et al. fit alpha <= ~0.5 for
// ground glass; beyond ~2 the single-scattering Smith model loses most of the energy).
constexpr double kMinMicrofacetAlpha = 1e-3;
constexpr double kMaxMicrofacetAlpha = 2.0;

// chi^+(a): 1 for a > 0, else 0 (Walter et al. 2007, Sec. 5.2, the positive characteristic
// function).
template <typename T>
T ChiPlus(const T& a) {
  return a > T(0) ? T(1) : T(0);
}

// alpha^2 tan^2(theta_w) seen along direction w for an anisotropic roughness (alpha_x,
// alpha_y): (alpha_x^2 w_x^2 + alpha_y^2 w_y^2) / w_z^2, i.e. the projected roughness
// alpha(phi_w)^2 = alpha_x^2 cos^2 phi_w + alpha_y^2 sin^2 phi_w times tan^2 theta_w (Heitz 2014,
// Sec. 5.2).
template <typename T>
T AlphaTan2(const Vector3T<T>& w, const T& alpha_x, const T& alpha_y) {
  return (Sqr(alpha_x * w.x()) + Sqr(alpha_y * w.y())) / Sqr(w.z());
}

// Shared Smith machinery for a distribution with D(m) and Lambda(w) (CRTP).
template <typename Derived, typename T>
struct SmithMicrofacetDistribution {
  // Smith masking of the microfacet m seen from w: chi^+((w . m) / (w . n)) / (1 + Lambda(w))
  // (Heitz 2014, Sec. 5; equal to Walter et al. 2007, Eq. 34 for GGX and Eq. 26 for Beckmann).
  T G1(const Vector3T<T>& w, const Vector3T<T>& wm) const {
    if (w.z() == T(0)) return T(0);
    return ChiPlus(T(w.dot(wm) / w.z())) / (T(1) + Self().Lambda(w));
  }

  // Walter et al. 2007, Eq. 23: separable shadowing-masking G(i, o, m) = G1(i, m) G1(o, m).
  // This is the G the rough dielectric (optics/walter_btdf.h) uses.
  T G(const Vector3T<T>& wi, const Vector3T<T>& wo, const Vector3T<T>& wm) const { return G1(wi, wm) * G1(wo, wm); }

  // Not in Walter et al.: height-correlated Smith G2 for reflection (wi, wo on the same side),
  // chi^+ chi^+ / (1 + Lambda(wi) + Lambda(wo)) (Heitz 2014, Sec. 6). Lies between
  // G1(wi) G1(wo) and min(G1(wi), G1(wo)). For transmission Heitz's height-correlated form is a
  // Beta function and is not provided.
  T GHeightCorrelatedReflection(const Vector3T<T>& wi, const Vector3T<T>& wo, const Vector3T<T>& wm) const {
    if (wi.z() == T(0) || wo.z() == T(0)) return T(0);
    const T chi = ChiPlus(T(wi.dot(wm) / wi.z())) * ChiPlus(T(wo.dot(wm) / wo.z()));
    return chi / (T(1) + Self().Lambda(wi) + Self().Lambda(wo));
  }

  // Density of Sample() over solid angle of m: D(m) |m . n| (Walter et al. 2007, Sec. 5.3,
  // p_m(m) = D(m) |m . n|).
  T Pdf(const Vector3T<T>& wm) const {
    using std::abs;
    return Self().D(wm) * abs(wm.z());
  }

 private:
  const Derived& Self() const { return static_cast<const Derived&>(*this); }
};

// Trowbridge-Reitz / GGX. Isotropic D is Walter et al. 2007, Eq. 33; anisotropic is the
// stretched form (Heitz 2014, Sec. 5).
template <typename T>
struct GgxDistributionT : SmithMicrofacetDistribution<GgxDistributionT<T>, T> {
  using Scalar = T;
  T alpha_x;  // Roughness along x (unitless, (0, ~2]).
  T alpha_y;  // Roughness along y (unitless, (0, ~2]).

  explicit GgxDistributionT(T alpha) : alpha_x(alpha), alpha_y(alpha) {}
  GgxDistributionT(T ax, T ay) : alpha_x(ax), alpha_y(ay) {}

  // D(m) = chi^+(m . n) / (pi alpha_x alpha_y cos^4 theta_m (1 + tan^2 theta_m (cos^2 phi_m /
  // alpha_x^2 + sin^2 phi_m / alpha_y^2))^2); for alpha_x = alpha_y = alpha this is Walter Eq. 33,
  // alpha^2 chi^+ / (pi cos^4 theta_m (alpha^2 + tan^2 theta_m)^2). Written in Cartesian form
  // (cos^4 theta (1 + tan^2 ...)^2 = (m_x^2 / alpha_x^2 + m_y^2 / alpha_y^2 + m_z^2)^2 for |m| = 1).
  T D(const Vector3T<T>& wm) const {
    if (wm.z() <= T(0)) return T(0);
    const T s = Sqr(wm.x() / alpha_x) + Sqr(wm.y() / alpha_y) + Sqr(wm.z());
    return T(kInvPi) / (alpha_x * alpha_y * s * s);
  }

  // Lambda(w) = (-1 + sqrt(1 + alpha^2 tan^2 theta_w)) / 2 (Heitz 2014, Sec. 5), so that
  // 1 / (1 + Lambda) = 2 / (1 + sqrt(1 + alpha^2 tan^2 theta_w)) is Walter Eq. 34. Evaluated as
  // a / (2 (1 + sqrt(1 + a))), a = alpha^2 tan^2 theta_w, to avoid cancellation near the normal.
  T Lambda(const Vector3T<T>& w) const {
    using std::sqrt;
    if (w.z() == T(0)) return T(HUGE_VAL);
    const T a = AlphaTan2(w, alpha_x, alpha_y);
    return a / (T(2) * (T(1) + sqrt(T(1) + a)));
  }

  // Microfacet normal with density D(m) m.z from uniforms u1, u2 in [0, 1). Walter et al.
  // 2007, Eqs. 35-36: theta_m = atan(alpha sqrt(u1 / (1 - u1))), phi_m = 2 pi u2. Anisotropic
  // by stretching the unit-roughness slope (tan theta_m cos phi_m, tan theta_m sin phi_m) by
  // (alpha_x, alpha_y) (Heitz 2014, Sec. 5: slope densities of stretched distributions), which
  // reduces to Eqs. 35-36 when alpha_x = alpha_y.
  Vector3T<T> Sample(double u1, double u2) const {
    const double tan_theta_unit = std::sqrt(u1 / (1.0 - u1));
    const double phi = 2.0 * kPi * u2;
    const Vector3T<T> wm(alpha_x * tan_theta_unit * std::cos(phi), alpha_y * tan_theta_unit * std::sin(phi), T(1));
    return wm / wm.norm();
  }

  std::string ToString() const {
    std::ostringstream out;
    out << "GgxDistribution(alpha_x=" << alpha_x << ", alpha_y=" << alpha_y << ")";
    return out.str();
  }

  static std::vector<ModelParameter> Params() {
    return {{"alpha_x", kMinMicrofacetAlpha, kMaxMicrofacetAlpha, "1"},
            {"alpha_y", kMinMicrofacetAlpha, kMaxMicrofacetAlpha, "1"}};
  }
};
using GgxDistribution = GgxDistributionT<double>;

// Beckmann. Isotropic D is Walter et al. 2007, Eq. 25; anisotropic is the stretched form
// (Heitz 2014, Sec. 5).
template <typename T>
struct BeckmannDistributionT : SmithMicrofacetDistribution<BeckmannDistributionT<T>, T> {
  using Scalar = T;
  T alpha_x;  // Roughness (RMS slope) along x (unitless, (0, ~2]).
  T alpha_y;  // Roughness (RMS slope) along y (unitless, (0, ~2]).

  explicit BeckmannDistributionT(T alpha) : alpha_x(alpha), alpha_y(alpha) {}
  BeckmannDistributionT(T ax, T ay) : alpha_x(ax), alpha_y(ay) {}

  // D(m) = chi^+(m . n) exp(-tan^2 theta_m (cos^2 phi_m / alpha_x^2 + sin^2 phi_m / alpha_y^2)) /
  // (pi alpha_x alpha_y cos^4 theta_m); for alpha_x = alpha_y it is Walter Eq. 25.
  T D(const Vector3T<T>& wm) const {
    using std::exp;
    if (wm.z() <= T(0)) return T(0);
    const T cos2 = Sqr(wm.z());
    const T e = (Sqr(wm.x() / alpha_x) + Sqr(wm.y() / alpha_y)) / cos2;
    return exp(-e) * T(kInvPi) / (alpha_x * alpha_y * cos2 * cos2);
  }

  // Exact Smith Lambda of the Beckmann distribution (Heitz 2014, Sec. 5):
  //   Lambda = (erf(a) - 1) / 2 + exp(-a^2) / (2 a sqrt(pi)),  a = 1 / (alpha tan theta_w),
  // so that 1 / (1 + Lambda) is Walter Eq. 26. Walter's rational approximation (Eq. 27) is not
  // used. Written with erfc(a) = 1 - erf(a) so that it stays accurate for large a.
  T Lambda(const Vector3T<T>& w) const {
    using std::erfc;
    using std::exp;
    using std::sqrt;
    if (w.z() == T(0)) return T(HUGE_VAL);
    const T alpha_tan2 = AlphaTan2(w, alpha_x, alpha_y);
    if (alpha_tan2 <= T(0)) return T(0);
    const T a = T(1) / sqrt(alpha_tan2);
    return (exp(-a * a) / (a * T(std::sqrt(kPi))) - erfc(a)) / T(2);
  }

  // Walter et al. 2007, Eqs. 28-29: theta_m = atan(sqrt(-alpha^2 ln(1 - u1))), phi_m = 2 pi u2;
  // anisotropic by stretching the unit-roughness slope, as for GGX.
  Vector3T<T> Sample(double u1, double u2) const {
    const double tan_theta_unit = std::sqrt(-std::log1p(-u1));
    const double phi = 2.0 * kPi * u2;
    const Vector3T<T> wm(alpha_x * tan_theta_unit * std::cos(phi), alpha_y * tan_theta_unit * std::sin(phi), T(1));
    return wm / wm.norm();
  }

  std::string ToString() const {
    std::ostringstream out;
    out << "BeckmannDistribution(alpha_x=" << alpha_x << ", alpha_y=" << alpha_y << ")";
    return out.str();
  }

  static std::vector<ModelParameter> Params() {
    return {{"alpha_x", kMinMicrofacetAlpha, kMaxMicrofacetAlpha, "1"},
            {"alpha_y", kMinMicrofacetAlpha, kMaxMicrofacetAlpha, "1"}};
  }
};
using BeckmannDistribution = BeckmannDistributionT<double>;

// Walter et al. 2007, Sec. 5.2: the Phong exponent that matches a Beckmann roughness,
// alpha_p = 2 alpha_b^-2 - 2 (and back, alpha_b = sqrt(2 / (alpha_p + 2))).
template <typename T>
T PhongExponentFromBeckmannAlpha(const T& alpha_b) {
  return T(2) / (alpha_b * alpha_b) - T(2);
}
template <typename T>
T BeckmannAlphaFromPhongExponent(const T& alpha_p) {
  using std::sqrt;
  return sqrt(T(2) / (alpha_p + T(2)));
}

// Isotropic Phong (Blinn) distribution, Walter et al. 2007, Eq. 30:
//   D(m) = chi^+(m . n) (alpha_p + 2) / (2 pi) cos^alpha_p theta_m.
// The Phong NDF has no closed-form Smith Lambda; as Walter suggests, Lambda / G1 are those of
// the Beckmann distribution with alpha_b = sqrt(2 / (alpha_p + 2)) (Walter uses the rational
// approximation of Eq. 27 for it; here the exact Beckmann erf form). Approximation: the
// projected-area identity of G1 holds only approximately (to ~1e-2 at alpha_p = 10).
template <typename T>
struct PhongDistributionT : SmithMicrofacetDistribution<PhongDistributionT<T>, T> {
  using Scalar = T;
  T alpha_p;  // Phong exponent (unitless, >= 0; larger is smoother).

  explicit PhongDistributionT(T exponent) : alpha_p(exponent) {}

  T D(const Vector3T<T>& wm) const {
    using std::pow;
    if (wm.z() <= T(0)) return T(0);
    return (alpha_p + T(2)) * T(kInv2Pi) * pow(wm.z(), alpha_p);
  }

  T Lambda(const Vector3T<T>& w) const {
    const T alpha_b = BeckmannAlphaFromPhongExponent(alpha_p);
    return BeckmannDistributionT<T>(alpha_b).Lambda(w);
  }

  // Walter et al. 2007, Sec. 5.2 (Phong sampling): theta_m = acos(u1^(1 / (alpha_p + 2))),
  // phi_m = 2 pi u2; then the density is D(m) cos theta_m.
  Vector3T<T> Sample(double u1, double u2) const {
    using std::pow;
    using std::sqrt;
    // 1 - u1 is uniform in (0, 1], so cos theta_m > 0.
    const T cos_theta = pow(T(1.0 - u1), T(1) / (alpha_p + T(2)));
    const T sin_theta = sqrt(std::max(T(0), T(1) - cos_theta * cos_theta));
    const double phi = 2.0 * kPi * u2;
    return Vector3T<T>(sin_theta * std::cos(phi), sin_theta * std::sin(phi), cos_theta);
  }

  std::string ToString() const {
    std::ostringstream out;
    out << "PhongDistribution(alpha_p=" << alpha_p << ")";
    return out.str();
  }

  static std::vector<ModelParameter> Params() { return {{"alpha_p", 0.0, 2.0e6, "1"}}; }
};
using PhongDistribution = PhongDistributionT<double>;

}  // namespace thinslab
