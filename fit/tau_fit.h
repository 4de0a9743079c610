// SPDX-License-Identifier: Apache-2.0
// Optical thickness map tau(x, y) from shadow maps (Gu et al. 2007, Sec. 5.1).
//
// Plain estimate, Gu Eq. 7: tau = -ln(I / I_clean). It is biased low wherever light the
// layer scatters forward (Eq. 6) lands near the unscattered light. The refinement models that
// light: with m = I / I_clean and S[tau] the Eq. 6 light from the whole layer on the board
// (optics/shadow_map_model.h) divided by I_clean, it solves
//   m = e^{-tau} + S[tau]
// by fixed-point iteration on S (S is a contraction: the layer scatters at most albedo of
// what it removes) and, in each iteration, a Ceres solve of the per-pixel Eq. 5 residuals
// with an edge-preserving (Huber) smoothness prior between neighbours.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "thinslab/calib/shadow_map_preparation.h"
#include "thinslab/core/image.h"
#include "thinslab/core/status.h"
#include "thinslab/core/parallel.h"
#include "thinslab/core/pixel_trace.h"

namespace thinslab {

// Per-pixel status codes written to the "status" channel (docs/format.md).
enum class TauPixelStatus : uint8_t {
  kOk = 0,
  kDark = 1,        // Reference or shadow signal too low to measure.
  kSaturated = 2,   // A contributing raw pixel saturated.
  kOutside = 3,     // Board point not seen by the camera.
  kClamped = 4,     // Transmission below e^{-tau_max}: tau set to tau_max.
  // Next to a clamped pixel: the camera pixels behind this one also see the bright side of the
  // edge, so tau reads far too low (a lower bound; docs/stability.md measured 2.5 for 5).
  kNextToClamped = 5,
  // Mixed (issue #24): tau changes by more than TauFitOptions::max_mixed_tau_step across the
  // larger of the map pixel and the camera's footprint, so the pixel reads -ln of a mean
  // transmission over very different thicknesses (an edge, texture the camera does not resolve).
  kMixed = 6,
};
// The names of codes 0..6, as summary.json's pixel counts and the status legend show them.
std::vector<std::string> TauPixelStatusNames();

struct TauFitOptions {
  // Model the scattered light (Eq. 6) instead of plain Eq. 7.
  bool refine_scattering = true;
  // Layer single-scattering albedo omega0 and HG g (unitless); given, e.g. from a laser-lobe
  // fit (Gu Eq. 8) or the category ranges of Gu Fig. 2.
  double layer_albedo = 0.3;
  double layer_g = 0.8;
  // "frame": the clean reference frames; "auto": a smooth (quadratic) surface fitted to the
  // automatically found clean regions of the shadow frame; "flat": the projector flat field
  // (calib/flat_field.exr, RectifiedShadowMaps::flat) times one scale fitted to those regions
  // (Gu Sec. 5.1; the flat is smoothed, so it assumes a board without texture). With "auto" and
  // "flat" the surface is refitted through the shadow less the modelled scattered light S
  // (Eq. 6) at every iteration of the fixed point until it moves by less than
  // outer_tolerance_tau (at most 10 refits).
  std::string reference = "frame";
  // Largest representable tau; darker pixels are clamped and flagged.
  double tau_max = 4.0;
  // Pixels whose reference is below this fraction of the median reference are dark.
  double min_reference_fraction = 0.1;
  // Pixels whose tau noise (the shot and read noise part of sigma_tau) exceeds this are dark
  // too: under low light the map is noise, not a measurement (docs/stability.md).
  double max_sigma_tau = 0.05;
  // Largest tau change across one footprint (the larger of the map pixel and the camera pixel's
  // square on the board) of a status-ok pixel; beyond it the pixel is kMixed. At 0.5, a pixel
  // half tau t, half t + 0.5 reads 0.03 low (-ln of the mean transmission).
  double max_mixed_tau_step = 0.5;
  // Standard deviation (in tau) of neighbour differences under the smoothness prior, beyond
  // which the Huber loss turns linear. 0 disables the prior (closed-form per-pixel update).
  // Off by default: on the simulated rig it did not lower the error at default or at 10x less
  // light, and costs 2-4x the time (docs/models/dirty_glass_tau.md has the figures).
  double smoothness_sigma_tau = 0;
  int max_outer_iterations = 15;      // Counted again from each refit of a judged reference.
  double outer_tolerance_tau = 2e-4;  // Stop when no pixel's tau moves more than this.
  double kernel_max_angle_deg = 80;   // Scattered light beyond this angle is neglected.
  int num_threads = DefaultThreadCount();
  // Reports the scattered-light iterations; returning false cancels the fit (core/progress.h).
  ProgressCallback progress;
  // One map pixel's data, iterations and result (`fit tau --pixel X,Y`).
  PixelTrace trace;

