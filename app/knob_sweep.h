// SPDX-License-Identifier: Apache-2.0
// Speed against accuracy (issue #8, part 2): one fit configuration per knob value, varied one
// knob at a time around the defaults (plus a few combined fast settings), each timed and scored
// on a simulated capture; the Pareto front marks the configurations no other one beats in both.
//
// Scores are what a user can see without ground truth (the held-out dots of a dot scan) and,
// where the capture has it, the error against the simulated truth.
#pragma once

#include <string>
#include <vector>

#include "thinslab/calib/laser_lobe_preparation.h"
#include "thinslab/calib/shadow_map_preparation.h"
#include "thinslab/core/image.h"
#include "thinslab/core/status.h"
#include "thinslab/fit/dmf_evaluation.h"
#include "thinslab/fit/dmf_map_fit.h"
#include "thinslab/fit/phase_fit.h"
#include "thinslab/fit/tau_fit.h"

namespace thinslab {

struct SweepPoint {
  std::string method;  // "dmf", "tau" or "phase".
  std::string knob;    // Option varied, e.g. "ndf_resolution"; "default" for the defaults.
  std::string value;   // Its value, e.g. "24".
  double seconds = 0;  // Fit time (processing of the capture excluded: it is shared).
  // dmf: median held-out in-lobe relative RMS; tau: RMS relative error vs truth; phase:
  // |g - g_true|.
  double error = -1;
  // dmf: median NDF relative L2 vs truth over the one-sided regions (-1 where the configuration
  // has no tabulated NDF); tau: mean relative bias vs truth; phase: the fit's sigma_g.
  double truth_error = -1;
  int parameters = 0;     // Fitted parameters over the map (tau: fitted pixels; phase: 2 or 3).
  int fitted_points = 0;  // dmf: points fitted directly (representatives when clustered).
  bool pareto = false;
};

// Marks, per method, the points that no other point of that method beats in both seconds and
// error (ties in both keep both). Points with error < 0 are never on the front.
void MarkParetoFront(std::vector<SweepPoint>* points);

struct DmfSweepOptions {
  DmfMapFitOptions defaults;        // The configuration every knob is varied around.
  std::vector<int> ndf_resolutions = {12, 16, 24, 32, 48};
  std::vector<double> cluster_fractions = {0, 0.003, 0.01, 0.03, 0.1, 0.3};  // 0: every point.
  std::vector<int> alpha_iteration_caps = {1, 2, 3, 10};
  std::vector<double> smoothness = {0.003, 0.01, 0.03, 0.1, 0.3};
  bool smith_off = true;            // Also fit without the Smith LM step.
  bool model_rungs = true;          // Rungs 3, 4, 5 of the model ladder, every point.
};

// `slices` must carry held-out dots (DmfProcessingOptions::hold_out); `truth` may be empty.
Status SweepDmfKnobs(const DmfSliceSet& slices, const std::vector<DmfTruthRegion>& truth,
                     const DmfSweepOptions& options, std::vector<SweepPoint>* points);

struct TauSweepOptions {
  TauFitOptions defaults;  // Layer albedo and g set to the capture's.
  std::vector<int> outer_iteration_caps = {1, 2, 4, 8};
  std::vector<double> smoothness_sigmas = {0.03, 0.1};
  std::vector<double> kernel_max_angles_deg = {30, 50, 65};
};

// `truth` holds channel "tau" on the rectified grid of `data`.
Status SweepTauKnobs(const RectifiedShadowMaps& data, const Image& truth, const TauSweepOptions& options,
                     std::vector<SweepPoint>* points);

struct PhaseSweepOptions {
  PhaseFitOptions defaults;  // tau set to the capture's; the outermost angle chosen (max_theta_auto).
  std::vector<double> ring_widths_px = {1, 4, 8};
  std::vector<double> max_thetas_deg = {30, 45, 60, 70};  // Fixed, against the default choice.
  std::vector<double> core_beam_radii = {2, 5, 8};
  std::vector<double> huber_scales = {1, 5};
  bool tau_free = true;  // Also fit tau with its prior.
};

// Laser-lobe g fit (Gu Eq. 8): error = |g - g_true|, truth_error = the fit's own sigma_g (what a
// user sees without the truth); a fit that fails is listed with error -1 (never on the front).
Status SweepPhaseKnobs(const LaserLobeImages& images, double g_true, const PhaseSweepOptions& options,
                       std::vector<SweepPoint>* points);

std::string SweepCsv(const std::vector<SweepPoint>& points);

// Error against fit time (log x), one colour per knob, the Pareto front as a line with its
// points labelled knob=value.
Status WriteSweepChart(const std::string& path, const std::vector<SweepPoint>& points, const std::string& method,
                       const std::string& title, const std::string& error_label);

}  // namespace thinslab
