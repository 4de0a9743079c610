// SPDX-License-Identifier: Apache-2.0
// Volumetric path tracer for a plane-parallel scattering layer between refractive interfaces:
// air (n1) above, the contaminant layer (n2; optical thickness tau, albedo omega0, HG g), and
// glass (n3) below, either semi-infinite or a slab with a parallel back face to air (the
// "thin transparent slab" of Gu et al. 2007, Appendix). It is the reference for
// optics/dirty_glass_layer.h and optics/thin_slab.h: collimated light at any incidence angle,
// Fresnel reflection or refraction chosen stochastically with probability F (exact
// unpolarised dielectric Fresnel, optics/fresnel.h), all orders of scattering and of
// interface reflection.
//
// The layer is laterally infinite and uniformly lit, so exit radiance does not depend on
// position and only directions are tracked (no lateral displacement). The glass does not
// absorb. Exit directions are binned on each side of the stack in the medium they end in
// (air above; glass for a semi-infinite glass, air below a slab).
//
// Frame: z = +N points to the air above; the incident direction wi (pointing away from the
// surface, towards the light) is in the x-z plane with wi.x >= 0. Exit azimuth phi is that of
// the exit direction (pointing away) measured from +x and folded to [0, pi] (the problem is
// symmetric about the plane of incidence); the mirror and the straight-through directions
// are at phi = pi.
#pragma once

#include <cstdint>
#include <vector>

namespace thinslab {

struct LayerPathTracerOptions {
  double tau = 0.1;     // Optical thickness of the layer, unitless, >= 0.
  double albedo = 0.3;  // Single-scattering albedo omega0, unitless [0, 1].
  double g = 0.8;       // HG mean cosine, unitless (-1, 1).
  double n1 = 1.0;      // Air, unitless refractive index.
  double n2 = 1.5;      // Layer.
  double n3 = 1.5;      // Glass.
  bool glass_slab = false;         // Glass has a back face to air (n1) below.
  double incident_theta_rad = 0;   // Angle of wi to its face's normal, in its medium, [0, pi/2).
  bool incident_from_below = false;  // Light arrives from the glass side (wi.z < 0).
  int num_paths = 1000000;
  int num_mu_bins = 16;   // Uniform bins of the exit |cos theta| in (0, 1].
  int num_phi_bins = 12;  // Uniform bins of the folded exit azimuth in [0, pi].
  int max_events = 100000;  // Interface + scattering events per path before it is dropped.
  uint64_t seed = 1;
};

// A binned BSDF estimate [1/sr] with its standard error. Bin (mu_idx, phi_idx) is at index
// mu_idx * num_phi_bins + phi_idx and covers mu in [mu_idx, mu_idx + 1) / num_mu_bins, phi in
// [phi_idx, phi_idx + 1) pi / num_phi_bins (and its mirror image -phi). The value is the exit
// flux per incident flux in the bin divided by (bin solid angle * bin-centre mu), so the
// matching model value is the mu-weighted bin average: integral f mu dw / (Omega mu_c).
struct LayerBsdfEstimate {
  std::vector<double> value;
  std::vector<double> std_error;
};

// One side of the stack (the incident side is "reflected").
struct LayerSideTally {
  double specular = 0;     // Unscattered flux fraction (all interface paths).
  double specular_gu = 0;  // Unscattered along the paths Gu Eqs. 1, 2, 5 keep (see .cc).
  LayerBsdfEstimate single;     // Exactly one scattering event, any interface path.
  LayerBsdfEstimate single_gu;  // One scattering event along the paths Gu Eqs. 3, 4, 6 keep.
  LayerBsdfEstimate multiple;   // Two or more scattering events.
  double scattered_flux = 0;    // All scattered flux leaving this side.
};

struct LayerPathTracerResult {
  LayerSideTally reflected;
  LayerSideTally transmitted;
  double absorbed = 0;  // Flux fraction absorbed (1 - omega0 per event, expected weight).
  double dropped = 0;   // Flux fraction in paths cut at max_events.
  int num_mu_bins = 0;
  int num_phi_bins = 0;

  double MuCenter(int mu_idx) const { return (mu_idx + 0.5) / num_mu_bins; }
  double PhiCenter(int phi_idx) const;
  double BinSolidAngle() const;  // Of the folded bin (both +phi and -phi halves).
};

LayerPathTracerResult TraceLayer(const LayerPathTracerOptions& options);

}  // namespace thinslab
