// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/phase_fit.h"

#include <ceres/ceres.h>
#include <ceres/covariance.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "thinslab/core/math.h"
#include "thinslab/fit/cost_functions/laser_lobe_cost.h"
#include "thinslab/optics/dirty_glass.h"

namespace thinslab {

bool PhaseFitOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(tau > 0 && tau <= 10)) {
    msg << "PhaseFitOptions::tau = " << tau << ". Violated constraint: (0, 10]";
  } else if (!(layer_albedo >= 0 && layer_albedo <= 1)) {
    msg << "PhaseFitOptions::layer_albedo = " << layer_albedo << ". Violated constraint: [0, 1]";
  } else if (tau_free && !(tau_prior_sigma > 0)) {
    msg << "PhaseFitOptions::tau_prior_sigma = " << tau_prior_sigma << ". Violated constraint: > 0";
  } else if (!(ring_width_px >= 1)) {
    msg << "PhaseFitOptions::ring_width_px = " << ring_width_px << ". Violated constraint: >= 1";
  } else if (!(core_beam_radii >= 1) || !(core_margin_px >= 0)) {
    msg << "PhaseFitOptions::core_beam_radii = " << core_beam_radii << ", core_margin_px = " << core_margin_px
        << ". Violated constraint: >= 1 and >= 0";
  } else if (!(max_theta_deg > 1 && max_theta_deg < 85)) {
    msg << "PhaseFitOptions::max_theta_deg = " << max_theta_deg << ". Violated constraint: (1, 85)";
  } else if (max_theta_auto && (max_theta_candidates_deg.empty() ||
                                std::any_of(max_theta_candidates_deg.begin(), max_theta_candidates_deg.end(),
                                            [](double t) { return !(t > 1 && t < 85); }))) {
    msg << "PhaseFitOptions::max_theta_candidates_deg: Violated constraint: non-empty, each in (1, 85)";
  } else if (min_ring_pixels < 3) {
    msg << "PhaseFitOptions::min_ring_pixels = " << min_ring_pixels << ". Violated constraint: >= 3";
  } else if (!(huber_scale > 0)) {
    msg << "PhaseFitOptions::huber_scale = " << huber_scale << ". Violated constraint: > 0";
  } else if (!(min_significance > 0)) {
    msg << "PhaseFitOptions::min_significance = " << min_significance << ". Violated constraint: > 0";
  } else if (!(max_sigma_g > 0)) {
    msg << "PhaseFitOptions::max_sigma_g = " << max_sigma_g << ". Violated constraint: > 0";
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

std::string PhaseFitSummary::ResultName() const {
  switch (result) {
    case Result::kNotRun: return "not_run";
    case Result::kSuccess: return "success";
    case Result::kNoMeasurableScattering: return "no_measurable_scattering";
    case Result::kFailure: return "failure";
  }
  return "unknown";
}

std::string PhaseFitSummary::BriefReport() const {
  std::ostringstream out;
  out.precision(4);
  out << "FitPhase: " << ResultName();
  if (result == Result::kSuccess) {
    out << ", g = " << g << " +- " << sigma_g << ", tau = " << tau << ", " << num_rings << " rings, chi2/dof "
        << chi2_reduced;
  }
  return out.str();
}

std::string PhaseFitSummary::FullReport() const {
  std::ostringstream out;
  out.precision(5);
  out << BriefReport() << "\nmessage: " << message << "\n"
      << "g: " << g << " +- " << sigma_g << " (covariance " << sigma_g_covariance << ", jackknife " << sigma_g_jackknife
      << " [" << jackknife_method << "], angle-range consistency "
      << (range_term_available ? std::to_string(sigma_g_range) : std::string("n/a (< 5 rings within half the range)"))
      << ", second-order extension " << sigma_g_multiple << " with relative amplitude " << second_order_fraction
      << " (at the layer's predicted " << predicted_second_order_fraction << ": " << sigma_g_predicted_second_order
      << ")"
      << ", choice of the outermost angle " << sigma_g_choice << ")\n"
      << "beta: " << beta << " (sigma of log beta " << sigma_log_beta << ")\n"
      << "tau: " << tau << " +- " << sigma_tau << "\n"
      << "rings: " << num_rings << " over theta " << theta_min_deg << " .. " << theta_max_deg << " deg (limit "
      << max_theta_deg << " deg" << (max_theta_trials.empty() ? "" : ", chosen by the smallest sigma_g") << ")\n"
      << "beam centre [m]: " << beam_centre_m.x() << ", " << beam_centre_m.y() << "\n"
      << "lobe detection significance: " << detection_significance << " sigma\n"
      << "chi2/dof: " << chi2_reduced << ", rms normalized residual: " << rms_normalized_residual << "\n"
      << "flat-fielded: " << (flat_fielded ? "yes" : "no")
      << ", clean subtracted: " << (clean_subtracted ? "yes" : "no") << "\ncategories (Gu 2007 Fig. 2): ";
  for (size_t i = 0; i < categories.size(); ++i) out << (i ? ", " : "") << categories[i];
  for (const std::string& w : warnings) out << "\nwarning: " << w;
  out << "\ntime [s]: " << total_s << "\n";
  return out.str();
}

std::vector<std::string> ContaminantCategories(double g, double sigma_g) {
  std::vector<std::string> out;
  for (const ContaminantCategoryRange& r : GuContaminantCategories()) {
    if (g + sigma_g >= r.g_min && g - sigma_g <= r.g_max) out.push_back(r.name);
  }
  return out;
}

namespace {

double Median(std::vector<double>* v) {
  std::nth_element(v->begin(), v->begin() + v->size() / 2, v->end());
  return (*v)[v->size() / 2];
}

// Sub-pixel beam centre: radiance-weighted centroid of the pixels above half the peak, within
// a few beam radii of the brightest pixel. Fails if the peak does not stand out.
Status FindBeamCentre(const LaserLobeImages& images, Eigen::Vector2d* centre_m) {
  const Image& lobe = images.lobe.radiance;
  const int w = lobe.width(), h = lobe.height();
  int best = -1;
  std::vector<double> values;
  for (int i = 0; i < w * h; ++i) {
    if (images.outside.data()[i] > 0) continue;
    values.push_back(lobe.data()[i]);
    if (best < 0 || lobe.data()[i] > lobe.data()[best]) best = i;
  }
  if (best < 0) return Status::Error("beam not found: the board region is outside the camera view");
  const double peak = lobe.data()[best];
  const double median = Median(&values);
  const double noise = std::sqrt(std::max(static_cast<double>(images.lobe.variance.data()[best]), 0.0));
  // A spike saturated at every exposure only has a lower bound (and no noise estimate).
  const bool saturated = images.lobe.all_saturated.data()[best] > 0;
  if (!(peak > 20 * std::max(median, 0.0) && (saturated || peak > 5 * noise))) {
    std::ostringstream msg;
    msg << "beam not found: the brightest board pixel (" << peak << " DN/us) does not stand out from the median ("
        << median << ") and the noise (" << noise << "); is the laser on and aimed at the board region?";
    return Status::Error(msg.str());
  }
  const int bx = best % w, by = best / w;
  const int radius = static_cast<int>(std::ceil(3 * images.beam_radius_m / images.pixel_pitch_m)) + 3;
  double sw = 0, sx = 0, sy = 0;
  for (int y = std::max(0, by - radius); y <= std::min(h - 1, by + radius); ++y) {
    for (int x = std::max(0, bx - radius); x <= std::min(w - 1, bx + radius); ++x) {
      const double v = lobe.at(x, y) - 0.5 * peak;
      if (v <= 0) continue;
      sw += v;
      sx += v * (x + 0.5);
      sy += v * (y + 0.5);
    }
  }
  *centre_m = images.grid_min_m + images.pixel_pitch_m * Eigen::Vector2d(sx / sw, sy / sw);
  return Status::Ok();
}


// Fits log beta, g (and tau) to `rings`, starting from the best g of a grid with the
// closed-form beta. Returns false if no positive scale fits.
bool SolveEq8(const PhaseFitOptions& options, const std::vector<LaserRing>& rings, double* log_beta, double* g,
              double* tau, ceres::Problem* problem, ceres::Solver::Summary* ceres_summary) {
  double best_chi2 = -1, g0 = 0, beta0 = 0;
  for (double gi = -0.9; gi <= 0.981; gi += 0.01) {
    double sff = 0, sfi = 0;
    for (const auto& ring : rings) {
      const double f = LaserLobeProfile(std::cos(ring.theta_rad), gi, options.tau);
      sff += Sqr(f / ring.sigma);
      sfi += f * ring.intensity / Sqr(ring.sigma);
    }
    const double beta = sfi / sff;
    if (!(beta > 0)) continue;
    double chi2 = 0;
    for (const auto& ring : rings) {
      chi2 += Sqr((beta * LaserLobeProfile(std::cos(ring.theta_rad), gi, options.tau) - ring.intensity) / ring.sigma);
    }
    if (best_chi2 < 0 || chi2 < best_chi2) {
      best_chi2 = chi2;
      g0 = gi;
      beta0 = beta;
    }
  }
  if (best_chi2 < 0) return false;
  *log_beta = std::log(beta0);
  *g = g0;
  *tau = options.tau;
  for (const auto& ring : rings) {
    problem->AddResidualBlock(LaserLobeRingCost::Create(std::cos(ring.theta_rad), ring.intensity, ring.sigma),
                              new ceres::HuberLoss(options.huber_scale), log_beta, g, tau);
  }
  problem->SetParameterLowerBound(g, 0, -0.99);
  problem->SetParameterUpperBound(g, 0, 0.99);
  if (options.tau_free) {
    problem->AddResidualBlock(GaussianPriorCost::Create(options.tau, options.tau_prior_sigma), nullptr, tau);
    problem->SetParameterLowerBound(tau, 0, 1e-4);
    problem->SetParameterUpperBound(tau, 0, 10);
  } else {
    problem->SetParameterBlockConstant(tau);
  }
  ceres::Solver::Options solver_options;
  solver_options.linear_solver_type = ceres::DENSE_QR;
  solver_options.max_num_iterations = 100;
  solver_options.logging_type = ceres::SILENT;
  ceres::Solve(solver_options, problem, ceres_summary);
  return ceres_summary->IsSolutionUsable();
}

// Block jackknife of g over kJackknifeBlocks contiguous theta blocks of rings. When Eq. 8 does
// not describe the lobe's shape (multiple scattering, stray light), fits on different angle
// ranges disagree, and this spread shows it where the covariance cannot. With fewer than two
// rings per block, each ring is its own block (delete-one jackknife), which needs >= 4 rings
// left per fit. *method says which, or why none ("" never).
constexpr int kJackknifeBlocks = 8;
double JackknifeSigmaG(const PhaseFitOptions& options, const std::vector<LaserRing>& rings, std::string* method) {
  const int n = static_cast<int>(rings.size());
  if (n < 5) {
    *method = "not computed: " + std::to_string(n) + " rings (at least 5 needed)";
    return 0;
  }
  const int blocks = n >= 2 * kJackknifeBlocks ? kJackknifeBlocks : n;
  *method = blocks == n ? "delete-one over " + std::to_string(n) + " rings"
                        : std::to_string(blocks) + " contiguous theta blocks";
  std::vector<double> estimates;
  for (int b = 0; b < blocks; ++b) {
    std::vector<LaserRing> kept;
    for (int k = 0; k < n; ++k) {
      if (k * blocks / n != b) kept.push_back(rings[k]);
    }
    double log_beta, g, tau;
    ceres::Problem problem;
    ceres::Solver::Summary summary;
    if (SolveEq8(options, kept, &log_beta, &g, &tau, &problem, &summary)) estimates.push_back(g);
  }
  if (estimates.size() < 2) {
    *method = "not computed: fewer than 2 of the " + std::to_string(blocks) + " jackknife fits succeeded";
    return 0;
  }
  double mean = 0;
  for (double e : estimates) mean += e / estimates.size();
  double ss = 0;
  for (double e : estimates) ss += Sqr(e - mean);
  const double m = static_cast<double>(estimates.size());
  return std::sqrt((m - 1) / m * ss);
}

// Model-consistency term: |g(all rings) - g(rings with theta <= max_theta / 2)|. Single
// scattering (Eq. 8) misses the multiply scattered light, which weighs most at large angles,
// so a lobe Eq. 8 does not describe gives different g over different angle ranges.
// *available is false when the inner range has fewer than 5 rings or its fit fails (0 returned).
double RangeConsistencySigmaG(const PhaseFitOptions& options, const std::vector<LaserRing>& rings, double g_all,
                              bool* available) {
  *available = false;
  const double theta_half = 0.5 * options.max_theta_deg * kPi / 180;
  std::vector<LaserRing> inner;
  for (const auto& ring : rings) {
    if (ring.theta_rad <= theta_half) inner.push_back(ring);
  }
  if (inner.size() < 5) return 0;
  double log_beta, g, tau;
  ceres::Problem problem;
  ceres::Solver::Summary summary;
  if (!SolveEq8(options, inner, &log_beta, &g, &tau, &problem, &summary)) return 0;
  *available = true;
  return std::abs(g - g_all);
}

// Warnings when chi2/dof is more than 5 standard deviations of its distribution (sqrt(2 / dof))
// from 1 and off by a factor of 4: the rings are not what Eq. 8 with their standard errors
// predicts. The factor was set after seeing single-scattering lobes of the simulated rig (albedo
// 0.01) read 2.8-3.0 at 25 rings, from a small systematic not identified (the finite beam or the
// camera's footprint on the steep inner rings are candidates); multiple scattering at tau 0.3,
// albedo 0.3 reads 14-19, tau 1.5, albedo 0.9 over 5000.
std::vector<std::string> ChiSquareWarnings(double chi2_reduced, double dof, int num_rings) {
  std::vector<std::string> warnings;
  const double spread = 5 * std::sqrt(2 / dof);
  std::ostringstream msg;
  msg.precision(3);
  if (chi2_reduced > std::max(4.0, 1 + spread)) {
    msg << "model mismatch: chi2/dof = " << chi2_reduced << " over " << num_rings
        << " rings: Eq. 8 (single scattering, the rig's geometry) does not describe the lobe within the rings' noise "
           "(multiple scattering of a thick or bright layer, a wrong board distance or beam centre, stray light); "
           "sigma_g is scaled by sqrt(chi2/dof) and holds the second-order term";
    warnings.push_back(msg.str());
  } else if (chi2_reduced < std::min(0.25, 1 - spread)) {
    msg << "chi2/dof = " << chi2_reduced << " over " << num_rings
        << " rings: the residuals are smaller than the rings' standard errors say (correlated or overstated "
           "noise); sigma_g may be too large";
    warnings.push_back(msg.str());
  }
  return warnings;
}

// Model-extension term: Eq. 8 extended by a second-order lobe of the same form at g^2 with
// relative amplitude c (fit/cost_functions/laser_lobe_cost.h), g refitted at each c of a grid
// over [0, 1] from the Eq. 8 solution (tau held at its fitted value); the term is the largest
// |g(c) - g| among the c whose cost is within delta chi2 = 1 (scaled by chi2/dof, like the
// covariance) of the best: the profile interval of g with c a nuisance parameter. Multiple
// scattering, which Eq. 8 leaves out, is mostly absorbed by a lower g that fits every angle
// range about equally well, so neither the jackknife nor the range term sees it (g 0.2, tau 0.3,
// albedo 0.3: error -0.012, those terms 0.003, this one 0.037). On a single-scattering lobe the
// data pin c near 0 and the term stays near the noise. 0 when no extended fit succeeds; *c_out
// gets the best c.
// The data cannot pin c where the twice-scattered lobe at g^2 looks like a slightly lower g
// (narrow rings of a forward lobe: g 0.8 on a 480 x 360 camera read 0.005 low with this term
// 0.001-0.003). So g is also refitted at the c the layer predicts (not in Gu et al. 2007): a
// once-scattered photon scatters again before it leaves the thin layer with probability about
// r = albedo (1 - e^{-tau}), and again, so the higher orders carry r / (1 - r) of the first
// (as the multiple-scattering term of fit/tau_fit.cc). *predicted_shift = |g(c_predicted) - g|.
double TwoOrderSigmaG(const PhaseFitOptions& options, const std::vector<LaserRing>& rings, double log_beta_1,
                      double g_1, double tau, double chi2_scale, double c_predicted, double* c_out,
                      double* predicted_shift) {
  // Profile of the cost over the amplitude c in [0, 1] (a local solver started at c = 0 stays
  // there when adding broad light alone makes the fit worse, although moving g with it would not).
  struct Point {
    double c, g, cost;
  };
  std::vector<Point> profile;
  std::vector<double> grid = {0.0, 0.01, 0.02, 0.03, 0.05, 0.07, 0.1, 0.15, 0.2, 0.3, 0.5, 0.7, 1.0};
  grid.push_back(c_predicted);
  *predicted_shift = 0;
  for (size_t k = 0; k < grid.size(); ++k) {
    const double c_fixed = grid[k];
    double log_beta = log_beta_1, g = g_1, c = c_fixed, t = tau;
    ceres::Problem problem;
    for (const auto& ring : rings) {
      problem.AddResidualBlock(LaserLobeTwoOrderRingCost::Create(std::cos(ring.theta_rad), ring.intensity, ring.sigma),
                               new ceres::HuberLoss(options.huber_scale), &log_beta, &g, &c, &t);
    }
    problem.SetParameterLowerBound(&g, 0, -0.99);
    problem.SetParameterUpperBound(&g, 0, 0.99);
    problem.SetParameterBlockConstant(&c);
    problem.SetParameterBlockConstant(&t);
    ceres::Solver::Options solver_options;
    solver_options.linear_solver_type = ceres::DENSE_QR;
    solver_options.max_num_iterations = 100;
    solver_options.logging_type = ceres::SILENT;
    ceres::Solver::Summary summary;
    ceres::Solve(solver_options, &problem, &summary);
    if (!summary.IsSolutionUsable()) continue;
    if (k + 1 == grid.size()) *predicted_shift = std::abs(g - g_1);
    if (c_fixed <= 1) profile.push_back({c_fixed, g, summary.final_cost});
  }
  *c_out = 0;
  if (profile.empty()) return 0;
  const Point best = *std::min_element(profile.begin(), profile.end(),
                                       [](const Point& a, const Point& b) { return a.cost < b.cost; });
  *c_out = best.c;
  // Profile interval of g at delta chi2 = 1, with chi2 scaled as the covariance is (cost = chi2 / 2).
  double spread = 0;
  for (const Point& p : profile) {
    if (2 * (p.cost - best.cost) <= chi2_scale) spread = std::max(spread, std::abs(p.g - g_1));
  }
  return spread;
}

}  // namespace

bool FitEq8ToRings(const PhaseFitOptions& options, const std::vector<LaserRing>& rings, double* beta, double* g,
                   double* tau) {
  double log_beta = 0;
  ceres::Problem problem;
  ceres::Solver::Summary summary;
  if (!SolveEq8(options, rings, &log_beta, g, tau, &problem, &summary)) return false;
  *beta = std::exp(log_beta);
  return true;
}

namespace {

// One board pixel of a ring: its value, its variance from the HDR merge (camera pixels taken as
// independent) and its azimuth around the beam centre.
struct RingPixel {
  double value = 0, variance = 0, azimuth_rad = 0, r_m = 0;
};

// A ring's value and standard error (issue #24 section 2). The mean, not the median: on a
// photon-starved lobe most pixels are exactly 0 and the rest skewed, and the median falls below
// the mean (to 0 when over half the pixels are 0), which biased g high and made it depend on the
// map pitch (averaging more camera pixels per board pixel makes a pixel less skewed). The mean
// of the pixels is unbiased for any noise distribution. Its standard error treats azimuthal
// sectors of the ring as independent clusters (the cluster-robust variance of a mean): board
// pixels finer than the camera's footprint share camera pixels and are correlated, so s /
// sqrt(n) would be too small, while sectors are far apart. A bright outlier (a speck on the
// board) raises its sector's mean and with it the standard error, so the Huber loss of the fit
// weighs the ring down. The HDR variance of the mean is a floor (a ring of exact zeros).
void RingMean(const std::vector<RingPixel>& pixels, double* mean, double* standard_error) {
  const int n = static_cast<int>(pixels.size());
  double sum = 0, variance_sum = 0;
  for (const RingPixel& px : pixels) {
    sum += px.value;
    variance_sum += px.variance;
  }
  *mean = sum / n;
  const int sectors = std::clamp(n / 4, 2, 16);
  std::vector<double> sector_sum(sectors, 0.0);
  std::vector<int> sector_count(sectors, 0);
  for (const RingPixel& px : pixels) {
    const int s = std::min(sectors - 1, static_cast<int>((px.azimuth_rad + kPi) / (2 * kPi) * sectors));
    sector_sum[s] += px.value;
    ++sector_count[s];
  }
  int used = 0;
  double cluster_ss = 0;
  for (int s = 0; s < sectors; ++s) {
    if (sector_count[s] == 0) continue;
    ++used;
    cluster_ss += Sqr(sector_sum[s] - sector_count[s] * *mean);
  }
  double variance = 0;
  if (used >= 2) {
    variance = static_cast<double>(used) / (used - 1) * cluster_ss / Sqr(static_cast<double>(n));
  } else {  // The whole ring in one sector (a sliver at the view's edge): pixels as independent.
    double ss = 0;
    for (const RingPixel& px : pixels) ss += Sqr(px.value - *mean);
    variance = ss / (n - 1) / n;
  }
  variance = std::max(variance, variance_sum / Sqr(static_cast<double>(n)));
  *standard_error = std::max(std::sqrt(variance), 1e-12);
}

// FitPhase at options.max_theta_deg.
// The spike core's radius: rings start here (PhaseFitOptions::core_beam_radii).
double LaserCoreRadius(const PhaseFitOptions& options, const LaserLobeImages& images) {
  return std::max(options.core_beam_radii * images.beam_radius_m,
                  images.beam_radius_m + options.core_margin_px * images.pixel_pitch_m);
}

}  // namespace

Status MeasureLaserRings(const PhaseFitOptions& options, const LaserLobeImages& images, LaserRingGeometry* geometry,
                         std::vector<LaserRing>* rings) {
  *geometry = LaserRingGeometry();
  if (images.lobe.empty()) return Status::Error("FitPhase: no contaminated laser lobe");
  if (!(images.board_distance_m > 0)) return Status::Error("FitPhase: board distance must be > 0");
  THINSLAB_RETURN_IF_ERROR(FindBeamCentre(images, &geometry->beam_centre_m));
  const Eigen::Vector2d centre = geometry->beam_centre_m;
  const Image& lobe = images.lobe.radiance;
  const int w = lobe.width(), h = lobe.height();
  const double p = images.pixel_pitch_m, d = images.board_distance_m;

  // Flat field normalised at the beam centre: divides out vignetting between rings.
  const bool flat = options.flat_field && !images.flat.empty();
  double flat_centre = 1;
  if (flat) {
    const Eigen::Vector2d c_px = (centre - images.grid_min_m) / p;
    flat_centre = images.flat.radiance.Bilinear(c_px.x(), c_px.y());
    if (!(flat_centre > 0)) return Status::Error("FitPhase: the flat field has no signal at the beam centre");
  }
  const bool subtract = options.subtract_clean && !images.clean.empty();
  const double r_core = LaserCoreRadius(options, images);
  const double r_max = d * std::tan(options.max_theta_deg * kPi / 180);
  geometry->flat_fielded = flat;
  geometry->clean_subtracted = subtract;
  geometry->flat_at_centre = flat_centre;
  geometry->r_core_m = r_core;
  geometry->r_max_m = r_max;
  const double ring_w = options.ring_width_px * p;
  const int num_bins = std::max(1, static_cast<int>((r_max - r_core) / ring_w));
  std::vector<std::vector<RingPixel>> bins(num_bins);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      if (images.outside.data()[i] > 0 || images.lobe.all_saturated.data()[i] > 0) continue;
      if (subtract && images.clean.all_saturated.data()[i] > 0) continue;
      const Eigen::Vector2d q = images.grid_min_m + p * Eigen::Vector2d(x + 0.5, y + 0.5);
      const double r = (q - centre).norm();
      if (r < r_core || r >= r_max) continue;
      const int k = static_cast<int>((r - r_core) / ring_w);
      if (k < 0 || k >= num_bins) continue;
      double v = lobe.data()[i];
      double var = images.lobe.variance.data()[i];
      if (subtract) {
        v -= images.clean.radiance.data()[i];
        var += images.clean.variance.data()[i];
      }
      if (flat) {
        const double f = images.flat.radiance.data()[i];
        if (!(f > 0)) continue;
        v *= flat_centre / f;
        var *= Sqr(flat_centre / f);
      }
      bins[k].push_back({v, std::max(var, 0.0), std::atan2(q.y() - centre.y(), q.x() - centre.x()), r});
    }
  }
  rings->clear();
  for (int k = 0; k < num_bins; ++k) {
    if (static_cast<int>(bins[k].size()) < options.min_ring_pixels) continue;
    LaserRing ring;
    // The ring's mean pixel radius, not its middle: a ring has more pixels (area) on its outer
    // side, and the lobe falls steeply at small angles.
    ring.r_m = 0;
    for (const RingPixel& px : bins[k]) ring.r_m += px.r_m / bins[k].size();
    ring.theta_rad = std::atan(ring.r_m / d);
    RingMean(bins[k], &ring.intensity, &ring.sigma);
    ring.pixels = static_cast<int>(bins[k].size());
    rings->push_back(ring);
  }
  return Status::Ok();
}

