// SPDX-License-Identifier: Apache-2.0
// Rough dielectric interface (reflection + transmission through one rough surface) of Walter,
// Marschner, Li and Torrance 2007, "Microfacet Models for Refraction through Rough Surfaces"
// (Secs. 4-5), for any distribution of optics/microfacet.h. Documented in
// docs/models/walter_microfacet.md.
//
// Conventions (docs/conventions.md): local frame with macro-normal n = +z; wi and wo are unit
// vectors that both point away from the surface (Walter's i and o; light arrives from wi and
// leaves along wo); BSDF values exclude the |cos theta_o| (or |cos theta_i|) factor.
// eta = eta_below / eta_above, the index on the -z side over the index on the +z side, so light
// arriving from above (wi.z > 0) has eta_i = 1, eta_o = eta (Walter's eta_i, eta_o up to a
// common scale, which cancels) and light arriving from below the swapped pair.
#pragma once

#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "thinslab/core/math.h"
#include "thinslab/optics/fresnel.h"
#include "thinslab/optics/microfacet.h"

namespace thinslab {

// One sample of the BSDF (Walter et al. 2007, Sec. 5.3).
template <typename T>
struct WalterBsdfSample {
  Vector3T<T> wo = Vector3T<T>::Zero();  // Sampled outgoing direction (unit, away from surface).
  T pdf = T(0);                          // Density of wo over solid angle [1/sr], from m (must equal Pdf(wi, wo)).
  T weight = T(0);                       // f(wi, wo) |wo . n| / pdf (Walter Eq. 41).
  bool is_reflection = false;
};

template <typename Distribution>
struct WalterRoughDielectric {
  using T = typename Distribution::Scalar;

  Distribution distribution;
  T eta;  // eta_below / eta_above (unitless, > 0 and != 1; e.g. 1.5 for glass below air).

  WalterRoughDielectric(const Distribution& dist, T eta_below_over_above)
      : distribution(dist), eta(eta_below_over_above) {}

  // Indices on the incident side and the other side of wi (only their ratio matters).
  void IncidentIndices(const Vector3T<T>& wi, T* eta_i, T* eta_o) const {
    const bool from_above = wi.z() > T(0);
    *eta_i = from_above ? T(1) : eta;
    *eta_o = from_above ? eta : T(1);
  }

  // Reflection half vector h_r = sign(i . n) (i + o) / |i + o| (Walter Eq. 13); it has h.z > 0
  // when wi and wo are on the same side. Returns false when it is undefined.
  static bool ReflectionHalfVector(const Vector3T<T>& wi, const Vector3T<T>& wo, Vector3T<T>* wm) {
    const Vector3T<T> h = wi + wo;
    const T norm = h.norm();
    if (!(norm > T(0))) return false;
    *wm = (wi.z() > T(0) ? T(1) : T(-1)) * h / norm;
    return true;
  }

  // Transmission half vector h_t = -(eta_i i + eta_o o) / |eta_i i + eta_o o| (Walter Eq. 16),
  // flipped to h.z > 0 (D(m) is defined on the upper hemisphere; the BSDF uses |i . h|, |o . h|
  // and the square of eta_i (i . h) + eta_o (o . h), which the flip leaves unchanged). Returns
  // false when it is undefined or when the microfacet would face away from wi or wo (the
  // chi^+ conditions of G1, which the sampler also enforces).
  bool TransmissionHalfVector(const Vector3T<T>& wi, const Vector3T<T>& wo, Vector3T<T>* wm) const {
    T eta_i, eta_o;
    IncidentIndices(wi, &eta_i, &eta_o);
    Vector3T<T> h = -(eta_i * wi + eta_o * wo);
    const T norm = h.norm();
    if (!(norm > T(0))) return false;
    h /= norm;
    if (h.z() < T(0)) h = -h;
    if (wi.dot(h) * wi.z() <= T(0) || wo.dot(h) * wo.z() <= T(0)) return false;
    *wm = h;
    return true;
  }

