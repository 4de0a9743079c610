// SPDX-License-Identifier: Apache-2.0
// The noise of a camera's frame values, declared by the manifest or estimated from the capture.
//
// Model (Poissonian-Gaussian, as Foi et al. 2008 fit raw sensor data): a frame value v (black
// level subtracted, before dividing by the exposure) has
//   var(v) = variance_floor + variance_per_value * max(v, 0),
// read noise squared plus shot noise (variance_per_value = 1 / gain in e-/DN). Renderer output
// (Monte Carlo noise) follows the same form closely enough to weight and to cut at 3 sigma.
//
// Why estimate: with no gain in the manifest thinslab used gain 1 and 1 DN of read noise, so
// every sigma, 3-sigma cut and "within noise" test depended on the value scale the writer
// chose (issue #23). Both estimators below are equivariant: scaling every value by s scales
// the floor by s^2 and the per-value slope by s, so every decision made in sigma units is the
// same at any scale.
//  - Repeated frames (two frames of one light state and exposure): d = (a - b) / sqrt(2) has
//    the variance of one frame at the level (a + b) / 2, whatever the scene's texture.
//  - A single frame: Immerkaer's (1996) residual, the image convolved with
//    [1 -2 1; -2 4 -2; 1 -2 1] / 6, which cancels constant and linear structure and has the
//    frame's noise variance. Structure at the scale of a pixel inflates it, so only weak-texture
//    samples are kept (after Liu, Tanaka and Okutomi 2013): those whose 5 x 5 neighbourhood of
//    residuals has a mean square below the 99 % quantile pure noise would give at the fitted
//    line's variance, iterated with the line; the robust variance of the kept samples is
//    corrected by the factor that selection has on pure noise (both by simulation, once).
//    Texture finer than the camera everywhere still reads as noise; the per-level median (not
//    the mean) keeps what is left of sparse edges from doing so.
// Per signal level (up to 64 equal-count bins of the local mean, narrow so that a bin does not
// mix very different variances) the variance is the squared robust
// sigma 1.4826 * median|r|; a least-squares line through the bins, weighted by count / var^2
// (relative errors), gives floor and slope, both clamped at >= 0.
#pragma once

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "thinslab/core/image.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct FrameNoiseModel {
  // Read-noise variance [value^2]; nullopt = not known (the caller's dark-frame estimate or
  // default applies; only with a declared gain).
  std::optional<double> variance_floor;
  double variance_per_value = 1;  // Shot-noise variance per unit of value (1 / gain).
  // "declared" (manifest gain and read_noise_dn), "declared_gain" (gain only), "repeated_frames",
  // "single_frame_residual", or "default" (nothing to estimate from).
  std::string method = "default";
  int64_t samples = 0;  // Pixels (or pixel pairs) of the estimate.
  int levels = 0;       // Signal levels the line was fitted to.
  bool estimated() const { return method == "repeated_frames" || method == "single_frame_residual"; }
  double Variance(double v) const { return variance_floor.value_or(0.0) + variance_per_value * (v > 0 ? v : 0.0); }
  // For HdrMergeOptions: gain (e-/DN; very large when there is no shot noise) and read noise.
  double gain_e_per_dn() const;
  double read_noise_dn(double fallback) const;
  std::string Describe() const;
  // {"method", "variance_floor" (null when unknown), "variance_per_value", "samples", "levels"}:
  // what every summary.json records under "noise".
  nlohmann::ordered_json ToJson() const;
};

// Samples of the two estimators; frames hold black-subtracted values, `saturation` is the
// black-subtracted saturation level (pixels at or above it, and their neighbours, are left out).
struct NoiseSamples {
  std::vector<float> level, residual;  // residual has the variance of one frame value at level.
  // Single frames only: the mean squared residual of the 5 x 5 residuals around the sample,
  // which the fit compares with the noise its line predicts to leave textured places out.
  std::vector<float> texture;
  static constexpr int kTextureRadius = 2;
  void AddRepeatedPair(const Image& a, const Image& b, double saturation, int stride);
  void AddSingleFrame(const Image& frame, double saturation, int stride);
};

// Fits the model to the samples; fails with a message when there are too few (< 200).
Status FitNoiseModel(const NoiseSamples& samples, const std::string& method, bool integer_frames,
                     FrameNoiseModel* model);

// The noise of `camera`'s frames in a capture: the manifest's declaration when it gives the
// gain (gain_e_per_dn > 0; with read_noise_dn the floor too), else an estimate from the usable
// frames of that camera (pairs of frames of one light state and exposure where the capture has
// them, else single frames), else, for integer frames or linear frames that each bring a
// variance_file, the old default (gain 1, floor unknown) with method "default"; linear frames
// without either fail naming the camera. `saturation_dn` follows the camera (raw DN minus black
// level).
Status ResolveFrameNoise(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                         FrameNoiseModel* model);

}  // namespace thinslab
