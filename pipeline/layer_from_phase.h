// SPDX-License-Identifier: Apache-2.0
// `thinslab fit tau --phase DIR`: the layer model a laser-lobe fit of the same layer chose
// (docs/models/model_ladder.md), passed to the tau fit. DIR is a `thinslab fit phase` output:
// summary.json (Gu Eq. 8 result, g) and, when written, ladder.json (the chosen rung). Rung 0
// (attenuator: no scattered light seen) fits plain Eq. 7, rung 1 (Frisvad isotropic slab) the
// refinement of Eqs. 5-6 with g = 0, rung 2 (Gu HG layer) with the fitted g. The albedo is not
// measured by the lobe fit and stays the tau fit's option.
#pragma once

#include <nlohmann/json.hpp>

#include <string>

#include "thinslab/core/status.h"
#include "thinslab/fit/tau_fit.h"

namespace thinslab {

// Reads PATH as a JSON object; errors name the file and, when it is missing, `expected` (what
// should have written it, e.g. "a `thinslab fit phase` output").
Status ReadJsonObjectFile(const std::string& path, const std::string& expected, nlohmann::json* j);

struct PhaseLayerChoice {
  std::string summary_path;
  std::string ladder_path;  // "" when the fit wrote no ladder.json (fits before 2026-12-05 with < 10 rings).
  int rung = 2;             // 0 attenuator, 1 isotropic slab, 2 HG layer.
  double g = 0, sigma_g = 0;
};

// Errors name the file and field: a missing or malformed summary, a summary of another model,
// a failed fit (no usable g), a ladder rung outside 0..2.
Status ReadPhaseLayerChoice(const std::string& phase_dir, PhaseLayerChoice* choice);

// Sets refine_scattering and layer_g from the choice.
void ApplyPhaseLayerChoice(const PhaseLayerChoice& choice, TauFitOptions* options);

}  // namespace thinslab
