// SPDX-License-Identifier: Apache-2.0
// The analytic microfacet distribution nearest to a tabulated dual-microfacet NDF (issue #24
// section 3): which family (GGX or Beckmann, Walter et al. 2007 Eqs. 33 and 25), its isotropic
// roughness, and which face of the slab is rough (from Dai's alpha, Eq. 11). Renderers and the
// model ladder speak in these terms; the tabulated NDF does not.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "thinslab/fit/dmf_ndf_grid.h"

namespace thinslab {

enum class NdfFamily : uint8_t { kGgx = 0, kBeckmann = 1, kUndecided = 2 };
const char* NdfFamilyName(NdfFamily family);
std::vector<std::string> NdfFamilyNames();  // Codes 0..kUndecided, for the legend.

enum class RoughFace : uint8_t { kTop = 0, kBottom = 1, kBoth = 2 };
const char* RoughFaceName(RoughFace face);
std::vector<std::string> RoughFaceNames();

struct EquivalentRoughnessOptions {
  // Cells where the tabulated D is below this fraction of its peak are left out: the Eq. 17
  // fill-in towards the boundary value is not a measurement of the tails.
  double min_relative_d = 1e-3;
  // The family whose misfit is smaller by this factor wins; closer: kUndecided (a lobe smeared by
  // the rig, or a rough-top halo, reads between the two).
  double family_ratio = 1.1;
  // Dai's alpha at or above this: the top (monitor-side) face is the rough one; at or below
  // 1 - this: the bottom (camera-side) face; between: both.
  double one_face_alpha = 0.75;
};

struct EquivalentRoughness {
  NdfFamily family = NdfFamily::kUndecided;
  double roughness = 0;  // Isotropic alpha of the better family (GGX when undecided).
  double ggx_alpha = 0, beckmann_alpha = 0;
  // Relative L2 misfit over the cells used, sqrt(sum (s D_fit - D)^2 / sum D^2) with the free
  // scale s (the tabulated D is normalised over the whole disk, the fit over the used cells).
  double ggx_misfit = 0, beckmann_misfit = 0;
};

// `log_ndf`: ln D per cell of `grid` (DmfPointFit::log_ndf). Roughness 0 and misfits 1 for an
// empty NDF.
EquivalentRoughness FitEquivalentRoughness(const std::vector<double>& log_ndf, const DmfNdfGrid& grid,
                                           const EquivalentRoughnessOptions& options = EquivalentRoughnessOptions());

// Sets family and roughness from the two families' fits (also for interpolated points, whose
// alphas and misfits are their representatives' weighted means).
void DecideFamily(const EquivalentRoughnessOptions& options, EquivalentRoughness* r);

// The family tail beyond the measured NDF: the analytic distribution (family, isotropic roughness
// and scale) nearest to ln D over the cells with `use[cell]` (D not normalised, so `scale`
// carries D's level). The family and `misfit` by FitEquivalentRoughness's relative L2 misfit;
// alpha and scale by the RMS of ln D - ln(scale D_family), which weighs the lobe's edge, where
// the tail continues, as much as its peak. scale 0 when fewer than 3 cells are usable.
struct FamilyTail {
  NdfFamily family = NdfFamily::kUndecided;
  double alpha = 0, scale = 0, misfit = 1;
};
FamilyTail FitFamilyTail(const std::vector<double>& log_d, const DmfNdfGrid& grid, const std::vector<bool>& use,
                         const EquivalentRoughnessOptions& options = EquivalentRoughnessOptions());
// scale x D of the family at roughness alpha at the grid cell's centre (Walter et al. 2007,
// Eq. 33 GGX, Eq. 25 Beckmann); 0 outside the disk.
double FamilyTailD(const FamilyTail& tail, const DmfNdfGrid& grid, int cell);

RoughFace RoughFaceOf(double top_face_weight, const EquivalentRoughnessOptions& options = EquivalentRoughnessOptions());

}  // namespace thinslab
