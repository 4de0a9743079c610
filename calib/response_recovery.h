// SPDX-License-Identifier: Apache-2.0
// Recovery of a camera's radiometric response from an exposure bracket of a static scene.
//
//  - Debevec & Malik 1997 ("Recovering high dynamic range radiance maps from photographs"):
//    least squares for g(z) = ln L(z) and the log irradiance ln E_i of each sampled pixel,
//    from g(z_ik) = ln E_i + ln t_k (their Eq. 2), hat weights w(z) (Eq. 4) and a smoothness
//    term lambda * sum w(z) g''(z)^2 (Eq. 3).
//  - Robertson, Borman & Stevenson 2003 ("Estimation-theoretic approach to dynamic range
//    enhancement using multiple exposures"): alternating estimates of the irradiances
//    x_i = sum_k w t_k L(z_ik) / sum_k w t_k^2 and of L as the least-squares fit to the
//    t_k x_i of the samples that hit each level, until L stops changing.
//
// Not in the papers: both solve for L on a grid of knots (at most `max_knots`, linear
// interpolation between them) instead of one unknown per DN level, so 12- and 16-bit frames
// cost the same as 8-bit ones; the smoothness term is scaled by the number of data rows and the
// knot spacing, so lambda means the same for any sample count and knot count; and pixels are
// sampled deterministically, stratified over irradiance (by the sum of the bracket's values,
// which rises monotonically with irradiance), from a seeded permutation per stratum, so a larger
// sample count adds pixels to a smaller one's and the curve does not jump between runs (OpenCV's
// CalibrateDebevec draws pixels uniformly at random).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "thinslab/calib/response_io.h"
#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct ResponseFrame {
  const Image* dn = nullptr;   // Black level subtracted, DN.
  double exposure_time_us = 0;  // Exposure the camera reported applying.
  int bit_depth = 0;            // 8..16.
  std::string name;             // For messages; "" = "frame <k>".
};

enum class ResponseMethod { kDebevec, kRobertson };

struct ResponseRecoveryOptions {
  ResponseMethod method = ResponseMethod::kDebevec;
  double saturation_dn = 0;   // Raw saturation minus black level; samples at or above are unused.
  double black_level_dn = 0;  // Recorded in the result.
  int max_knots = 256;        // Knots = min(max_knots, saturation_dn + 1); 16..4096.
  int num_samples = 2000;     // Pixels sampled; >= 20.
  int num_strata = 64;        // Irradiance strata the samples are spread over; >= 1.
  // Debevec: weight of the integral of w(z) g''(u)^2 over u = z / z_sat in [0, 1], relative to
  // the mean squared data residual (ln units); >= 0.
  double smoothness_lambda = 1e-7;
  // Robertson: the same in linear DN (L''(u)^2 against squared residuals in DN); >= 0.
  double robertson_smoothness_lambda = 1e-6;
  int min_exposures = 3;      // Fewer distinct exposures are refused; >= 2.
  int max_iterations = 3000;  // Robertson.
  double tolerance = 1e-6;    // Robertson: stop when max |dL| / L(reference) falls below.
  double reference_dn = 0;    // L(reference) = reference; 0 = saturation_dn / 2.
  uint64_t seed = 1;

  bool Check(std::string* error) const;
};

struct ResponseRecoverySummary {
  int num_samples = 0;     // Pixels used.
  int num_rows = 0;        // Data equations (pixel, exposure) used.
  int num_knots = 0;
  int iterations = 0;      // Robertson.
  int monotonicity_fixes = 0;  // Knots raised to keep L non-decreasing.
  double rms_log_residual = 0;
  double dn_coverage = 0;  // BracketDnCoverage of the frames.
  double solve_s = 0;
  std::string BriefReport() const;
};

// `frames` in order of strictly increasing exposure, all the same size and bit depth.
Status RecoverResponse(const std::vector<ResponseFrame>& frames, const ResponseRecoveryOptions& options,
                       CameraResponse* response, ResponseRecoverySummary* summary);

// Share of the DN range a bracket's values cover, in [0, 1]: [0, saturation_dn) is cut into
// `num_bins` equal bins, and a bin counts when at least max(3, 1e-5 x the usable values) of the
// usable values (0 < z < saturation_dn - 0.5, over all frames) fall in it (a few hot or noisy
// pixels do not count). The response is constrained by data only where the bracket has values;
// a near-uniform scene gives one cluster per exposure and leaves the rest of the curve to the
// smoothness term (docs/models/radiometric_calibration.md, "Known limits").
double BracketDnCoverage(const std::vector<ResponseFrame>& frames, double saturation_dn, int num_bins = 32);

// Below this coverage `thinslab calib response` warns that the bracket constrains the curve poorly.
inline constexpr double kMinBracketDnCoverage = 0.5;

// A bracket `thinslab calib response` could use, for the automatic choice.
struct BracketCandidate {
  std::string name;
  int num_exposures = 0;
  int num_frames = 0;
  double dn_coverage = 0;  // BracketDnCoverage.
};

// Index of the bracket to recover the response from: the most distinct exposures; among those,
// the largest DN coverage (a near-uniform scene with as many exposures constrains the curve only
// at a few levels); then the most frames; then the first. -1 if `candidates` is empty.
int ChooseResponseBracket(const std::vector<BracketCandidate>& candidates);

// The stratified, seeded pixel sample used by RecoverResponse (exposed for tests): indices of
// pixels with at least one usable sample, spread over `num_strata` bands of irradiance.
std::vector<size_t> SampleBracketPixels(const std::vector<ResponseFrame>& frames, double saturation_dn,
                                        int num_samples, int num_strata, uint64_t seed);

}  // namespace thinslab
