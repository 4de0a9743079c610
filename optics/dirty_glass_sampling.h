// SPDX-License-Identifier: Apache-2.0
// Importance sampling of the diffuse (scattered) part of the Gu et al. 2007 contaminant layer
// (optics/dirty_glass_layer.h) the way the paper does it (Sec. 6: "sampling of the BRDF/BTDF
// models is done by sampling the Henyey-Greenstein phase function"): the incident beam is
// refracted into the layer (Snell, n sin(theta) conserved across the parallel faces), a
// scattering direction is drawn from HG(g) about it, and that direction is refracted out through
// the face it heads for (air above; glass below, or air below a thin slab). Directions follow
// docs/conventions.md: wi and wo point away from the surface, +z is the air side.
//
// Density over the exit solid angle: the HG density of the internal direction times the
// refraction Jacobian d omega_s / d omega_o = n_out^2 |cos theta_o| / (n2^2 |cos theta_s|)
// (n sin(theta) is conserved, so n^2 cos(theta) d omega is too). Samples that would be totally
// internally reflected return false; the density then integrates to the escaping fraction.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>

#include "thinslab/core/math.h"
#include "thinslab/optics/dirty_glass_layer.h"
#include "thinslab/optics/henyey_greenstein.h"

namespace thinslab {

namespace dirty_glass_sampling_detail {

// Index of the medium a direction with the given z sign lives in (outside the layer).
inline double OuterIndex(const DirtyGlassLayer<double>& layer, double z) {
  return z > 0 ? layer.n1 : (layer.thin_slab ? layer.n1 : layer.n3);
}

// Refracts a unit direction from index n_from into index n_to across a face parallel to z = 0,
// keeping the sign of z. Returns false on total internal reflection.
inline bool RefractParallel(const Eigen::Vector3d& d, double n_from, double n_to, Eigen::Vector3d* out) {
  const double s = n_from / n_to;
  const double x = d.x() * s, y = d.y() * s;
  const double sin2 = x * x + y * y;
  if (sin2 >= 1.0) return false;
  *out = Eigen::Vector3d(x, y, std::copysign(std::sqrt(1.0 - sin2), d.z()));
  return true;
}

// Propagation direction of the incident light inside the layer.
inline bool IncidentInLayer(const DirtyGlassLayer<double>& layer, const Eigen::Vector3d& wi, Eigen::Vector3d* d) {
  return RefractParallel(-wi, OuterIndex(layer, wi.z()), layer.n2, d);
}

}  // namespace dirty_glass_sampling_detail

// Density [1/sr] of SampleLayerScatteredDirection producing wo.
inline double LayerScatteredDirectionPdf(const DirtyGlassLayer<double>& layer, const Eigen::Vector3d& wi,
                                         const Eigen::Vector3d& wo) {
  using namespace dirty_glass_sampling_detail;
  Eigen::Vector3d d_in, d_s;
  if (!IncidentInLayer(layer, wi, &d_in)) return 0.0;
  const double n_out = OuterIndex(layer, wo.z());
  // The internal direction that refracts into wo (always exists: going into the layer from the
  // exit medium is never totally reflected when the reverse path escapes).
  if (!RefractParallel(wo, n_out, layer.n2, &d_s)) return 0.0;
  const double jacobian = Sqr(n_out) * std::abs(wo.z()) / (Sqr(layer.n2) * std::abs(d_s.z()));
  return HenyeyGreenstein(d_in.dot(d_s), layer.g) * jacobian;
}

// Draws an exit direction from uniform u1, u2 in [0, 1). Returns false if the incident beam or
// the scattered light is totally internally reflected (no exit along this sample).
inline bool SampleLayerScatteredDirection(const DirtyGlassLayer<double>& layer, const Eigen::Vector3d& wi, double u1,
                                          double u2, Eigen::Vector3d* wo, double* pdf) {
  using namespace dirty_glass_sampling_detail;
  Eigen::Vector3d d_in;
  if (!IncidentInLayer(layer, wi, &d_in)) return false;
  const double cos_t = SampleHenyeyGreensteinCosTheta(u1, layer.g);
  const double sin_t = SafeSqrt(1.0 - cos_t * cos_t);
  const double phi = 2 * kPi * u2;
  // Orthonormal frame (t, b, d_in).
  const Eigen::Vector3d helper = std::abs(d_in.z()) < 0.9 ? Eigen::Vector3d(0, 0, 1) : Eigen::Vector3d(1, 0, 0);
  const Eigen::Vector3d t = d_in.cross(helper).normalized();
  const Eigen::Vector3d b = d_in.cross(t);
  const Eigen::Vector3d d_s = sin_t * (std::cos(phi) * t + std::sin(phi) * b) + cos_t * d_in;
  if (d_s.z() == 0.0) return false;
  if (!RefractParallel(d_s, layer.n2, OuterIndex(layer, d_s.z()), wo)) return false;
  *pdf = LayerScatteredDirectionPdf(layer, wi, *wo);
  return *pdf > 0;
}

}  // namespace thinslab