namespace {

Status FitPhaseAtMaxTheta(const PhaseFitOptions& options, const LaserLobeImages& images, std::vector<LaserRing>* rings,
                          PhaseFitSummary* summary) {
  const auto t0 = std::chrono::steady_clock::now();
  *summary = PhaseFitSummary();
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  LaserRingGeometry geometry;
  THINSLAB_RETURN_IF_ERROR(MeasureLaserRings(options, images, &geometry, rings));
  summary->beam_centre_m = geometry.beam_centre_m;
  summary->flat_fielded = geometry.flat_fielded;
  summary->clean_subtracted = geometry.clean_subtracted;
  const double r_core = geometry.r_core_m;
  summary->num_rings = static_cast<int>(rings->size());
  if (rings->size() < 5) {
    std::ostringstream msg;
    msg << "FitPhase: only " << rings->size() << " rings with >= " << options.min_ring_pixels
        << " pixels between the core (r = " << r_core * 1e3 << " mm) and theta = " << options.max_theta_deg
        << " deg; is the board region large enough and seen by the camera?";
    return Status::Error(msg.str());
  }
  summary->theta_min_deg = rings->front().theta_rad * 180 / kPi;
  summary->theta_max_deg = rings->back().theta_rad * 180 / kPi;

  // Is there a lobe at all? chi2 of the rings against zero.
  double chi2_zero = 0;
  for (const auto& ring : *rings) chi2_zero += Sqr(ring.intensity / ring.sigma);
  const double n_rings = static_cast<double>(rings->size());
  summary->detection_significance = (chi2_zero - n_rings) / std::sqrt(2 * n_rings);
  summary->tau = options.tau;
  auto finish = [&]() {
    summary->total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  };
  if (summary->detection_significance < options.min_significance) {
    summary->result = PhaseFitSummary::Result::kNoMeasurableScattering;
    std::ostringstream msg;
    msg << "no measurable scattering: outside the beam core the lobe is consistent with zero (significance "
        << summary->detection_significance << " sigma < " << options.min_significance << "); g is not defined";
    summary->message = msg.str();
    finish();
    return Status::Ok();
  }

  double log_beta = 0, g = 0, tau = options.tau;
  ceres::Problem problem;
  ceres::Solver::Summary ceres_summary;
  if (!SolveEq8(options, *rings, &log_beta, &g, &tau, &problem, &ceres_summary)) {
    summary->result = PhaseFitSummary::Result::kFailure;
    summary->message = ceres_summary.message.empty() ? "no positive lobe scale fits the rings"
                                                     : "Ceres: " + ceres_summary.message;
    finish();
    return Status::Error("FitPhase: " + summary->message);
  }

  // Residuals and chi2 (without the robust loss).
  double chi2 = 0;
  for (auto& ring : *rings) {
    ring.model = std::exp(log_beta) * LaserLobeProfile(std::cos(ring.theta_rad), g, tau);
    chi2 += Sqr((ring.model - ring.intensity) / ring.sigma);
  }
  // log beta and g are free; a free tau brings its own prior residual, so dof stays n - 2.
  const double dof = std::max(1.0, n_rings - 2);
  summary->chi2_reduced = chi2 / dof;
  summary->rms_normalized_residual = std::sqrt(chi2 / n_rings);
  summary->g = g;
  summary->beta = std::exp(log_beta);
  summary->tau = tau;

  // Covariance of (log beta, g[, tau]), scaled by chi2/dof when the model does not explain the
  // rings to within their standard errors (multiple scattering, stray light).
  ceres::Covariance::Options cov_options;
  cov_options.algorithm_type = ceres::DENSE_SVD;
  cov_options.null_space_rank = -1;
  ceres::Covariance covariance(cov_options);
  std::vector<std::pair<const double*, const double*>> blocks = {{&g, &g}, {&log_beta, &log_beta}};
  if (options.tau_free) blocks.push_back({&tau, &tau});
  if (!covariance.Compute(blocks, &problem)) {
    summary->result = PhaseFitSummary::Result::kFailure;
    summary->message = "g is not determined by the rings (covariance is rank-deficient)";
    finish();
    return Status::Error("FitPhase: " + summary->message);
  }
  const double scale = std::sqrt(std::max(1.0, summary->chi2_reduced));
  double var = 0;
  covariance.GetCovarianceBlock(&g, &g, &var);
  summary->sigma_g_covariance = std::sqrt(std::max(var, 0.0)) * scale;
  summary->sigma_g_jackknife = JackknifeSigmaG(options, *rings, &summary->jackknife_method);
  summary->sigma_g_range = RangeConsistencySigmaG(options, *rings, g, &summary->range_term_available);
  {
    const double r = options.layer_albedo * (1 - std::exp(-tau));
    // Capped: beyond 10x the first order the layer is no thin single-scattering layer at all.
    summary->predicted_second_order_fraction = std::min(r / (1 - r), 10.0);
    const double profile_spread =
        TwoOrderSigmaG(options, *rings, log_beta, g, tau, std::max(1.0, summary->chi2_reduced),
                       summary->predicted_second_order_fraction, &summary->second_order_fraction,
                       &summary->sigma_g_predicted_second_order);
    summary->sigma_g_multiple = std::max(profile_spread, summary->sigma_g_predicted_second_order);
  }
  summary->sigma_g = std::hypot(std::hypot(std::max(summary->sigma_g_covariance, summary->sigma_g_jackknife),
                                           summary->sigma_g_range),
                                summary->sigma_g_multiple);
  covariance.GetCovarianceBlock(&log_beta, &log_beta, &var);
  summary->sigma_log_beta = std::sqrt(std::max(var, 0.0)) * scale;
  if (options.tau_free) {
    covariance.GetCovarianceBlock(&tau, &tau, &var);
    summary->sigma_tau = std::sqrt(std::max(var, 0.0)) * scale;
  }
  summary->categories = ContaminantCategories(g, summary->sigma_g);
  // A noisy lobe (a short bracket, read noise) can leave g anywhere in [-1, 1]; the covariance
  // and jackknife say so, and the result must too rather than report a number.
  if (!(summary->sigma_g <= options.max_sigma_g)) {
    summary->result = PhaseFitSummary::Result::kFailure;
    std::ostringstream msg;
    msg.precision(3);
    msg << "g is not determined by the rings: g = " << g << " +- " << summary->sigma_g << " (covariance "
        << summary->sigma_g_covariance << ", jackknife " << summary->sigma_g_jackknife << ", angle range "
        << summary->sigma_g_range << ") exceeds max_sigma_g = " << options.max_sigma_g
        << "; the lobe is too noisy: lengthen the exposure bracket or average more frames";
    summary->message = msg.str();
    finish();
    return Status::Error("FitPhase: " + summary->message);
  }
  summary->warnings = ChiSquareWarnings(summary->chi2_reduced, dof, summary->num_rings);
  summary->result = PhaseFitSummary::Result::kSuccess;
  summary->message = std::abs(g) > 0.985 ? "g is at its bound (|g| > 0.985): the lobe is narrower than the rings resolve"
                                         : "ok";
  finish();
  return Status::Ok();
}

}  // namespace