  bool Check(std::string* error) const;
};

struct TauMaps {
  Image tau;        // Channels: tau, tau_eq7 (Gu Eq. 7 alone), status, sigma_tau.
  // The frames' noise part of sigma_tau alone (the split-half check compares it).
  Image sigma_tau_noise;
  // I_clean the map was fitted with (DN/us, rectified): the reference frames, or the clean
  // surface of reference "auto" / "flat". What a validation shadow is predicted from.
  Image reference;
};

struct TauFitSummary {
  enum class Result { kNotRun, kSuccess, kFailure };
  Result result = Result::kNotRun;
  std::string message = "FitTau was not called.";
  int width = 0, height = 0;
  int64_t pixels_total = 0, pixels_fitted = 0, pixels_dark = 0, pixels_saturated = 0,
          pixels_outside = 0, pixels_clamped = 0, pixels_next_to_clamped = 0;
  int64_t pixels_dark_noise = 0;  // Of pixels_dark: flagged because sigma_tau > max_sigma_tau.
  int64_t pixels_mixed = 0;
  // The camera's footprint on the board (calib/board_rectification.h) over the pixels in view:
  // median, smallest, largest [m]; camera pixels per map pixel = (pitch / footprint)^2 at the
  // median. 0 when unknown.
  double camera_footprint_median_m = 0, camera_footprint_min_m = 0, camera_footprint_max_m = 0;
  double camera_pixels_per_map_pixel = 0;
  double pixel_pitch_m = 0;
  // Reference "auto" / "flat": the clean surface's relative misfit to the pixels judged clean,
  // beyond their noise (in sigma_tau as tau = -ln(I / I_clean) moves by d I_clean / I_clean).
  double reference_relative_sigma = 0;
  // Medians over status-ok pixels of the parts of sigma_tau (in quadrature): the frames' noise,
  // the reference's misfit, the multiple scattering Eq. 6 leaves out, the resolution term.
  double median_sigma_noise = 0, median_sigma_reference = 0, median_sigma_model = 0, median_sigma_resolution = 0;
  std::vector<std::string> warnings;
  // Reference "auto" / "flat": the pixels the clean surface was fitted through (judged clean);
  // -1 for "frame" (clean-glass frames, no judgement).
  int64_t pixels_judged_clean = -1;
  int outer_iterations = 0;
  double final_max_update_tau = 0;
  double mean_scattered_fraction = 0;  // Mean S / m over fitted pixels.
  double plain_s = 0, refine_s = 0, total_s = 0;

  bool IsUsable() const { return result == Result::kSuccess; }
  std::string BriefReport() const;
  std::string FullReport() const;
};

// Fills maps->tau (width x height of the rectified grid). Never writes NaN: pixels that
// cannot be measured get tau = 0 (or tau_max when clamped) and a status code; sigma_tau is the
// 1-sigma uncertainty of tau, in quadrature: the frames' shot and read noise, the clean
// reference's misfit (auto / flat), the light Eq. 6 leaves out (multiple scattering) and the
// resolution term (local tau gradient times the camera footprint); 0 where status is 1-3.
Status FitTau(const TauFitOptions& options, const RectifiedShadowMaps& data, TauMaps* maps,
              TauFitSummary* summary);

}  // namespace thinslab
