// SPDX-License-Identifier: Apache-2.0
// Henyey-Greenstein g of a contaminant from its laser lobe (Gu et al. 2007, Sec. 5.2, Eq. 8).
// The HDR board image is flat-fielded (the board under a uniform light divides out the camera's
// vignetting), the clean-glass lobe is subtracted (stray light), the beam centre is found with
// sub-pixel precision, the board is cut into rings of radius r around it, theta = atan(r / d),
// and each ring gives the mean of its pixels with a cluster-robust standard error. Eq. 8 is fitted to the
// rings with Ceres (parameters log beta, g and optionally tau with a Gaussian prior; Huber
// loss), and the covariance gives sigma_g.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "thinslab/calib/laser_lobe_preparation.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct PhaseFitOptions {
  // Optical thickness of the layer (unitless), e.g. from `thinslab fit tau` on a shadow map of
  // the same layer. Eq. 8's shape depends on it weakly.
  double tau = 0.3;
  // Fit tau too, with a Gaussian prior N(tau, tau_prior_sigma).
  bool tau_free = false;
  double tau_prior_sigma = 0.1;
  // Layer single-scattering albedo omega0 (given, as for `fit tau`; Eq. 8 absorbs it into beta).
  // Only sigma_g uses it: the second order the layer predicts, r / (1 - r) of the first with
  // r = albedo (1 - e^{-tau}), bounds the g shift of the multiple scattering Eq. 8 leaves out.
  double layer_albedo = 0.3;
  double ring_width_px = 2;  // Ring width in board pixels.
  // The spike core is excluded: rings start at r = max(core_beam_radii * beam radius,
  // beam radius + core_margin_px pixels) from the beam centre (docs/models/laser_lobe_g.md).
  double core_beam_radii = 3;
  double core_margin_px = 4;
  double max_theta_deg = 60;  // Outermost ring (when max_theta_auto is off).
  // Fit once per candidate outermost angle and keep the successful fit with the smallest sigma_g.
  // Eq. 8 is single scattering: the layer's multiple scattering widens the lobe's tail, which
  // reads as a lower g when wide rings are fitted (g 0.8: 0.017 low at 60 degrees, 0.005 at 30;
  // docs/benchmarks.md), while a broad lobe (small g) needs the wide rings to be determined at all
  // (g 0.2: sigma_g 0.12 at 30 degrees, 0.012 at 60). sigma_g holds both (its angle-range term
  // measures the mismatch), so the smallest one picks the angle without the truth.
  bool max_theta_auto = true;
  std::vector<double> max_theta_candidates_deg = {30, 45, 60};
  int min_ring_pixels = 8;
  bool subtract_clean = true;  // Subtract the clean-glass lobe when the session has one.
  bool flat_field = true;      // Divide by the board flat field when the session has one.
  double huber_scale = 2.0;    // Huber loss scale on ring residuals, in standard errors.
  // Below this significance (sigma) of the lobe over zero, the result is "no measurable scattering".
  double min_significance = 5;
  // Above this sigma_g, g is not determined (kFailure): +-2 sigma would then span more than
  // most of a Gu Fig. 2 category range (0.5-0.8 wide), so no category could be told apart.
  double max_sigma_g = 0.2;

  bool Check(std::string* error) const;
};

struct LaserRing {
  double r_m = 0;
  double theta_rad = 0;
  double intensity = 0;  // Flat-fielded DN per microsecond (mean of the ring's board pixels).
  double sigma = 0;      // Its standard error (azimuthal sectors as clusters; fit/phase_fit.cc).
  int pixels = 0;
  double model = 0;      // Fitted Eq. 8 value (after FitPhase).
};

struct PhaseFitSummary {
  enum class Result { kNotRun, kSuccess, kNoMeasurableScattering, kFailure };
  Result result = Result::kNotRun;
  std::string message = "FitPhase was not called.";
  double g = 0;
  // sigma_g = hypot(max(statistical sigma from the covariance scaled by sqrt(chi2/dof),
  // block-jackknife sigma over 8 theta blocks of rings), angle-range consistency |g(all rings) -
  // g(theta <= max_theta / 2)|, sigma_g_multiple). The last three catch lobe-shape mismatch
  // (multiple scattering, which Eq. 8 leaves out) that the covariance, which assumes the model is
  // right, cannot.
  double sigma_g = 0, sigma_g_covariance = 0, sigma_g_jackknife = 0, sigma_g_range = 0;
  // How the jackknife was formed ("8 contiguous theta blocks", "delete-one over N rings", or
  // "not computed: ..."); whether the range term could be formed (>= 5 rings within half the
  // angle range): a 0 term is then "not measured", not "no spread".
  std::string jackknife_method = "not computed";
  bool range_term_available = false;
  // With max_theta_auto, sigma_g also holds (in quadrature) |g - g at the neighbouring candidate
  // angle|: what the choice of the outermost angle moves g by (0 without it).
  double sigma_g_choice = 0;
  // The multiple scattering Eq. 8 leaves out (in quadrature in sigma_g): the larger of the
  // profile interval of g when Eq. 8 is extended by a second-order lobe at g^2 of free relative
  // amplitude c, and the shift of g at the c the layer predicts (fit/phase_fit.cc,
  // TwoOrderSigmaG); the best-fitting c; the predicted c and its g shift.
  double sigma_g_multiple = 0, second_order_fraction = 0;
  double predicted_second_order_fraction = 0, sigma_g_predicted_second_order = 0;
  double beta = 0, sigma_log_beta = 0;
  double tau = 0, sigma_tau = 0;
  double chi2_reduced = 0;
  double rms_normalized_residual = 0;
  double detection_significance = 0;  // (chi2 of the rings against zero - N) / sqrt(2N).
  int num_rings = 0;
  double theta_min_deg = 0, theta_max_deg = 0;
  double max_theta_deg = 0;  // Outermost-angle limit of the kept fit (chosen, with max_theta_auto).
  // With max_theta_auto: (candidate angle, its sigma_g, or -1 if that fit did not succeed).
  std::vector<std::pair<double, double>> max_theta_trials;
  Eigen::Vector2d beam_centre_m = Eigen::Vector2d::Zero();
  std::vector<std::string> categories;  // Gu Fig. 2 categories consistent with g +- sigma_g.
  bool flat_fielded = false, clean_subtracted = false;
  // E.g. chi2/dof far from 1 (model mismatch, or overstated noise); in summary.json and printed.
  std::vector<std::string> warnings;
  double total_s = 0;

