// SPDX-License-Identifier: Apache-2.0
// Fit no more model than a slice needs (issue #8, the BTDF rungs of the ladder on dot-scan
// data). For one point's slice, in order of complexity:
//   rung 3  single rough GGX or Beckmann interface (Walter et al. 2007): alpha_g, k_s
//                                                                                    (2 parameters)
//   rung 4  dual-microfacet with an analytic isotropic GGX or Beckmann NDF (Dai Eq. 11 with D
//           and G of one roughness): alpha_ndf, the Eq. 11 weight alpha, k_s          (3 parameters)
// (the family and, for rung 3, the rough face are discrete choices by the training cost.)
//   rung 5  dual-microfacet with the tabulated NDF (fit/dmf_point_fit.h): the interior
//           cells of the N x N grid, alpha, smith_alpha, k_s                   (N^2 pi/4 + ~3)
// A slice whose lobe is narrower than the dot spacing or that shows no scattering at all
// (PrecheckSlice: specular or no lobe) resolves no BTDF shape and takes rung 0, the attenuator
// (a smooth slab only attenuates).
// Each rung is fitted to the training dots and scored on the held-out dots (in-lobe relative
// RMS, HeldOutRelativeRms). The chosen rung is the simplest whose held-out error is within noise
// of the best: over the same held-out dots, rung r is kept unless its mean extra squared error
// exceeds the dots' mean measurement variance plus significance_sigmas standard errors of the
// per-dot differences (fit/ladder_choice.h). The noise floor e_noise (the held-out error measurement noise alone would give,
// sqrt(sum sigma^2 / sum meas^2)) is reported. BIC on the training log residuals of the lobe's
// dots, the same dots for every rung (n ln(RSS / n) + k ln n), is the documented alternative.
// rho_d (Eq. 14) is common to all rungs.
#pragma once

#include <array>
#include <string>

#include "thinslab/fit/dmf_point_fit.h"
#include "thinslab/fit/single_interface_fit.h"

