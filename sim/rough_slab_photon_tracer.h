// SPDX-License-Identifier: Apache-2.0
// Monte Carlo photon tracer for a non-absorbing slab of index eta in air bounded by two rough
// dielectric interfaces (the ground truth of Dai et al. 2009, Fig. 3 and Fig. 5, for
// optics/dual_microfacet_btdf.h). Each interface is a Smith microsurface (GGX or Beckmann,
// isotropic or anisotropic with alpha_x, alpha_y along the slab x and y axes, uncorrelated
// masking of Walter et al. 2007, Eq. 23): at every hit the tracer
//   1. samples a microfacet normal m from the distribution of visible normals
//      D_wi(m) = G1(wi) max(0, wi . m) D(m) / (wi . n), exactly for both NDFs:
//      GGX by Heitz 2018, "Sampling the GGX Distribution of Visible Normals" (stretch, sample
//      the projected hemisphere, unstretch); Beckmann by the slope-space routine of Heitz and
//      d'Eon 2014, "Importance Sampling Microfacet-Based BSDFs using the Distribution of
//      Visible Normals" (stretch to unit roughness, sample the visible-slope marginal by
//      numerical inversion of its CDF as improved by Jakob 2014 / pbrt-v3 BeckmannSample11,
//      the other slope from its Gaussian, rotate, unstretch). No photon weights: every
//      photon still carries weight 1 (SampleVisibleNormal below is chi-square tested),
//   2. reflects with probability F(wi . m) (optics/fresnel.h), else refracts about m,
//   3. lets the photon leave the microsurface with probability G1(wo, m) (chi^+ included); the
//      rest is counted as "masked" (light that single-scattering Smith theory drops).
// In expectation the scattered density is then exactly Walter's f (Eqs. 20-21) |wo . n|, so
// the transmitted-direction histogram estimates the radiance BTDF of the whole slab, with all
// internal bounces. The slab is infinitely thin (no lateral offset, as in Dai Sec. 3); every
// photon carries weight 1, so reflected + transmitted + masked + capped = 1 exactly.
//
// Frame: macro normal +z on the incident side; wi (pointing to the light, wi.z > 0) is given.
// Transmitted directions o (o.z < 0, pointing away) are binned on the orthographic projection
// (o.x, o.y) in [-1, 1]^2 with N x N square cells: since |o.z| d omega = do_x do_y, the
// estimate count / (num_photons * cell area in the disk) is the cosine-weighted mean of the
// BTDF over the cell, i.e. count / (num_photons * solid angle * |cos theta_o|) of the brief.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <string>
#include <vector>

namespace thinslab {

enum class RoughSlabNdf { kGgx, kBeckmann };

// "ggx" / "beckmann".
const char* RoughSlabNdfName(RoughSlabNdf ndf);
bool ParseRoughSlabNdf(const std::string& name, RoughSlabNdf* ndf);

struct RoughSlabPhotonTracerOptions {
  double eta = 1.5;             // Slab index over air, unitless, > 1.
  // Roughness of the incident-side (top, +z) face along x, unitless [1e-3, 2], and along y;
  // alpha_*_y = 0 means isotropic (alpha_y = alpha_x).
  double alpha_top = 0.3;
  double alpha_bottom = 0.001;  // Roughness of the far face along x.
  double alpha_top_y = 0;
  double alpha_bottom_y = 0;
  RoughSlabNdf ndf_top = RoughSlabNdf::kGgx;
  RoughSlabNdf ndf_bottom = RoughSlabNdf::kGgx;
  Eigen::Vector3d wi = Eigen::Vector3d(0, 0, 1);  // Unit, wi.z > 0.
  int64_t num_photons = 1000000;
  int max_interactions = 64;  // Interface hits per photon before it is capped.
  int num_bins = 64;          // N: N x N cells of the transmitted (o.x, o.y) square.
  uint64_t seed = 1;
};

struct RoughSlabPhotonTracerResult {
  int num_bins = 0;
  int64_t num_photons = 0;
  double reflected = 0;    // Fractions of photons leaving through the top face,
  double transmitted = 0;  // through the bottom face,
  double masked = 0;       // dropped by Smith masking G1(wo, m),
  double capped = 0;       // cut at max_interactions.
  // Transmitted photon counts, cell (row, col) at row * num_bins + col, o.x along col and o.y
  // along row: cell centre (-1 + (col + 0.5) h, -1 + (row + 0.5) h), h = 2 / num_bins.
  std::vector<int64_t> transmitted_counts;
  // Lateral displacement of the transmitted photons between where they entered the incident-side
  // face and where they left the far face, for a slab of unit thickness (x, y of the frame),
  // summed per cell, separately for the photons that crossed the slab once (2 interface hits)
  // and for those that crossed it 3, 5, ... times (internal reflections): a mean times a slab's
  // thickness is where that part of the light leaving in the cell's direction entered. The two
  // parts lie far apart (one crossing at ~tan 28 degrees, several at grazing internal angles),
  // so one mean would put all the light where none enters. The slab's BTDF itself treats it as
  // infinitely thin (see above).
  std::vector<int64_t> transmitted_once_counts;
  std::vector<double> once_offset_x, once_offset_y;
  // Every photon that crossed several times: its offset (a few % of the transmitted photons,
  // spread over tens of thicknesses by grazing internal bounces, so one mean would not do).
  std::vector<Eigen::Vector2f> multiple_offsets;
  // Transmitted counts by number of interface hits (index = hits, 2 = straight through).
  std::vector<int64_t> transmitted_by_hits;

  double CellWidth() const { return 2.0 / num_bins; }
  double CellCentre(int idx) const { return -1 + (idx + 0.5) * CellWidth(); }
  // Area of the cell inside the unit disk (16 x 16 midpoint sub-samples; exact for interior cells).
  double CellAreaInDisk(int row, int col) const;
  // BTDF estimate [1/sr] of the cell and its Poisson standard error; 0 for cells outside the disk.
  double Btdf(int row, int col) const;
  double BtdfStdError(int row, int col) const;
};

RoughSlabPhotonTracerResult TraceRoughSlab(const RoughSlabPhotonTracerOptions& options);

// One microfacet normal from the distribution of visible normals of `ndf` (roughness alpha_x,
// alpha_y) seen from wi (local frame, unit, wi.z > 0), from uniforms u1, u2 in [0, 1): density
// over solid angle G1(wi) max(0, wi . m) D(m) / wi.z (exact for both kinds). Exposed for tests.
Eigen::Vector3d SampleVisibleNormal(RoughSlabNdf ndf, double alpha_x, double alpha_y, const Eigen::Vector3d& wi,
                                    double u1, double u2);

}  // namespace thinslab
