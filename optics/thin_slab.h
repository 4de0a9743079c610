// SPDX-License-Identifier: Apache-2.0
// Single-scattering thin slab of Frisvad, Christensen and Falster 2005, "Efficient Light
// Scattering through Thin Semi-Transparent Objects" (GRAPHITE 2005), Sec. 3, after
// Chandrasekhar 1960 Ch. IX: a plane-parallel medium of optical thickness tau1, index-matched
// (no refraction), lit by a collimated beam, with the emergent radiance approximated by one
// scattering event plus the direct (unscattered) transmission.
//
// Conventions (docs/conventions.md, docs/models/thin_slab.md):
// - mu0 = cos of the beam to the normal of the lit face, mu = cos of the exit direction to the
//   normal of the face it leaves by; both in (0, 1].
// - cos_scatter is the cosine between the propagation directions before and after the
//   scattering event (HG argument, as in optics/henyey_greenstein.h). Frisvad writes
//   p'(omega . omega'_0) with omega'_0 towards the light; ScatterCosine* below give the
//   propagation-direction cosine for both faces so the sign cannot be mixed up.
// - *Radiance() are per unit irradiance E(0) measured normal to the beam (Chandrasekhar's
//   pi F), which is what Eq. 4 needs. Per unit irradiance on the surface (E(0) mu0, e.g. Eq. 6
//   for a point light) divide by mu0: *Bsdf() do that and are BSDF values in the pbrt sense
//   (cosine excluded, [1/sr]). Using Eq. 6's E with Eq. 4 unchanged counts mu0 twice.
#pragma once

#include <cmath>
#include <sstream>
#include <string>
#include <type_traits>
#include <vector>

#include "thinslab/optics/henyey_greenstein.h"

namespace thinslab {

// One model parameter for UIs, fits and docs: valid range [min, max] and unit.
struct ThinSlabParameterInfo {
  std::string name;
  double min = 0;
  double max = 0;
  std::string unit;
};

namespace thin_slab_detail {

// expm1(x) / x, continuous through x = 0 (value 1, slope 1/2).
template <typename T>
T ExpRel(const T& x) {
  using std::abs;
  using std::expm1;
  if (abs(x) < T(1e-5)) return T(1) + x * (T(0.5) + x / T(6));
  return expm1(x) / x;
}

}  // namespace thin_slab_detail

template <typename T>
struct ThinSlab {
  T tau1 = T(0.1);    // Optical thickness tau_1 of the slab, unitless, >= 0.
  T albedo = T(0.5);  // Single-scattering albedo Lambda = sigma_s / sigma_t, unitless [0, 1].
  T g = T(0);         // HG mean cosine, unitless (-1, 1); 0 is Frisvad's isotropic Lambda/(4 pi).

  static std::vector<ThinSlabParameterInfo> Parameters() {
    // tau1 max: Frisvad quote < 1% error for tau1 <= 0.2 (Chandrasekhar p. 205); above ~0.5
    // multiple scattering dominates for albedo near 1 (docs/models/thin_slab.md).
    return {{"tau1", 0.0, 1.0, "unitless (optical thickness)"},
            {"albedo", 0.0, 1.0, "unitless (single-scattering albedo Lambda)"},
            {"g", -0.99, 0.99, "unitless (HG mean cosine)"}};
  }

  std::string ToString() const {
    std::ostringstream os;
    os << "ThinSlab{tau1=" << ScalarValue(tau1) << ", albedo=" << ScalarValue(albedo) << ", g=" << ScalarValue(g)
       << "}";
    return os.str();
  }

  // Frisvad Sec. 3 after Eq. 5: Lambda / (4 pi) replaced by Lambda p'(cos); p' is HG.
  T Phase(const T& cos_scatter) const { return albedo * HenyeyGreenstein(cos_scatter, g); }

  // Eq. 4: single-scattered radiance leaving the lit face at tau = 0 (front-lit view), per
  // unit beam-normal irradiance E(0) [1/sr]:
  //   L_+^(1)(0, mu) / E(0) = Lambda p mu0 / (mu + mu0) (1 - e^{-tau1 (1/mu + 1/mu0)}).
  T ReflectedRadiance(const T& mu0, const T& mu, const T& cos_scatter) const {
    using std::expm1;
    const T rate = T(1) / mu + T(1) / mu0;
    return Phase(cos_scatter) * mu0 / (mu + mu0) * (-expm1(-tau1 * rate));
  }

  // Eq. 5: single-scattered radiance leaving the far face at tau = tau1 (back-lit view), per
  // unit beam-normal irradiance E(0) [1/sr]:
  //   L_-^(1)(tau1, mu) / E(0) = Lambda p mu0 / (mu - mu0) (e^{-tau1/mu} - e^{-tau1/mu0}).
  // Rewritten as Lambda p (tau1 / mu) e^{-tau1/mu0} ExpRel(tau1 (1/mu0 - 1/mu)), which is the
  // same for mu != mu0 and tends to the limit Lambda p tau1 e^{-tau1/mu0} / mu0 at mu = mu0.
  T TransmittedRadiance(const T& mu0, const T& mu, const T& cos_scatter) const {
    using std::exp;
    const T x = tau1 * (T(1) / mu0 - T(1) / mu);
    return Phase(cos_scatter) * tau1 / mu * exp(-tau1 / mu0) * thin_slab_detail::ExpRel(x);
  }

  // Eqs. 7-8: direct transmission factor e^{-tau1/mu} of the radiance behind the slab (the
  // alpha of Eq. 9), the same for front- and back-lit views.
  T DirectTransmittance(const T& mu) const {
    using std::exp;
    return exp(-tau1 / mu);
  }

  // BSDF forms (per unit irradiance on the surface, cosine excluded) [1/sr].
  T ReflectedBsdf(const T& mu0, const T& mu, const T& cos_scatter) const {
    return ReflectedRadiance(mu0, mu, cos_scatter) / mu0;
  }
  T TransmittedBsdf(const T& mu0, const T& mu, const T& cos_scatter) const {
    return TransmittedRadiance(mu0, mu, cos_scatter) / mu0;
  }

  // Propagation-direction cosine for light arriving at mu0 and leaving at mu, with dphi the
  // azimuth of the exit direction minus the azimuth of the direction towards the light (both
  // measured as directions pointing away from the slab, on their own faces). Reflection: both
  // on the lit face; back-scattering into the light is cos = -1.
  static T ScatterCosineReflected(const T& mu0, const T& mu, const T& dphi) {
    using std::cos;
    using std::sqrt;
    return -(mu0 * mu + sqrt(T(1) - mu0 * mu0) * sqrt(T(1) - mu * mu) * cos(dphi));
  }
  // Transmission: the exit direction is on the far face; straight through is dphi = pi and
  // mu = mu0, cos = 1.
  static T ScatterCosineTransmitted(const T& mu0, const T& mu, const T& dphi) {
    using std::cos;
    using std::sqrt;
    return mu0 * mu - sqrt(T(1) - mu0 * mu0) * sqrt(T(1) - mu * mu) * cos(dphi);
  }
};

}  // namespace thinslab
