// SPDX-License-Identifier: Apache-2.0
// The stability matrix of issue #8 for the tau fit (shadow maps, Gu et al. 2007 Eqs. 5-7) and
// the laser-lobe g fit (Gu Eq. 8): one case = a small capture from the simulated rig (Monte
// Carlo layer transport, sensor noise, quantisation), perturbed where the axis asks for it
// (exposure, layer, camera pose in the manifest), run through the unchanged fit pipeline, and
// scored against ground truth together with what the fit itself reported (status codes,
// summary, the written files). Shared by tests/stability_tau_phase_test.cc (a CI-sized matrix)
// and bench/stability_tau_phase.cc (the finer sweep behind docs/stability.md).
#pragma once

#include <cstdint>
#include <string>

#include "thinslab/app/commands.h"
#include "thinslab/core/image.h"
#include "thinslab/core/status.h"
#include "thinslab/fit/phase_fit.h"
#include "thinslab/fit/tau_fit.h"
#include "thinslab/sim/laser_lobe_rig.h"
#include "thinslab/sim/synthesize_shadow_session.h"

namespace thinslab {

// ---- tau fit ----

struct TauStabilityCase {
  SyntheticShadowSessionOptions sim;  // Rig and session; SmallShadowMapRig() gives CI sizes.
  Image tau_true;                     // Layer texture on the sample grid, channel 0 (unitless).
  // Camera pose error written into the manifest before fitting: the camera frame is translated
  // so that the board centre moves by this many camera pixels along image x (rectification
  // error). 0 = the true pose.
  double pose_error_px = 0;
  FitTauRun run;  // Fit options; layer_albedo and layer_g are replaced by the rig's.
};

struct TauStabilityResult {
  Status pipeline;  // Not ok = the pipeline refused the capture, with a message.
  TauFitSummary summary;
  // From the written tau.exr (all zero when the pipeline refused).
  int64_t pixels = 0, ok = 0, dark = 0, saturated = 0, outside = 0, clamped = 0, next_to_clamped = 0, mixed = 0;
  // Status-ok pixels whose error is within 1 and 2 sigma_tau (coverage, issue #24).
  int64_t within_1_sigma = 0, within_2_sigma = 0;
  // summary.json consistency.rms_z (split-half check; -1 when it was skipped).
  double consistency_rms_z = -1;
  int64_t non_finite_values = 0;    // NaN or inf in any channel of tau.exr.
  int64_t invalid_status = 0;       // Status values that are not a TauPixelStatus code.
  // Over status-ok pixels: error of the "tau" channel against ground truth.
  double rms_abs_error = 0, mean_error = 0, max_abs_error = 0, rms_true = 0;
  double rms_abs_error_plain = 0;   // Same for "tau_eq7" (Gu Eq. 7).
  double rms_sigma_tau = 0;         // RMS of the fit's own sigma_tau over the same pixels.
  // RMS error against the truth moved by the board shift the pose error causes (ok pixels at
  // least 2 texels inside the grid): what is left once the map is put back in place.
  double rms_abs_error_realigned = 0;
  double pose_error_board_texels = 0;  // That shift, in texels of the sample grid.
  // Status-ok pixels whose true tau exceeds the fit's tau_max: reported as ok, but wrong.
  int64_t ok_beyond_tau_max = 0;
  // Clamped pixels whose true tau is below tau_max - 0.5: flagged without cause.
  int64_t clamped_below_tau_max = 0;
};

// The CI-sized shadow-map rig: 320 x 240 camera, 50k Monte Carlo photons per tau node, the
// default sensor, 4 frames per state, board at 1 mm.
SyntheticShadowSessionOptions SmallShadowMapRig(uint64_t seed);
// Texture helpers (width x height texels at the rig's pitch).
Image UniformTau(int width, int height, double tau);
// Clean background with four square patches of tau = patch_taus[k], one per quadrant.
Image PatchTau(int width, int height, const double patch_taus[4], double background_tau);

// Synthesizes into <work_dir>/session, fits into <work_dir>/fit, reads back tau.exr and scores.
// Returns an error only for harness failures (synthesis, I/O); a fit that refuses the capture
// is reported in result->pipeline.
Status RunTauStabilityCase(const TauStabilityCase& test_case, const std::string& work_dir, TauStabilityResult* result);

// Moves the camera of <session_dir>/session.json so that the board centre shifts by
// `shift_px` camera pixels along image x; the frames stay as captured. `board_shift_m`
// (optional) receives the resulting misregistration in the sample frame: the fit's pixel at X
// shows the board at X + board_shift_m.
Status PerturbCameraPose(const std::string& session_dir, double shift_px, Eigen::Vector3d* board_shift_m);

// ---- g fit (laser lobe) ----

struct PhaseStabilityCase {
  SyntheticLaserSessionOptions sim;  // SmallLaserLobeRig() gives CI sizes.
  PhaseFitOptions fit;               // fit.tau is set to the rig's tau when <= 0 (0.3 if the rig's is 0).
  int supersample = 3;
};

struct PhaseStabilityResult {
  Status pipeline;  // Not ok = FitPhase refused (beam not found, too few rings, ...).
  PhaseFitSummary summary;
  bool summary_finite = true;  // g, sigma_g, beta, chi2 finite.
  int64_t non_finite_in_files = 0;  // "nan"/"inf"/"null" tokens in rings.csv and summary.json.
};

// The CI-sized laser rig: 480 x 360 camera, 0.3 mm board pitch, 50k photons, no clean bracket.
SyntheticLaserSessionOptions SmallLaserLobeRig(double tau, double g, uint64_t seed);

Status RunPhaseStabilityCase(const PhaseStabilityCase& test_case, const std::string& work_dir,
                             PhaseStabilityResult* result);

}  // namespace thinslab
