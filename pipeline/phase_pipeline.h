// SPDX-License-Identifier: Apache-2.0
// The whole laser-lobe fit of the layer's Henyey-Greenstein g (Gu et al. 2007, Eq. 8) from a
// capture folder to an output folder, without device code.
#pragma once

#include <string>
#include <vector>

#include "thinslab/calib/laser_lobe_preparation.h"
#include "thinslab/core/status.h"
#include "thinslab/fit/laser_lobe_ladder.h"
#include "thinslab/fit/phase_fit.h"

namespace thinslab {

// `fit phase`: reads a laser-lobe session, fits Gu Eq. 8 and writes <out_dir>/{summary.json,
// summary.txt, rings.csv, lobe_plot.png, options.ini} atomically.
// allow_incomplete_capture: accept a capture whose acquisition did not complete (--allow-incomplete).
Status FitPhasePipeline(const std::string& session_dir, const std::string& out_dir, const PhaseFitOptions& options,
                        const LaserLobePreparationOptions& preparation, bool allow_incomplete_capture,
                        const std::string& options_ini, PhaseFitSummary* summary,
                        std::vector<LaserRing>* rings, LaserLadderResult* ladder = nullptr);

// Median tau over the status-0 pixels of a `fit tau` map (tau.exr): the layer's tau that
// `fit phase --tau-map` fixes.
Status MedianTauFromMap(const std::string& path, double* tau);

}  // namespace thinslab
