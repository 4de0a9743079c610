// SPDX-License-Identifier: Apache-2.0
// Dual-microfacet fit of one surface point's BTDF slice (Dai et al. 2009, Sec. 4.2).
//
// Model (Eq. 13): R(i, o) = rho_d + k_s rho(i, o), rho the dual-microfacet BTDF of
// optics/dual_microfacet_btdf.h (Eq. 11 interpolation of the virtual configurations, Eqs. 6
// and 10) with a tabulated NDF D and Smith shadowing of roughness smith_alpha (Walter et al.
// 2007, Eq. 23 with the GGX G1).
//
// Algorithm:
//  1. NDF step (Eqs. 15-17): one sparse linear least-squares problem in ln D per point,
//       alpha ln D(h_t) + (1 - alpha) ln D(h_b) = ln(R - rho_d) - alpha ln A_t - (1 - alpha) ln A_b
//     for every training measurement above the noise floor, plus the Laplacian smoothness rows
//     of Eq. 17 (weight `smoothness`), boundary cells fixed at ln 1e-6. k_s is not separated
//     here: the level of ln D absorbs ln k_s, and k_s is the projected integral of the solved D
//     (after which D is normalised). Solved by sparse Cholesky (Eigen SimplicialLDLT) of the
//     normal equations.
//  2. alpha step (Eq. 18): golden-section search on [0, 1] for the alpha whose predicted
//     BTDF-weighted mean incident direction matches the measured one, D fixed.
//  Alternate from alpha = 0.5 until alpha moves by less than `alpha_tolerance`, first with the
//  polar symmetry of Eq. 19 (mirror cells share one unknown), then once more without it.
//  3. Smith roughness (Sec. 4.2): Levenberg-Marquardt (Ceres) on the Eq. 15 residuals over
//     smith_alpha with alpha and the shape of D fixed (a free log level is fitted with it, since
//     G changes the level that D has absorbed); then one final NDF step at the new value.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <ostream>
#include <string>
#include <vector>

#include "thinslab/core/byte_buffer.h"
#include "thinslab/fit/dmf_equivalent_roughness.h"
#include "thinslab/fit/dmf_ndf_grid.h"