Status FitPhase(const PhaseFitOptions& options, const LaserLobeImages& images, std::vector<LaserRing>* rings,
                PhaseFitSummary* summary) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  if (!options.max_theta_auto) {
    THINSLAB_RETURN_IF_ERROR(FitPhaseAtMaxTheta(options, images, rings, summary));
    summary->max_theta_deg = options.max_theta_deg;
    return Status::Ok();
  }
  const auto t0 = std::chrono::steady_clock::now();
  std::vector<double> candidates = options.max_theta_candidates_deg;
  std::sort(candidates.begin(), candidates.end());
  // The widest candidate's outcome stands when none succeeds: it has the most rings, so its
  // detection (or its error) is the most sensitive one.
  std::vector<std::pair<double, double>> trials;
  std::vector<std::pair<double, double>> successful_g;  // (angle, g) of the fits that succeeded.
  bool have_best = false;
  PhaseFitSummary best, widest;
  std::vector<LaserRing> best_rings, widest_rings;
  Status widest_status = Status::Ok();
  for (double theta : candidates) {
    PhaseFitOptions o = options;
    o.max_theta_auto = false;
    o.max_theta_deg = theta;
    PhaseFitSummary s;
    std::vector<LaserRing> r;
    const Status status = FitPhaseAtMaxTheta(o, images, &r, &s);
    s.max_theta_deg = theta;
    const bool usable = status.ok() && s.IsUsable();
    trials.emplace_back(theta, usable ? s.sigma_g : -1.0);
    if (usable) successful_g.emplace_back(theta, s.g);
    if (usable && (!have_best || s.sigma_g < best.sigma_g)) {
      have_best = true;
      best = s;
      best_rings = r;
    }
    widest = s;
    widest_rings = std::move(r);
    widest_status = status;
  }
  if (!have_best) {
    *summary = widest;
    *rings = std::move(widest_rings);
    summary->max_theta_trials = trials;
    return widest_status;
  }
  *summary = best;
  *rings = std::move(best_rings);
  summary->max_theta_trials = trials;
  if (have_best && successful_g.size() >= 2) {
    // The choice's own consistency term: the kept fit against its neighbour angle (the next
    // wider one, or the next narrower for the widest). The angle-range term only sees the bias
    // inside the kept range; a narrow range has few rings to see it with (g 0.9 at 30 degrees:
    // error 0.0037, sigma_g 0.0009 without this term, 0.0034 with it).
    size_t k = 0;
    while (successful_g[k].first != summary->max_theta_deg) ++k;
    const size_t neighbour = k + 1 < successful_g.size() ? k + 1 : k - 1;
    summary->sigma_g_choice = std::abs(summary->g - successful_g[neighbour].second);
    summary->sigma_g = std::hypot(summary->sigma_g, summary->sigma_g_choice);
    summary->categories = ContaminantCategories(summary->g, summary->sigma_g);
    if (!(summary->sigma_g <= options.max_sigma_g)) {
      summary->result = PhaseFitSummary::Result::kFailure;
      std::ostringstream msg;
      msg.precision(3);
      msg << "g is not determined by the rings: g = " << summary->g << " +- " << summary->sigma_g
          << " moves by " << summary->sigma_g_choice << " between outermost angles " << summary->max_theta_deg
          << " and " << successful_g[neighbour].first << " degrees, beyond max_sigma_g = " << options.max_sigma_g;
      summary->message = msg.str();
      return Status::Error("FitPhase: " + summary->message);
    }
  }
  summary->total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return Status::Ok();
}

