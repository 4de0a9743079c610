// SPDX-License-Identifier: Apache-2.0
// Model ladder on a laser-lobe capture (issue #8, rungs 0-2): what the lobe around a collimated
// beam through the layer can tell apart.
//   rung 0  attenuator only: no scattered light outside the beam core (tau alone, from the
//           shadow map);
//   rung 1  thin isotropic slab (Frisvad et al. 2005 single scattering, p = Lambda / 4 pi): one
//           scale beta (albedo x beam x board x camera), tau given;
//   rung 2  Henyey-Greenstein contaminant layer (Gu et al. 2007 Eq. 8): beta and g.
// The rings of FitPhase are split, even rings fitted and odd rings held out (with fewer than 10
// rings: each ring held out in turn, leave-one-out); each rung predicts the held-out rings and the choice is fit/ladder_choice.h's (the simplest rung within
// noise of the best, errors in units of each ring's standard error). BIC on the training rings
// is reported as the documented alternative.
#pragma once

#include <array>
#include <string>
#include <vector>

#include "thinslab/core/status.h"
#include "thinslab/fit/phase_fit.h"

namespace thinslab {

constexpr int kNumLaserLadderRungs = 3;  // Rung number = index.
const char* LaserLadderRungName(int rung);

struct LaserLadderResult {
  int training_rings = 0, held_out_rings = 0;
  std::array<int, kNumLaserLadderRungs> parameters{{0, 1, 2}};
  // Mean over held-out rings of ((prediction - intensity) / sigma)^2; about 1 for a model that
  // describes the lobe to within the rings' noise.
  std::array<double, kNumLaserLadderRungs> held_out_chi2{{0, 0, 0}};
  std::array<double, kNumLaserLadderRungs> bic{{0, 0, 0}};  // Training chi2 + k ln n.
  std::array<double, kNumLaserLadderRungs> seconds{{0, 0, 0}};
  std::array<std::vector<double>, kNumLaserLadderRungs> squared_errors;  // Per held-out ring.
  double frisvad_beta = 0;             // Rung 1.
  double gu_beta = 0, gu_g = 0;        // Rung 2.
  int chosen_rung = -1, chosen_by_bic = -1;
  std::string split;  // "odd rings held out" (>= 10 rings) or "leave-one-out".
  // When the fit of all rings rejects the held-out choice (|g| > 3 sigma_g rejects rungs 0-1):
  // the held-out choice and why it was replaced by rung 2; -1 otherwise.
  int overruled_rung = -1;
  std::string overrule_reason;
};

// `rings` as FitPhase returns them (at least 5); options.tau is the layer's optical thickness.
// `full_fit`: FitPhase's summary on the same rings (nullptr: the held-out choice stands).
Status FitLaserLobeLadder(const std::vector<LaserRing>& rings, const PhaseFitOptions& options,
                          double significance_sigmas, const PhaseFitSummary* full_fit, LaserLadderResult* result);

std::string LaserLadderJson(const LaserLadderResult& result);

}  // namespace thinslab