namespace thinslab {

// One surface point's measurements in the optical frame of optics/dual_microfacet_btdf.h
// (light side +z: i.z > 0, o.z < 0).
struct DmfSlice {
  Eigen::Vector3d o = Eigen::Vector3d(0, 0, -1);  // View direction (unit, o.z < 0).
  std::vector<Eigen::Vector3d> i;                 // Light direction of dot q (unit, i.z > 0).
  std::vector<double> value;                      // R(i_q, o) of Eq. 12 [1/sr].
  std::vector<double> sigma;                      // Its standard deviation [1/sr] (0: unknown).
  std::vector<double> solid_angle;                // Solid angle of dot q's grid cell seen from x [sr].
  std::vector<uint8_t> train;                     // 1: used by the fit; 0: held out.
  std::vector<uint8_t> edge;                      // Borders of the dot grid dot q is on (DmfGridBorder bits; empty: unknown).
  double rho_d = 0;                               // Diffuse term of Eq. 13 [1/sr] (Eq. 14).
  int num_dots() const { return static_cast<int>(i.size()); }
};

// Bits of DmfSlice::edge: the dot lies on the first or last column, the first or last row of the
// dot grid.
enum DmfGridBorder : uint8_t { kFirstColumn = 1, kLastColumn = 2, kFirstRow = 4, kLastRow = 8 };

enum class DmfStatus : uint8_t {
  kOk = 0,
  kNoLobe = 1,        // Fewer than min_measurements training dots above the noise floor.
  kSpecular = 2,      // Lobe narrower than the dot spacing (fewer than min_core_measurements dots
                      // in its core): NDF unresolved.
  kSaturated = 3,     // Too many of the point's dot measurements saturated.
  kOutside = 4,       // Point not seen by the camera or off the sample.
  kNotConverged = 5,  // Eq. 18 still moves alpha by more than max_alpha_residual (result kept).
  kInterpolated = 6,  // Clustered run: model interpolated from representatives (Eqs. 20-22).
  // Less than min_measured_ndf_fraction of the fitted NDF's projected mass lies in cells a
  // measurement constrains: the rest is the Eq. 17 smoothness filling gaps between sparse dots
  // or extrapolating a lobe wider than the monitor, so k_s (the NDF's integral) and the tails
  // are not measured. Also when the lobe is wider than the monitor (still above
  // max_edge_fraction of its peak on two opposite borders of the dot grid) or peaks on a border
  // dot (its maximum may lie beyond). The fit is kept; it predicts the dots it saw.
  kUndersampled = 7,
  // The fitted model transmits more than the light it receives (DmfPointFit::transmittance >
  // max_transmittance), k_s > max_k_s, or its normalised NDF transmits less than
  // min_unit_transmittance: the normalised NDF put its mass at half vectors that
  // transmit almost nothing (grazing cells, where ln A of Eq. 15 is very negative and any
  // level of D fits), so k_s is meaningless although the dots seen are predicted.
  kUnphysical = 8,
};
const char* DmfStatusName(DmfStatus status);
// DmfStatusName of codes 0..kUnphysical, for the status legend.
std::vector<std::string> DmfStatusNames();

struct DmfPointFitOptions {
  int ndf_resolution = 32;         // N: N x N cells of the orthographic NDF grid (Dai Table 1: 32 x 32).
  double eta = 1.5;                // Slab index over air (known, Dai Sec. 4.2).
  double smoothness = 0.03;        // Weight of the Eq. 17 Laplacian rows against the Eq. 16 rows.
  // What the NDF holds beyond the convex hull of the cells a measurement touches: "smooth", Eq.
  // 17's Laplacian fill towards the boundary value (Dai et al. 2009), which drops the mass of a
  // long (GGX) tail no dot reaches, so k_s reads low; "family", the analytic family (GGX or
  // Beckmann, isotropic) fitted to the measured cells, with their level, where it fits them
  // within ndf_tail_max_misfit (relative L2; else the smooth fill stays). Not in Dai et al.
  // (issue #24; docs/models/dual_microfacet_fit.md "The NDF's unmeasured tail").
  std::string ndf_tail = "family";
  // Measured (2026-12-08, 10 x 10 dots): one-sided isotropic regions' representatives read
  // 0.07-0.36 (10th-90th percentiles), anisotropic and two-sided ones 0.23-0.77 (medians
  // 0.38-0.65), where an isotropic tail overstates k_s.
  double ndf_tail_max_misfit = 0.35;
  double initial_smith_alpha = 0.2;  // Dai Sec. 4.2: "Iteration is first performed assuming alpha_b = 0.2".
  bool fit_smith_alpha = true;
  double alpha_tolerance = 0.01;   // Dai: stop when alpha changes by less than 0.01.
  int max_alpha_iterations = 10;   // Dai: "converges in fewer than 10 steps".
  // Status kNotConverged when Eq. 18 still moves alpha by more than this at the result
  // (DmfPointFit::alpha_residual). The iteration bisects a cycle that does not contract; before,
  // such 2-cycles (alpha jumping between 1 and 0.64) flagged 12 of 25 points of a rough-top
  // region on a dense-dot capture and left alpha at whichever iterate came last (issue #24
  // section 3, docs/stability.md "False alarms").
  double max_alpha_residual = 0.05;
  double golden_tolerance = 1e-3;  // Bracket width at which the golden-section search stops.
  // A measurement enters Eq. 16 when R - rho_d exceeds both this fraction of the slice's peak and
  // noise_sigmas standard deviations (its logarithm is meaningless below).
  double min_relative_value = 0.02;
  double noise_sigmas = 3;
  // Eq. 18 compares mean directions over the lobe core only (measurements above this fraction of
  // the peak): the far tails carry light that left through internal reflections and multiple
  // bounces (seen in the photon tracer), which the two virtual configurations do not model and
  // which would pull alpha towards the middle.
  double alpha_lobe_fraction = 0.3;
  // Fewer training dots than this inside the lobe core: the lobe is narrower than the dot
  // spacing (a smooth face), status kSpecular.
  int min_core_measurements = 3;
  int min_measurements = 8;        // Fewer usable training dots: status kNoLobe or kSpecular.
  // Below this measured share of the fitted NDF (DmfPointFit::measured_ndf_fraction): status
  // kUndersampled (docs/stability.md has the measured boundary).
  double min_measured_ndf_fraction = 0.5;
  // A lobe still above this fraction of its peak on two opposite borders of the dot grid is wider
  // than the monitor: the mass of D beyond it, and with it k_s, is extrapolated (status
  // kUndersampled). A lobe cut by one border only (a point whose lobe centre lies near the
  // monitor's edge) keeps its measured side and, by the symmetric first pass of Eq. 19, its
  // shape: that alone flagged up to all points of a region whose alpha, k_s and held-out
  // prediction were right (issue #24 section 3, docs/stability.md "False alarms").
  double max_edge_fraction = 0.5;
  // Above this directional transmittance: status kUnphysical. A non-absorbing slab transmits at
  // most 1; the margin covers noise and the Eq. 14 rho_d taken from the lobe's floor.
  double max_transmittance = 1.3;
  // Above this k_s: status kUnphysical. With D normalised (Dai Sec. 3) k_s is the slab's
  // transmittance over that of the unit model, about 1 for a clean non-absorbing slab (0.75-1.3
  // measured on the simulated rig); 4 leaves room for rho_d and calibration errors.
  double max_k_s = 4;
  // Below this transmittance per unit k_s (the normalised NDF's own directional transmittance):
  // status kUnphysical. The NDF put most of its mass at half vectors that send the light nowhere
  // near the hemisphere (grazing cells); k_s then scales up a model whose light is mostly not
  // seen. Measured (issue #24 section 3): points with k_s within 1.5 x the truth read 0.16-1.2
  // (5th percentile 0.18) over the stability matrix and five nine-region captures; the status-ok
  // points of a lobe wider than the monitor with k_s 3.0-3.5 (true 1) read 0.07.
  double min_unit_transmittance = 0.15;
  // The analytic family and roughness nearest to the fitted NDF (DmfPointFit::roughness).
  EquivalentRoughnessOptions roughness;
  // The point's measurements, alpha iterations and result (`fit dmf --pixel`); nullptr: none.
  std::ostream* trace = nullptr;
  bool Check(std::string* error) const;
  // Status kUnphysical: transmits more than max_transmittance, k_s above max_k_s, or less than
  // min_unit_transmittance per unit k_s.
  bool Unphysical(double transmittance, double k_s) const {
    return transmittance > max_transmittance || k_s > max_k_s || transmittance < min_unit_transmittance * k_s;
  }
  // Status kUndersampled: too little of the NDF measured, or the lobe runs past the monitor.
  bool Undersampled(double measured_ndf_fraction, const DmfSlice& slice) const;
};

struct DmfPointFit {
  DmfStatus status = DmfStatus::kNoLobe;
  double alpha = 0.5;        // Eq. 11 weight: 1 = rough top (monitor side), 0 = rough bottom.
  double smith_alpha = 0.2;  // Roughness of the Smith shadowing term.
  double k_s = 0;            // Eq. 13 scale [unitless]: integral of the unnormalised D.
  double rho_d = 0;          // [1/sr], copied from the slice.
  std::vector<double> log_ndf;  // ln D per cell (N*N, D normalised: projected integral 1); empty if not fitted.
  // The NDF was interpolated from representatives (Eq. 20); a map streamed under a memory budget
  // does not keep it in log_ndf (DmfMaps::FitWithNdf rebuilds it).
  bool ndf_interpolated = false;
  bool HasNdf() const { return !log_ndf.empty() || ndf_interpolated; }
  int alpha_iterations = 0;
  // |Eq. 18's alpha - alpha| at the result, D solved there: 0 at an exact fixed point; below
  // alpha_tolerance when the iteration converged; large where Eq. 18 jumps across the result.
  double alpha_residual = 0;
  int num_used = 0;             // Training measurements in Eq. 16.
  double log_rms_residual = 0;  // RMS of the Eq. 15 residuals in ln units at the solution.
  // The NDF beyond the measured cells' hull is the fitted family's tail (DmfPointFitOptions::
  // ndf_tail "family" and within its misfit limit); false: Eq. 17's fill (or interpolated).
  bool family_tail = false;
  // Share of the fitted NDF's projected integral in cells that an Eq. 16 row touches (the 2 x 2
  // bilinear footprint of either virtual configuration's half vector), of the table as Eq. 17
  // fills it (before a family tail, DmfPointFitOptions::ndf_tail); 0 when not fitted.
  double measured_ndf_fraction = 0;
  // Directional transmittance of the fitted model for this view, integral of R cos(theta_i)
  // d omega_i over the light hemisphere (energy conservation wants <= 1); 0 when not fitted.
  // Interpolated points (clustered runs) take their representatives', rescaled to their own
  // k_s and rho_d (fit/dmf_map_fit.cc).
  double transmittance = 0;
  // The analytic NDF nearest to log_ndf (fit/dmf_equivalent_roughness.h); interpolated points
  // take their representatives' weighted alphas and misfits.
  EquivalentRoughness roughness;
  // Split-half refit (DmfMapFitOptions::split_half): alpha and equivalent roughness fitted from
  // each half of the training dots, their differences (first half minus second); `split_fitted`
  // false where either half could not be fitted or no split was run.
  bool split_fitted = false;
  double split_alpha_difference = 0, split_roughness_difference = 0;
  // Standard deviations of alpha and of roughness.roughness (PoolSplitHalfSigmas and the model
  // terms of fit/dmf_map_fit.h); 0 where not estimated.
  double sigma_alpha = 0, sigma_roughness = 0;
};

// A fit packed for another process of the group (core/process_group.h) and read back: every
// field, bit for bit. Unpack returns false on a message of another layout.
void PackDmfPointFit(const DmfPointFit& fit, ByteWriter* out);
bool UnpackDmfPointFit(ByteReader* in, DmfPointFit* fit);

// DmfPointFit::transmittance: sum of R over a 64 x 64 grid of the unit disk of projected light
// directions (cos(theta) d omega = dx dy).
double DirectionalTransmittance(const DmfPointFit& fit, const DmfNdfGrid& grid, double eta, const Eigen::Vector3d& o);

// Dai Eq. 14, rho_d = min_q { R_q : I_q > 0.05 I_avg }, over the training dots of a slice whose
// dots lie on an nx x ny grid (row-major). The minimum of single noisy measurements is biased
// low by a few standard deviations, so each candidate enters as the mean of its 3 x 3 grid
// neighbourhood (candidates only). `fraction` is Dai's 0.05. 0 when no dot qualifies.
double EstimateDiffuse(const DmfSlice& slice, int nx, int ny, double fraction = 0.05);

// Largest R - rho_d over the training dots.
double TrainingPeak(const DmfSlice& slice);
// How far the lobe runs past two opposite borders of the dot grid (the monitor's outermost
// directions): per border, the largest R - rho_d of its training dots over the training peak;
// the result is the larger over the two axes of the smaller of the two opposite borders' values.
// 0 when the slice does not mark its border dots.
double LobeFractionAtOppositeEdges(const DmfSlice& slice);
// True when the largest training R - rho_d is on a border dot of the grid.
bool LobePeaksOnEdge(const DmfSlice& slice);
// Training dots whose R - rho_d can enter the logarithms of Eqs. 15-16: above
// min_relative_value of the training peak and noise_sigmas standard deviations.
std::vector<int> UsableTrainingDots(const DmfSlice& slice, const DmfPointFitOptions& options);

// What FitDualMicrofacetPoint would say before fitting: kNoLobe without usable training dots,
// kSpecular with fewer than min_measurements usable dots or min_core_measurements in the lobe
// core, else kOk. Cheap: the clustered map fit uses it so that unresolvable points keep their
// own status instead of borrowing a neighbour's NDF.
DmfStatus PrecheckSlice(const DmfSlice& slice, const DmfPointFitOptions& options);

// Fits one slice. `grid` must have options.ndf_resolution.
DmfPointFit FitDualMicrofacetPoint(const DmfSlice& slice, const DmfNdfGrid& grid, const DmfPointFitOptions& options);

// Predicted R(i, o) = rho_d + k_s rho(i, o) of a fit (0 where the model has no transmission).
double PredictDualMicrofacet(const DmfPointFit& fit, const DmfNdfGrid& grid, double eta, const Eigen::Vector3d& i,
                             const Eigen::Vector3d& o);

// k_s of the point of `slice` for the model shape (alpha, D, smith_alpha) in *fit: the mean log
// ratio of measurement to unit-scale prediction over the usable training dots (the closed-form
// minimum of the Eq. 15 objective in ln k_s; 1 when no dot is usable), and log_rms_residual: the
// RMS of the Eq. 15 log residuals with that k_s and fit->rho_d. One prediction per dot serves
// both. Returns the dots that entered k_s.
int ScaleShapeToSlice(const DmfSlice& slice, const DmfNdfGrid& grid, const DmfPointFitOptions& options,
                      DmfPointFit* fit);

// Relative RMS error of a prediction on the held-out dots of `slice` inside the lobe (measured
// R - rho_d above `lobe_fraction` of the held-out peak): sqrt(sum (pred - meas)^2 / sum
// (meas - rho_d)^2). -1 when no held-out dot is in the lobe. `predict` maps (i, o) to R.
template <typename Predict>
double HeldOutRelativeRms(const DmfSlice& slice, double lobe_fraction, const Predict& predict) {
  double peak = 0;
  for (int q = 0; q < slice.num_dots(); ++q) {
    if (!slice.train[q]) peak = std::max(peak, slice.value[q] - slice.rho_d);
  }
  double num = 0, den = 0;
  for (int q = 0; q < slice.num_dots(); ++q) {
    if (slice.train[q] || slice.value[q] - slice.rho_d < lobe_fraction * peak) continue;
    const double d = predict(slice.i[q], slice.o) - slice.value[q];
    num += d * d;
    den += (slice.value[q] - slice.rho_d) * (slice.value[q] - slice.rho_d);
  }
  return den > 0 ? std::sqrt(num / den) : -1;
}

}  // namespace thinslab
