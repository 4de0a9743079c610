// SPDX-License-Identifier: Apache-2.0
// The dual-microfacet BTDF of Dai, Wang, Liu, Snyder, Wu and Guo 2009, "The dual-microfacet
// model for capturing thin transparent slabs" (Sec. 3, Eqs. 4-11; Appendix Eqs. 23-26), and a
// tabulated normal distribution for it (Sec. 4.2 recovers D on a hemisphere grid).
//
// Geometry (docs/conventions.md): a thin slab of relative index eta > 1 in air, macro normal
// +z on the incident side. i (i.z > 0) and o (o.z < 0) point away from the surface. The slab
// is infinitely thin (Dai Sec. 3), so only directions matter. Two virtual configurations:
//   (c) rough top, flat bottom: i refracts at a top microfacet h_t into the internal direction
//       w = o_m / eta, which leaves through the flat bottom as o (rho_t, Eqs. 4-6);
//   (d) flat top, rough bottom: i refracts at the flat top into i' (written pointing back up,
//       away from the bottom face), then at a bottom microfacet h_b into o (rho_b, Eqs. 7-10).
// Eq. 11 interpolates ln rho between them. Values are radiance BTDFs without the cosine (pbrt
// f() convention); the two eta^2 factors of the two crossings (air -> slab -> air) cancel, so
// no net eta factor remains (docs/conventions.md, Radiometry), as derived next to Eq. 6 below.
#pragma once

#include <glog/logging.h>

#include <Eigen/Core>
#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

#include "thinslab/core/math.h"
#include "thinslab/optics/fresnel.h"
#include "thinslab/optics/microfacet.h"

namespace thinslab {

// A normal distribution D(m) tabulated on the orthographic projection of the hemisphere
// (the projection Dai et al. use to show their NDFs, Fig. 6): m = (x, y, sqrt(1 - x^2 - y^2)),
// (x, y) in the unit disk. The square [-1, 1]^2 is cut into N x N cells of side h = 2 / N;
// value (row, col) = values[row * N + col] is D at the cell centre (x_c, y_c) =
// (-1 + (col + 0.5) h, -1 + (row + 0.5) h). Lookup is bilinear between cell centres (clamped
// to the outermost centres); D = 0 for m.z <= 0. Because d omega = dx dy / m.z, the projected
// area normalisation integral of D (m . n) d omega = 1 (Dai Sec. 3) is the plain area
// integral of D over the disk; the constructors divide by that integral of the bilinear
// interpolant (midpoint rule with kNormSubsamples^2 points per cell, points outside the disk
// dropped).
class TabulatedNdf {
 public:
  using Scalar = double;
  static constexpr int kNormSubsamples = 8;

  // From raw cell values (any positive scale; they are renormalised). CHECKs the size.
  TabulatedNdf(int n, std::vector<double> values) : n_(n), values_(std::move(values)) {
    CHECK_GE(n_, 2);
    CHECK_EQ(static_cast<int>(values_.size()), n_ * n_);
    for (double v : values_) CHECK_GE(v, 0.0);
    const double integral = InterpolantIntegral();
    CHECK_GT(integral, 0.0);
    for (double& v : values_) v /= integral;
  }

  // Samples an analytic distribution (anything with D(Eigen::Vector3d)) at the cell centres;
  // centres outside the disk take D at the nearest point of radius 1 - 1e-9.
  template <typename Distribution>
  static TabulatedNdf FromDistribution(const Distribution& distribution, int n) {
    std::vector<double> values(n * n);
    for (int row = 0; row < n; ++row) {
      for (int col = 0; col < n; ++col) {
        double x = CellCentre(col, n), y = CellCentre(row, n);
        const double r = std::hypot(x, y);
        if (r > 1 - 1e-9) {
          x *= (1 - 1e-9) / r;
          y *= (1 - 1e-9) / r;
        }
        const Eigen::Vector3d m(x, y, std::sqrt(std::max(0.0, 1 - x * x - y * y)));
        values[row * n + col] = distribution.D(m);
      }
    }
    return TabulatedNdf(n, std::move(values));
  }

  int n() const { return n_; }
  const std::vector<double>& values() const { return values_; }

  double D(const Eigen::Vector3d& m) const {
    if (m.z() <= 0) return 0;
    return Interpolate(m.x(), m.y());
  }

 private:
  static double CellCentre(int idx, int n) { return -1 + (idx + 0.5) * 2.0 / n; }

  double At(int row, int col) const { return values_[row * n_ + col]; }

