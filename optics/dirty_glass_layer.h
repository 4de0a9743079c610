// SPDX-License-Identifier: Apache-2.0
// The full contaminant-layer BRDF/BTDF of Gu, Ramamoorthi, Belhumeur and Nayar 2007, "Dirty
// Glass: Rendering Contamination on Transparent Surfaces" (EGSR 2007), Sec. 3.1 Eqs. 1-6 and
// the Appendix: a single-scattering layer (optical thickness tau, albedo omega0, HG g, index
// n2) between air (n1, the +z side, normal N = +z) and glass (n3, the -z side), for any
// incident direction, with exact unpolarised Fresnel at both interfaces. optics/dirty_glass.h
// is the special case n1 = n2 = n3, normal incidence.
//
// Conventions (docs/conventions.md, docs/models/dirty_glass_layer.md):
// - wi, wo are unit vectors pointing away from the surface, in the medium they live in: air
//   for z > 0; for z < 0 glass (n3), or air below the slab when thin_slab is set.
// - Diffuse values are BSDF values [1/sr], cosine excluded: the radiance leaving along wo per
//   unit irradiance on the surface from wi (the paper's "divide by L_i mu_i").
// - The specular (delta) terms are returned as flux fractions: the share of the incident power
//   leaving in the mirror direction (Eqs. 1 + 2) or in the refracted direction (Eq. 5). As a
//   radiance ratio the transmitted one carries (n_out / n_in)^2 (conventions.md, Radiometry).
// - Scattering angles are between propagation directions inside the layer (the paper's
//   p(pi - theta'_i - theta'_r), p(theta'_i - theta'_r), p(theta'_i - theta'_t) are the
//   in-plane special cases); refracted cosines mu' follow Snell, n sin(theta) conserved.
//
// Radiometry. Eqs. 3, 4, 6 as printed (copied from Hanrahan and Krueger 1993) carry mu'_i /
// mu_i and no interface radiance factor. A collimated beam of surface irradiance E refracted
// into the layer has beam-normal irradiance T12 E / mu'_i, and radiance leaving the layer into
// a medium of index n_out is scaled by (n_out / n2)^2, so the single-scatter BSDF is
//   Eq. 3: f = T_in T_out (n_out/n2)^2 omega0 p (1 - e^{-tau (1/mu'_i + 1/mu'_r)}) / (mu'_i + mu'_r)
// (and likewise for Eqs. 4, 6). This is the default; it is reciprocal and matches
// sim/layer_path_tracer within MC noise. `as_printed = true` multiplies the diffuse terms by
// (n2/n_out)^2 mu'_i / mu_i to give the printed equations; both agree when n1 = n2 = n3.
#pragma once

#include <Eigen/Core>
#include <cmath>
#include <sstream>
#include <string>
#include <type_traits>

#include "thinslab/core/math.h"
#include "thinslab/optics/fresnel.h"
#include "thinslab/optics/henyey_greenstein.h"
#include "thinslab/optics/thin_slab.h"

namespace thinslab {

template <typename T>
struct DirtyGlassLayerSpecular {
  // Eqs. 1 + 2 (Appendix first term for wi from the glass): flux fraction mirror-reflected.
  T reflectance = T(0);
  // Eq. 5 (Appendix first BTDF term): flux fraction transmitted unscattered along
  // transmitted_dir; 0 (and transmitted_dir zero) under total internal reflection.
  T transmittance = T(0);
  Eigen::Matrix<T, 3, 1> transmitted_dir = Eigen::Matrix<T, 3, 1>::Zero();
};

template <typename T>
struct DirtyGlassLayerDiffuse {
  T scatter_incident = T(0);  // Eq. 3 (reflection) or Eq. 6 (transmission) [1/sr].
  T scatter_mirrored = T(0);  // Eq. 4: scattering of the beam mirrored at the far side [1/sr].
  T Total() const { return scatter_incident + scatter_mirrored; }
};

template <typename T>
struct DirtyGlassLayer {
  using Vec3 = Eigen::Matrix<T, 3, 1>;

  T tau = T(0.1);     // Optical thickness of the layer, unitless, >= 0.
  T albedo = T(0.3);  // Single-scattering albedo omega0, unitless [0, 1].
  T g = T(0.8);       // HG mean cosine, unitless (-1, 1).
  T n1 = T(1.0);      // Air (z > 0), unitless refractive index.
  T n2 = T(1.5);      // Contaminant layer.
  T n3 = T(1.5);      // Glass (z < 0).
  // Appendix "thin transparent slab": the glass has a parallel back face to air (n1); F23
  // becomes F23 + T23 T32 F31 in Eqs. 2 and 4, BTDF terms gain T31, and -z directions are in
  // the air below the slab. Light from below (wi.z < 0) is handled the same way (the back
  // face first: F31 + T31 T13 (...), T13 on entry), which the paper does not spell out.
  bool thin_slab = false;
  bool as_printed = false;  // Printed radiometry of Eqs. 3, 4, 6 (see file comment).