  // Walter Eq. 20: f_r = F(i, h_r) G(i, o, h_r) D(h_r) / (4 |i . n| |o . n|); zero unless wi and
  // wo are on the same side.
  T EvalReflection(const Vector3T<T>& wi, const Vector3T<T>& wo) const {
    using std::abs;
    const T cos_i = wi.z(), cos_o = wo.z();
    if (!(cos_i * cos_o > T(0))) return T(0);
    Vector3T<T> wm;
    if (!ReflectionHalfVector(wi, wo, &wm)) return T(0);
    T eta_i, eta_o;
    IncidentIndices(wi, &eta_i, &eta_o);
    const T fresnel = FresnelDielectric(T(abs(wi.dot(wm))), T(eta_o / eta_i));
    return fresnel * distribution.G(wi, wo, wm) * distribution.D(wm) / (T(4) * abs(cos_i) * abs(cos_o));
  }

  // Walter Eq. 21:
  //   f_t = |i . h_t| |o . h_t| / (|i . n| |o . n|)
  //         eta_o^2 (1 - F(i, h_t)) G(i, o, h_t) D(h_t) / (eta_i (i . h_t) + eta_o (o . h_t))^2,
  // zero unless wi and wo are on opposite sides. The eta_o^2 makes this the radiance BTDF
  // (light from wi, medium eta_i, into wo, medium eta_o: radiance is scaled by (eta_o /
  // eta_i)^2, the 1/eta^2 rule of docs/conventions.md with eta read along the camera path,
  // eta_i / eta_o). It obeys f_t(i, o) / eta_o^2 = f_t(o, i) / eta_i^2 (Walter Sec. 4.2),
  // not plain reciprocity.
  T EvalTransmission(const Vector3T<T>& wi, const Vector3T<T>& wo) const {
    using std::abs;
    const T cos_i = wi.z(), cos_o = wo.z();
    if (!(cos_i * cos_o < T(0))) return T(0);
    Vector3T<T> wm;
    if (!TransmissionHalfVector(wi, wo, &wm)) return T(0);
    T eta_i, eta_o;
    IncidentIndices(wi, &eta_i, &eta_o);
    const T i_dot_m = wi.dot(wm), o_dot_m = wo.dot(wm);
    const T fresnel = FresnelDielectric(T(abs(i_dot_m)), T(eta_o / eta_i));
    const T denom = eta_i * i_dot_m + eta_o * o_dot_m;
    return abs(i_dot_m) * abs(o_dot_m) / (abs(cos_i) * abs(cos_o)) * eta_o * eta_o * (T(1) - fresnel) *
           distribution.G(wi, wo, wm) * distribution.D(wm) / (denom * denom);
  }

  // Walter Sec. 5: f_s = f_r + f_t (only one is non-zero for a given pair).
  T Eval(const Vector3T<T>& wi, const Vector3T<T>& wo) const {
    return wi.z() * wo.z() > T(0) ? EvalReflection(wi, wo) : EvalTransmission(wi, wo);
  }

  // Density over solid angle of the wo that Sample() returns (Walter Eq. 38):
  //   reflection:   F(i, h_r) D(h_r) |h_r . n| / (4 |o . h_r|)                      (Eq. 14)
  //   transmission: (1 - F(i, h_t)) D(h_t) |h_t . n| eta_o^2 |o . h_t| /
  //                 (eta_i (i . h_t) + eta_o (o . h_t))^2                              (Eq. 17)
  T Pdf(const Vector3T<T>& wi, const Vector3T<T>& wo) const {
    using std::abs;
    const T cos_i = wi.z(), cos_o = wo.z();
    if (cos_i == T(0) || cos_o == T(0)) return T(0);
    T eta_i, eta_o;
    IncidentIndices(wi, &eta_i, &eta_o);
    Vector3T<T> wm;
    if (cos_i * cos_o > T(0)) {
      if (!ReflectionHalfVector(wi, wo, &wm)) return T(0);
      const T fresnel = FresnelDielectric(T(abs(wi.dot(wm))), T(eta_o / eta_i));
      return fresnel * distribution.Pdf(wm) / (T(4) * abs(wo.dot(wm)));
    }
    if (!TransmissionHalfVector(wi, wo, &wm)) return T(0);
    const T i_dot_m = wi.dot(wm), o_dot_m = wo.dot(wm);
    const T fresnel = FresnelDielectric(T(abs(i_dot_m)), T(eta_o / eta_i));
    const T denom = eta_i * i_dot_m + eta_o * o_dot_m;
    return (T(1) - fresnel) * distribution.Pdf(wm) * eta_o * eta_o * abs(o_dot_m) / (denom * denom);
  }