  bool IsUsable() const { return result == Result::kSuccess; }
  std::string ResultName() const;
  std::string BriefReport() const;
  std::string FullReport() const;
};

// Gu et al. 2007 Fig. 2: dust 0.4 <= g <= 0.9, dirt 0 <= g <= 0.8, lipids 0.7 <= g <= 1.
std::vector<std::string> ContaminantCategories(double g, double sigma_g);

// Eq. 8 fitted to given rings (Ceres, Huber loss as in FitPhase; tau free with its prior when
// options.tau_free). False when no positive lobe scale fits. Used by FitPhase and the model
// ladder (fit/laser_lobe_ladder.h).
bool FitEq8ToRings(const PhaseFitOptions& options, const std::vector<LaserRing>& rings, double* beta, double* g,
                   double* tau);

// Where and how the rings were measured.
struct LaserRingGeometry {
  Eigen::Vector2d beam_centre_m = Eigen::Vector2d::Zero();  // On the board (sample x, y).
  bool flat_fielded = false, clean_subtracted = false;
  // Ring value = (lobe - clean) flat_at_centre / flat: the board as the camera sees it at the
  // beam centre (1 without flat fielding).
  double flat_at_centre = 1;
  double r_core_m = 0, r_max_m = 0;  // Rings span [r_core, r_max) around the centre.
};

// The rings of `images.lobe` (flat-fielded and clean-subtracted when options allow and the
// capture has them) around the beam centre found in it, from the spike core out to
// options.max_theta_deg; each a mean with its standard error (Sec. 5.2).
Status MeasureLaserRings(const PhaseFitOptions& options, const LaserLobeImages& images, LaserRingGeometry* geometry,
                         std::vector<LaserRing>* rings);

// What a fitted lobe predicts for a measured one (issue #23 section 4), per band of theta.
struct LobePredictionBand {
  double theta_min_deg = 0, theta_max_deg = 0;
  int rings = 0;
  // sqrt(sum (pred - meas)^2 / sum meas^2) over the band's rings; with the fit's own scale, and
  // with the scale that fits the measured rings best (the shape alone: g and tau).
  double relative_rms = -1, shape_relative_rms = -1;
  double noise_relative_rms = -1;  // sqrt(sum sigma^2 / sum meas^2), sigma the rings' standard errors.
};
struct LobePrediction {
  Eigen::Vector2d beam_centre_m = Eigen::Vector2d::Zero();  // Found in the measured lobe.
  LaserRingGeometry geometry;
  double board_distance_m = 0;
  double scale = 0;  // beta (d_fit / d)^2: the Eq. 8 profile times this is a ring's value.
  std::vector<LaserRing> rings;  // Measured; `model` holds the prediction.
  double scale_ratio = 0;        // Best-fitting scale / the fit's scale (1: the fit's beta holds).
  std::vector<LobePredictionBand> bands;  // 0-15, 15-30, 30-45, 45-60, 60-90 deg with rings, then all (0-90).
};

// Eq. 8 with the fit's beta, g and tau, made at `fit_board_distance_m`, against the rings of
// `images.lobe` measured out to options.max_theta_deg at images.board_distance_m (beta scales
// as the inverse square of the distance). The beam centre is the measured lobe's own: the
// beam's position is geometry, not part of the fitted model.
Status PredictLaserLobe(const PhaseFitOptions& options, double beta, double g, double tau,
                        double fit_board_distance_m, const LaserLobeImages& images, LobePrediction* prediction);

// Fails (Status) on bad options or input (beam not found, too few rings). A clean pane is not
// an error: the summary says kNoMeasurableScattering.
Status FitPhase(const PhaseFitOptions& options, const LaserLobeImages& images, std::vector<LaserRing>* rings,
                PhaseFitSummary* summary);

}  // namespace thinslab