  std::string ToString() const {
    std::ostringstream os;
    os << "DirtyGlassLayer{tau=" << ScalarValue(tau) << ", albedo=" << ScalarValue(albedo)
       << ", g=" << ScalarValue(g) << ", n1=" << ScalarValue(n1) << ", n2=" << ScalarValue(n2)
       << ", n3=" << ScalarValue(n3) << ", thin_slab=" << thin_slab << ", as_printed=" << as_printed
       << "}";
    return os.str();
  }

  // Unscattered terms for light from wi.
  DirtyGlassLayerSpecular<T> Specular(const Vec3& wi) const {
    using std::exp;
    DirtyGlassLayerSpecular<T> out;
    const Side a = SideOf(wi), b = Other(a);
    const T k = InvariantOf(wi, a);  // n sin(theta), conserved through the stack.
    const T entry_outer_f = OuterReflectance(a, k);
    const T t_a = SideTransmittance(a, k);
    const T mu_l = LayerCos(k);
    if (mu_l <= T(0)) {  // The beam cannot enter the layer (TIR at an inner face).
      out.reflectance = entry_outer_f + (T(1) - entry_outer_f) * InnerReflectanceFromOutside(a, k);
      return out;
    }
    const T att = exp(-tau / mu_l);
    // Eq. 1 (F12) + Eq. 2 (T12 T21 F23 e^{-tau (1/mu'_i + 1/mu'_r)}, mu'_r = mu'_i); Appendix:
    // F23 + T32 T23 F12 e^{...} from the glass; thin slab: F23 -> F23 + T23 T32 F31 and the
    // back face in front when lit from below.
    out.reflectance = entry_outer_f + (T(1) - entry_outer_f) * InnerReflectanceFromOutside(a, k) +
                      t_a * t_a * FarReflectance(b, k) * att * att;
    // Eq. 5: T12 T23 e^{-tau / mu'_i}; thin slab: times T31 (Appendix).
    out.transmittance = t_a * SideTransmittance(b, k) * att;
    const T mu_b = OuterCos(b, k);
    if (mu_b > T(0) && out.transmittance > T(0)) {
      const T scale = OuterIndex(a) / OuterIndex(b);  // Snell: tangential part n_a / n_b.
      out.transmitted_dir = Vec3(-scale * wi.x(), -scale * wi.y(), a == kTop ? -mu_b : mu_b);
    } else {
      out.transmittance = T(0);
    }
    return out;
  }

  // Single-scatter BRDF (wo on the side of wi) or BTDF (opposite side) [1/sr].
  DirtyGlassLayerDiffuse<T> Diffuse(const Vec3& wi, const Vec3& wo) const {
    using std::exp;
    using std::expm1;
    DirtyGlassLayerDiffuse<T> out;
    const Side a = SideOf(wi), o = SideOf(wo);
    const T k_i = InvariantOf(wi, a), k_o = InvariantOf(wo, o);
    const T mu_i = LayerCos(k_i), mu_o = LayerCos(k_o);  // mu'_i, mu'_r or mu'_t.
    if (mu_i <= T(0) || mu_o <= T(0)) return out;
    const T t_in = SideTransmittance(a, k_i), t_out = SideTransmittance(o, k_o);
    const T n_out = OuterIndex(o);
    // Radiance leaving the layer into n_out: (n_out / n2)^2 (conventions.md, Radiometry).
    T scale = t_in * t_out * Sqr(n_out / n2) * albedo;
    if (as_printed) scale *= Sqr(n2 / n_out) * mu_i / OuterCos(a, k_i);
    // Tangential parts of the propagation directions in the layer: -(n_a/n2) wi_xy for the
    // incident beam, (n_o/n2) wo_xy for the exit direction.
    const T xy = -(OuterIndex(a) * OuterIndex(o) / (n2 * n2)) *
                 (wi.x() * wo.x() + wi.y() * wo.y());
    const T e_i = exp(-tau / mu_i);
    if (o == a) {
      // Eq. 3: T12 T21 mu'_i / (mu'_i + mu'_r) (1 - e^{-tau (1/mu'_i + 1/mu'_r)}) omega0
      // p(pi - theta'_i - theta'_r) / mu_i, here per the file comment; the incident beam
      // goes away from side a, the exit direction towards it: cos = xy - mu'_i mu'_r.
      const T p3 = HenyeyGreenstein(xy - mu_i * mu_o, g);
      out.scatter_incident =
          scale * p3 * (-expm1(-tau * (T(1) / mu_i + T(1) / mu_o))) / (mu_i + mu_o);
      // Eq. 4: T12 T21 F23 mu'_i / (mu'_i - mu'_r) (e^{-tau/mu'_i} - e^{-tau/mu'_r})
      // e^{-tau/mu'_i} omega0 p(theta'_i - theta'_r) / mu_i: the beam mirrored at the far side
      // (F23, or F23 + T23 T32 F31 for the thin slab) travels towards side a.
      const T p4 = HenyeyGreenstein(xy + mu_i * mu_o, g);
      out.scatter_mirrored = scale * FarReflectance(Other(a), k_i) * p4 * e_i *
                             DiffExpOverDiff(mu_i, mu_o);
    } else {
      // Eq. 6: T12 T23 mu'_i / (mu'_i - mu'_t) (e^{-tau/mu'_i} - e^{-tau/mu'_t}) omega0
      // p(theta'_i - theta'_t) / mu_i; thin slab: times T31 (inside SideTransmittance).
      const T p6 = HenyeyGreenstein(xy + mu_i * mu_o, g);
      out.scatter_incident = scale * p6 * DiffExpOverDiff(mu_i, mu_o);
    }
    return out;
  }