namespace thinslab {

struct AnalyticDmfFit {
  bool ok = false;
  MicrofacetFamily family = MicrofacetFamily::kGgx;
  double alpha_ndf = 0.2;  // Roughness of the virtual surface (D and G of `family`).
  double alpha = 0.5;      // Eq. 11 weight.
  double k_s = 0, rho_d = 0;
  double log_rms_residual = 0;
};

// Rung 4 by Ceres on the Eq. 15 log residuals: GGX from three starts of the weight (0.2, 0.5,
// 0.8), Beckmann from the best GGX solution; the lowest cost is kept.
AnalyticDmfFit FitAnalyticDualMicrofacet(const DmfSlice& slice, const DmfPointFitOptions& options);
double PredictAnalyticDualMicrofacet(const AnalyticDmfFit& fit, double eta, const Eigen::Vector3d& i,
                                     const Eigen::Vector3d& o);

constexpr int kNumLadderRungs = 3;
constexpr std::array<int, kNumLadderRungs> kLadderRungIds = {3, 4, 5};  // Issue #8 numbering.
const char* LadderRungName(int rung_index);

// How the ladder chooses: the held-out paired comparison (default), or the smallest BIC on the
// training log residuals (n ln(RSS / n) + k ln n, summed over a group's points).
enum class LadderCriterion { kHeldOut, kBic };

struct LadderOptions {
  DmfPointFitOptions point;
  LadderCriterion criterion = LadderCriterion::kHeldOut;
  double significance_sigmas = 2.0;
  double lobe_fraction = 0.1;  // Held-out dots above this fraction of the peak are scored.
};

struct LadderResult {
  bool specular = false;       // Rung 0: no rung fitted.
  int chosen = -1;             // Index into kLadderRungIds by options.criterion; -1 when no rung could be scored.
  int chosen_by_bic = -1;      // Index into kLadderRungIds by BIC alone (reported either way).
  std::array<double, kNumLadderRungs> held_out{{-1, -1, -1}};
  std::array<double, kNumLadderRungs> bic{{0, 0, 0}};
  std::array<int, kNumLadderRungs> parameters{{0, 0, 0}};
  std::array<double, kNumLadderRungs> seconds{{0, 0, 0}};
  double noise_floor = 0;      // e_noise.
  // Per rung, the squared prediction error of every scored dot (same dots for all rungs), and
  // the sum of the squared measurements they are relative to: what ChooseLadderRung pools.
  std::array<std::vector<double>, kNumLadderRungs> squared_errors;
  std::vector<double> noise_variances;  // sigma^2 of the same dots (HDR variance; 0 where unknown).
  double signal = 0;
  SingleInterfaceFit single;
  AnalyticDmfFit analytic;
  DmfPointFit tabulated;
  // Issue #8 rung number of the choice: 0 (attenuator), 3, 4, 5; -1 when nothing could be told.
  int chosen_rung() const { return specular ? 0 : chosen >= 0 ? kLadderRungIds[chosen] : -1; }
};

// The point-fit options of rungs 3 and 4: only training dots in the lobe (above lobe_fraction
// of the peak, where the held-out dots are scored) enter their Eq. 15 log residuals. An analytic
// single-refraction lobe cannot follow the far tails of a real slab (light that bounced inside
// it, brighter than the single-refraction model by 1.2-4x below 5 % of the peak on the simulated
// GGX 0.3 slab), and in log space those tails weigh as much as the lobe: fitted on every dot
// above 2 % of the peak, rung 3 on that slab took k_s 1.15 for 1.0 and predicted the held-out
// lobe 2x worse than its own true model. Rung 5 keeps Dai's objective (its tabulated D can follow
// the tails). Falls back to options.point where the lobe holds fewer than min_measurements dots.
DmfPointFitOptions AnalyticRungOptions(const LadderOptions& options);

// The slice must hold held-out dots (train == 0); `grid` has options.point.ndf_resolution.
// `chosen` is the choice from this point's dots alone (ChooseLadderRung over one point).
LadderResult FitLadder(const DmfSlice& slice, const DmfNdfGrid& grid, const LadderOptions& options);

// The choice for a group of points of one material (a pixel cluster, issue #8): the paired
// comparison pooled over all their scored dots, each point's dots relative to its own signal.
// Index into kLadderRungIds; -1 when no rung was fitted on every point of the group. Specular
// points are skipped (they are rung 0 on their own). With LadderCriterion::kBic, the rung of the
// smallest BIC summed over the group's points (the rungs fitted on every one of them).
int ChooseLadderRung(const std::vector<const LadderResult*>& group, double significance_sigmas,
                     LadderCriterion criterion = LadderCriterion::kHeldOut);

// The chosen rung's model in the form of the tabulated fit, so that maps.exr and the NDF atlas
// hold what the ladder chose (issue #8: fit no more model than the sample needs): rung 3 is
// alpha = 1 (rough top) or 0 with D of its family and roughness, rung 4 the analytic weight and
// D; ln D is sampled at the centres of the cells inside the disk (ln epsilon outside, as fitted),
// smith_alpha is the analytic roughness (the tabulated model's Smith term is GGX's: exact for
// GGX, for Beckmann within the few per cent the two Smith terms differ below grazing). k_s is
// refitted in closed form on `slice`'s training dots (the Eq. 15 objective), so a point of a
// clustered run can take its representative's shape with its own scale; rho_d is kept.
// `rung_index` 0 or 1 (kLadderRungIds 3 or 4); other values, or a shape that was not fitted,
// leave `fit` unchanged and return false.
bool ReplaceWithLadderRung(const LadderResult& shape, int rung_index, const DmfSlice& slice, const DmfNdfGrid& grid,
                           const DmfPointFitOptions& options, DmfPointFit* fit);
// A point of a clustered run that inherits its representative's choice takes the
// representative's replaced model (`replaced`, from ReplaceWithLadderRung) with its own k_s; the
// transmittance is the representative's rescaled, as for interpolated points (fit/dmf_map_fit.cc).
bool AdoptLadderShape(const DmfPointFit& replaced, const DmfSlice& slice, const DmfNdfGrid& grid,
                      const DmfPointFitOptions& options, DmfPointFit* fit);

}  // namespace thinslab
