// SPDX-License-Identifier: Apache-2.0
// Exact unpolarised Fresnel reflectance of a dielectric interface and Snell refraction of a
// direction, as used by the rough dielectric of Walter, Marschner, Li and Torrance 2007,
// "Microfacet Models for Refraction through Rough Surfaces" (Sec. 5.1, Eq. 22), and by pbrt-v4
// (FrDielectric, Refract). Directions point away from the surface (docs/conventions.md).
// eta = eta_t / eta_i is relative to the side the normal points to: light arriving from the
// side of n (cos_theta_i > 0) goes from index eta_i into index eta_t.
#pragma once

#include <Eigen/Core>
#include <cmath>

#include "thinslab/core/math.h"

namespace thinslab {

// Fresnel reflectance of unpolarised light, F = (r_parallel^2 + r_perpendicular^2) / 2.
// cos_theta_i = wi . n; a negative value means the light arrives from the other side, where
// the relative index is 1 / eta. Total internal reflection returns 1.
// Walter et al. 2007, Eq. 22 writes the same quantity as
//   F = (g - c)^2 / (2 (g + c)^2) (1 + (c (g + c) - 1)^2 / (c (g - c) + 1)^2),
//   c = |cos_theta_i|, g^2 = eta^2 - 1 + c^2 (TIR when g^2 < 0);
// the amplitude form below is equivalent and is what walter_btdf_test checks against Eq. 22.
template <typename T>
T FresnelDielectric(T cos_theta_i, T eta) {
  using std::sqrt;
  cos_theta_i = Clamp(cos_theta_i, T(-1), T(1));
  if (cos_theta_i < T(0)) {
    eta = T(1) / eta;
    cos_theta_i = -cos_theta_i;
  }
  // Snell: sin_theta_t = sin_theta_i / eta.
  const T sin2_theta_i = T(1) - cos_theta_i * cos_theta_i;
  const T sin2_theta_t = sin2_theta_i / (eta * eta);
  if (sin2_theta_t >= T(1)) return T(1);  // Total internal reflection.
  const T cos_theta_t = sqrt(T(1) - sin2_theta_t);
  const T r_parallel = (eta * cos_theta_i - cos_theta_t) / (eta * cos_theta_i + cos_theta_t);
  const T r_perpendicular = (cos_theta_i - eta * cos_theta_t) / (cos_theta_i + eta * cos_theta_t);
  return (r_parallel * r_parallel + r_perpendicular * r_perpendicular) / T(2);
}

// Walter et al. 2007, Eq. 22, literally (c = |cos_theta_i|, eta = eta_t / eta_i for the side
// the light comes from). Kept as an independent form for tests; FresnelDielectric is the one
// the models use.
template <typename T>
T FresnelDielectricWalterEq22(T cos_theta_i, T eta) {
  using std::abs;
  using std::sqrt;
  if (cos_theta_i < T(0)) eta = T(1) / eta;
  const T c = abs(cos_theta_i);
  const T g2 = eta * eta - T(1) + c * c;
  if (g2 <= T(0)) return T(1);  // Total internal reflection.
  const T g = sqrt(g2);
  const T a = (g - c) / (g + c);
  const T b = (c * (g + c) - T(1)) / (c * (g - c) + T(1));
  return T(0.5) * a * a * (T(1) + b * b);
}

// Snell refraction of wi (unit, pointing away from the surface) about the unit normal n.
// eta = eta_t / eta_i for light arriving from the side n points to; if wi . n < 0 the light
// arrives from the other side and the roles swap (n -> -n, eta -> 1 / eta). On success *wt
// is the unit transmitted direction, pointing away from the surface on the far side, with
// eta_i sin_theta_i = eta_t sin_theta_t. Returns false on total internal reflection.
template <typename T>
bool Refract(const Eigen::Matrix<T, 3, 1>& wi, Eigen::Matrix<T, 3, 1> n, T eta, Eigen::Matrix<T, 3, 1>* wt) {
  using std::sqrt;
  T cos_theta_i = wi.dot(n);
  if (cos_theta_i < T(0)) {
    eta = T(1) / eta;
    cos_theta_i = -cos_theta_i;
    n = -n;
  }
  const T sin2_theta_i = T(1) - cos_theta_i * cos_theta_i;
  const T sin2_theta_t = sin2_theta_i / (eta * eta);
  if (sin2_theta_t >= T(1)) return false;
  const T cos_theta_t = sqrt(T(1) - sin2_theta_t);
  // Tangential part -wi_tangent / eta, normal part -cos_theta_t n (Walter Eq. 40 with
  // c = wi . n > 0 and relative index 1 / eta).
  *wt = -wi / eta + (cos_theta_i / eta - cos_theta_t) * n;
  return true;
}

// Mirror reflection of wi about n (any orientation of n): wo = 2 (wi . n) n - wi
// (Walter et al. 2007, Eq. 39).
template <typename T>
Eigen::Matrix<T, 3, 1> Reflect(const Eigen::Matrix<T, 3, 1>& wi, const Eigen::Matrix<T, 3, 1>& n) {
  return T(2) * wi.dot(n) * n - wi;
}

}  // namespace thinslab