  T Bsdf(const Vec3& wi, const Vec3& wo) const { return Diffuse(wi, wo).Total(); }

 private:
  enum Side { kTop, kBottom };
  static Side Other(Side s) { return s == kTop ? kBottom : kTop; }
  static Side SideOf(const Vec3& w) { return w.z() >= T(0) ? kTop : kBottom; }

  // Index of the medium a direction on side s lives in.
  T OuterIndex(Side s) const { return s == kTop ? n1 : (thin_slab ? n1 : n3); }
  // Index of the medium touching the layer on side s.
  T InnerIndex(Side s) const { return s == kTop ? n1 : n3; }
  bool HasBackFace(Side s) const { return s == kBottom && thin_slab; }

  T InvariantOf(const Vec3& w, Side s) const {
    using std::sqrt;
    return OuterIndex(s) * sqrt(w.x() * w.x() + w.y() * w.y());
  }
  // cos(theta) in a medium of index n for invariant k; 0 if the direction cannot exist there.
  static T CosIn(const T& k, const T& n) {
    using std::sqrt;
    const T s2 = Sqr(k / n);
    return s2 < T(1) ? sqrt(T(1) - s2) : T(0);
  }
  T LayerCos(const T& k) const { return CosIn(k, n2); }
  T OuterCos(Side s, const T& k) const { return CosIn(k, OuterIndex(s)); }

  // Fresnel reflectance between media n_from -> n_to for invariant k (symmetric in the
  // direction of travel when both cosines exist; 1 under TIR).
  static T Fr(const T& k, const T& n_from, const T& n_to) {
    const T c = CosIn(k, n_from);
    if (c <= T(0)) return T(1);
    return FresnelDielectric(c, n_to / n_from);
  }
  // Back face of the slab (air n1 / glass n3), or 0.
  T OuterReflectance(Side s, const T& k) const {
    return HasBackFace(s) ? Fr(k, n1, n3) : T(0);
  }
  // Transmittance from the outer medium of side s into the layer (or back; the same).
  T SideTransmittance(Side s, const T& k) const {
    T t = T(1) - Fr(k, InnerIndex(s), n2);
    if (HasBackFace(s)) t *= T(1) - Fr(k, n1, n3);  // Appendix: the extra T31.
    return t;
  }
  // Reflectance of the inner face of side s for light arriving from outside (after the back
  // face): F12 (Eq. 1), F32 (Appendix).
  T InnerReflectanceFromOutside(Side s, const T& k) const {
    const T f = Fr(k, InnerIndex(s), n2);
    if (!HasBackFace(s)) return f;
    // Thin slab lit from below: the F32 reflection leaves through the back face (T31).
    return f * (T(1) - Fr(k, n1, n3));
  }
  // Reflectance seen from inside the layer at side s, to first order: F23 (Eqs. 2, 4), F21
  // (Appendix), thin slab F23 + T23 T32 F31 (Appendix).
  T FarReflectance(Side s, const T& k) const {
    const T f = Fr(k, n2, InnerIndex(s));
    if (!HasBackFace(s)) return f;
    return f + Sqr(T(1) - f) * Fr(k, n3, n1);
  }
  // (e^{-tau/a} - e^{-tau/b}) / (a - b), stable at a = b (limit tau e^{-tau/a} / a^2).
  T DiffExpOverDiff(const T& a, const T& b) const {
    using std::exp;
    const T x = tau * (T(1) / b - T(1) / a);
    return tau * exp(-tau / b) * thin_slab_detail::ExpRel(x) / (a * b);
  }
};

}  // namespace thinslab