  // Walter et al. 2007, Sec. 5.3: sample m with density D(m) |m . n| from (u1, u2), reflect
  // with probability F(i, m) (decided by u_lobe) and otherwise refract. Returns false when the
  // sample carries no energy (m facing away from wi, or wo on the wrong side of the
  // macro-surface); such samples are part of the density deficit (Pdf integrates to <= 1).
  bool Sample(const Vector3T<T>& wi, double u_lobe, double u1, double u2, WalterBsdfSample<T>* sample) const {
    using std::abs;
    const T cos_i = wi.z();
    if (cos_i == T(0)) return false;
    T eta_i, eta_o;
    IncidentIndices(wi, &eta_i, &eta_o);
    const Vector3T<T> wm = distribution.Sample(u1, u2);                  // wm.z > 0.
    const Vector3T<T> wm_facing = cos_i > T(0) ? wm : Vector3T<T>(-wm);  // On wi's side.
    const T i_dot_m = wi.dot(wm_facing);
    if (!(i_dot_m > T(0))) return false;  // chi^+(i . m / i . n) = 0: weight would be 0.
    const T fresnel = FresnelDielectric(i_dot_m, T(eta_o / eta_i));
    const T pdf_m = distribution.Pdf(wm);  // p_m(m) = D(m) |m . n|.
    Vector3T<T> wo;
    if (T(u_lobe) < fresnel) {
      wo = Reflect(wi, wm_facing);  // Walter Eq. 39.
      if (!(wo.z() * cos_i > T(0))) return false;
      sample->is_reflection = true;
      // Walter Eqs. 38 and 14: p_o = F p_m / (4 |o . m|).
      sample->pdf = fresnel * pdf_m / (T(4) * abs(wo.dot(wm)));
    } else {
      // Walter Eq. 40 (Snell about m); TIR cannot happen here because then F = 1.
      if (!Refract(wi, wm_facing, T(eta_o / eta_i), &wo)) return false;
      if (!(wo.z() * cos_i < T(0))) return false;
      sample->is_reflection = false;
      // Walter Eqs. 38 and 17: p_o = (1 - F) p_m eta_o^2 |o . m| / (eta_i (i . m) + eta_o (o . m))^2.
      const T denom = eta_i * i_dot_m + eta_o * wo.dot(wm_facing);
      sample->pdf = (T(1) - fresnel) * pdf_m * eta_o * eta_o * abs(wo.dot(wm)) / (denom * denom);
    }
    sample->wo = wo;
    // Walter Eq. 41: weight = f |o . n| / pdf = |i . m| G(i, o, m) / (|i . n| |m . n|).
    sample->weight = i_dot_m * distribution.G(wi, wo, wm) / (abs(cos_i) * wm.z());
    return sample->pdf > T(0);
  }

  std::string ToString() const {
    std::ostringstream out;
    out << "WalterRoughDielectric(" << distribution.ToString() << ", eta=" << eta << ")";
    return out.str();
  }

  static std::vector<ModelParameter> Params() {
    std::vector<ModelParameter> params = Distribution::Params();
    params.push_back({"eta", 1.0 / 3.0, 3.0, "1"});
    return params;
  }
};

template <typename Distribution>
WalterRoughDielectric<Distribution> MakeWalterRoughDielectric(const Distribution& distribution,
                                                              typename Distribution::Scalar eta) {
  return WalterRoughDielectric<Distribution>(distribution, eta);
}

}  // namespace thinslab