  double Interpolate(double x, double y) const {
    const double h = 2.0 / n_;
    const double u = Clamp((x + 1) / h - 0.5, 0.0, n_ - 1.0);
    const double v = Clamp((y + 1) / h - 0.5, 0.0, n_ - 1.0);
    const int c0 = std::min(static_cast<int>(u), n_ - 2), r0 = std::min(static_cast<int>(v), n_ - 2);
    const double fu = u - c0, fv = v - r0;
    return (1 - fv) * ((1 - fu) * At(r0, c0) + fu * At(r0, c0 + 1)) +
           fv * ((1 - fu) * At(r0 + 1, c0) + fu * At(r0 + 1, c0 + 1));
  }

  double InterpolantIntegral() const {
    const double h = 2.0 / n_, hs = h / kNormSubsamples;
    double sum = 0;
    const int m = n_ * kNormSubsamples;
    for (int j = 0; j < m; ++j) {
      const double y = -1 + (j + 0.5) * hs;
      for (int k = 0; k < m; ++k) {
        const double x = -1 + (k + 0.5) * hs;
        if (x * x + y * y < 1) sum += Interpolate(x, y);
      }
    }
    return sum * hs * hs;
  }

  int n_;
  std::vector<double> values_;
};

// The two virtual configurations and their interpolation. Ndf provides D(m) (analytic or
// TabulatedNdf); Shadowing provides the Smith G(i, o, m) of Walter et al. 2007, Eq. 23 (Dai
// Sec. 4.2 uses Smith with its own roughness). T is the scalar (double or a ceres::Jet for
// the analytic distributions).
template <typename Ndf, typename Shadowing = Ndf>
struct DualMicrofacetBtdf {
  using T = typename Shadowing::Scalar;
  using Vec = Vector3T<T>;

  Ndf ndf;
  Shadowing shadowing;
  T eta;  // Slab index over air, unitless, > 1 (Dai Eq. 2 assumes eta_G > eta_A).

  DualMicrofacetBtdf(Ndf d, Shadowing s, T eta_slab) : ndf(std::move(d)), shadowing(std::move(s)), eta(eta_slab) {
    CHECK_GT(ScalarValue(eta), 1.0);
  }

  // o_m = eta o' = (o_x, o_y, -sqrt(eta^2 - o_x^2 - o_y^2)) (Dai, below Eq. 4): eta times the
  // internal propagation direction that the flat bottom refracts into o (tangential momentum
  // eta w_xy = o_xy).
  Vec OutgoingMomentum(const Vec& o) const {
    using std::sqrt;
    return Vec(o.x(), o.y(), -sqrt(eta * eta - o.x() * o.x() - o.y() * o.y()));
  }

  // i_m = eta i' = (i_x, i_y, sqrt(eta^2 - i_x^2 - i_y^2)) (Dai Eq. 8).
  Vec IncidentMomentum(const Vec& i) const {
    using std::sqrt;
    return Vec(i.x(), i.y(), sqrt(eta * eta - i.x() * i.x() - i.y() * i.y()));
  }

  // Dai Eq. 4: h_t = -(i + o - |o - o_m| z+) / |i + o_m|. Here
  // o - o_m = (0, 0, o.z + sqrt(eta^2 - o_xy^2)) and that z is > 0 for eta > 1, so
  // |o - o_m| z+ = o - o_m and Eq. 4 is h_t = -(i + o_m) / |i + o_m|: Walter's transmission
  // half vector (Walter et al. 2007, Eq. 16 setting) for i -> o_m / eta. h_t.z > 0.
  Vec TopHalfVector(const Vec& i, const Vec& o) const {
    const Vec h = -(i + OutgoingMomentum(o));
    return h / h.norm();
  }

  // Dai Eq. 7: h_b = (i + o + |i - i_m| z+) / |o + i_m|; i - i_m has only a negative z, so
  // this is h_b = (i_m + o) / |i_m + o| (Walter's half vector for i' -> o at the bottom, eta
  // inside, 1 outside). h_b.z > 0.
  Vec BottomHalfVector(const Vec& i, const Vec& o) const {
    const Vec h = IncidentMomentum(i) + o;
    return h / h.norm();
  }

  // |d omega_ht / d omega_o|. Garbled in the seed text; using the geometric derivation: Eq. 23
  // chains Walter's Eq. 16 for i -> w = o_m / eta (Dai Eq. 25),
  //   |d omega_ht / d omega_w| = eta |o_m . h_t| / (i . h_t + o_m . h_t)^2,
  // with the flat-face etendue relation eta^2 |w.z| d omega_w = |o.z| d omega_o,
  //   |d omega_w / d omega_o| = |o.z| / (eta |o_m.z|)
  // (the seed's Eq. 26, |o . o_m| / eta^3, only agrees with this at normal exit), giving
  //   |d omega_ht / d omega_o| = |o.z| |o_m . h_t| / (|o_m.z| (i . h_t + o_m . h_t)^2)   (Eq. 5).
  // dual_microfacet_btdf_test checks it against finite differences.
  T TopJacobian(const Vec& i, const Vec& o) const {
    using std::abs;
    const Vec om = OutgoingMomentum(o);
    const Vec h = TopHalfVector(i, o);
    const T denom = i.dot(h) + om.dot(h);
    return abs(o.z()) * abs(om.dot(h)) / (abs(om.z()) * denom * denom);
  }