Status PredictLaserLobe(const PhaseFitOptions& options, double beta, double g, double tau,
                        double fit_board_distance_m, const LaserLobeImages& images, LobePrediction* prediction) {
  *prediction = LobePrediction();
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  if (!(beta > 0) || !(g > -1 && g < 1) || !(tau > 0) || !(fit_board_distance_m > 0)) {
    return Status::Error("PredictLaserLobe: the fit's beta, g, tau and board distance must be > 0, (-1, 1), > 0, > 0");
  }
  THINSLAB_RETURN_IF_ERROR(MeasureLaserRings(options, images, &prediction->geometry, &prediction->rings));
  prediction->beam_centre_m = prediction->geometry.beam_centre_m;
  const double d = images.board_distance_m;
  prediction->board_distance_m = d;
  // Eq. 8's beta holds 1 / d^2 (board irradiance of a point source at distance d / cos theta).
  const double scale = beta * Sqr(fit_board_distance_m / d);
  prediction->scale = scale;
  double sum_pm = 0, sum_pp = 0;
  for (LaserRing& ring : prediction->rings) {
    ring.model = scale * LaserLobeProfile(std::cos(ring.theta_rad), g, tau);
    sum_pm += ring.model * ring.intensity;
    sum_pp += Sqr(ring.model);
  }
  // The scale that fits the measured rings best in the figure below (least squares, unweighted
  // as the relative RMS is): the shape compared alone.
  const double best = sum_pp > 0 ? sum_pm / sum_pp : 0;
  prediction->scale_ratio = best;
  const double edges_deg[] = {0, 15, 30, 45, 60, 90};
  for (int b = 0; b <= 5; ++b) {
    LobePredictionBand band;
    band.theta_min_deg = b < 5 ? edges_deg[b] : 0;
    band.theta_max_deg = b < 5 ? edges_deg[b + 1] : 90;
    double sum_meas2 = 0, sum_err2 = 0, sum_shape2 = 0, sum_var = 0;
    for (const LaserRing& ring : prediction->rings) {
      const double theta_deg = ring.theta_rad * 180 / kPi;
      if (theta_deg < band.theta_min_deg || theta_deg >= band.theta_max_deg) continue;
      ++band.rings;
      sum_meas2 += Sqr(ring.intensity);
      sum_err2 += Sqr(ring.model - ring.intensity);
      sum_shape2 += Sqr(best * ring.model - ring.intensity);
      sum_var += Sqr(ring.sigma);
    }
    if (band.rings == 0 || !(sum_meas2 > 0)) continue;
    band.relative_rms = std::sqrt(sum_err2 / sum_meas2);
    band.shape_relative_rms = std::sqrt(sum_shape2 / sum_meas2);
    band.noise_relative_rms = std::sqrt(sum_var / sum_meas2);
    prediction->bands.push_back(band);
  }
  if (prediction->rings.empty()) {
    return Status::Error("PredictLaserLobe: no ring with >= " + std::to_string(options.min_ring_pixels) +
                         " pixels in the measured lobe");
  }
  return Status::Ok();
}

}  // namespace thinslab