  // Dai Eq. 9: |d omega_hb / d omega_o| = |o . h_b| / (i_m . h_b + o . h_b)^2.
  T BottomJacobian(const Vec& i, const Vec& o) const {
    using std::abs;
    const Vec h = BottomHalfVector(i, o);
    const T denom = IncidentMomentum(i).dot(h) + o.dot(h);
    return abs(o.dot(h)) / (denom * denom);
  }

  // Dai Eq. 6: rho_t = J_t |i . h_t| F_t(i . h_t) F_t(w . z+) G D(h_t) / (|i . z| |o . z|), F_t
  // the Fresnel transmittance. This is exactly Walter's f_t(i, w) (eta^2 radiance gain) times
  // (1 - F_bottom) / eta^2 (radiance leaving the slab) after changing variables w -> o. G is
  // G1(i, h_t) G1(w, h_t) with w the internal direction: the seed writes G(i, o, h_t), but the
  // facet is on the top face and sees w, not o.
  T EvalTop(const Vec& i, const Vec& o) const {
    using std::abs;
    if (!(i.z() > T(0) && o.z() < T(0))) return T(0);
    const Vec h = TopHalfVector(i, o);
    const Vec w = OutgoingMomentum(o) / eta;
    const T i_dot_h = i.dot(h);
    if (!(i_dot_h > T(0)) || !(w.dot(h) < T(0))) return T(0);
    const T t_facet = T(1) - FresnelDielectric(i_dot_h, eta);
    const T t_flat = T(1) - FresnelDielectric(T(-w.z()), T(T(1) / eta));
    return TopJacobian(i, o) * i_dot_h * t_facet * t_flat * shadowing.G(i, w, h) * T(ndf.D(h)) /
           (abs(i.z()) * abs(o.z()));
  }

  // Dai Eq. 10: rho_b = J_b |i' . h_b| F_t(i' . h_b) F_t(i . z+) G D(h_b) / (|i' . z| |o . z|):
  // the flat top transmits (1 - F(i.z)) and multiplies radiance by eta^2, Walter's f_t at the
  // bottom (eta -> 1) has the 1/eta^2, and the incident solid angle maps as
  // |i.z| d omega_i = eta^2 |i'.z| d omega_i'; all eta factors cancel. G = G1(i', h_b) G1(o, h_b).
  T EvalBottom(const Vec& i, const Vec& o) const {
    using std::abs;
    if (!(i.z() > T(0) && o.z() < T(0))) return T(0);
    const Vec h = BottomHalfVector(i, o);
    const Vec ip = IncidentMomentum(i) / eta;
    const T ip_dot_h = ip.dot(h);
    if (!(ip_dot_h > T(0)) || !(o.dot(h) < T(0))) return T(0);
    const T t_facet = T(1) - FresnelDielectric(ip_dot_h, T(T(1) / eta));
    const T t_flat = T(1) - FresnelDielectric(i.z(), eta);
    return BottomJacobian(i, o) * ip_dot_h * t_facet * t_flat * shadowing.G(ip, o, h) * T(ndf.D(h)) /
           (abs(ip.z()) * abs(o.z()));
  }

  // Dai Eq. 11: ln rho = alpha ln rho_t + (1 - alpha) ln rho_b, alpha in [0, 1]. The endpoints
  // return rho_t or rho_b exactly (also where the other one is 0); inside, a zero factor gives 0.
  T Eval(const Vec& i, const Vec& o, T alpha) const {
    using std::exp;
    using std::log;
    if (alpha >= T(1)) return EvalTop(i, o);
    if (alpha <= T(0)) return EvalBottom(i, o);
    const T rho_t = EvalTop(i, o), rho_b = EvalBottom(i, o);
    if (!(rho_t > T(0)) || !(rho_b > T(0))) return T(0);
    return exp(alpha * log(rho_t) + (T(1) - alpha) * log(rho_b));
  }
};

template <typename Ndf, typename Shadowing>
DualMicrofacetBtdf<Ndf, Shadowing> MakeDualMicrofacetBtdf(Ndf ndf, Shadowing shadowing,
                                                          typename Shadowing::Scalar eta) {
  return DualMicrofacetBtdf<Ndf, Shadowing>(std::move(ndf), std::move(shadowing), eta);
}

}  // namespace thinslab
