// SPDX-License-Identifier: Apache-2.0
// HDR merge of an exposure bracket. Frame k holds black-subtracted values z_k (DN); the
// camera's inverse response L (calib/response_io.h; identity for a linear camera) turns each
// unsaturated sample into the radiance estimate x_k = (L(z_k) - D_k) / t_k in linear DN per
// microsecond, with D_k the linearised dark signal at that exposure (optional) and t_k the
// exposure the camera reported applying. Its variance is
//   var_k = (max(L(z_k), 0) / gain + read^2 + [L'(z_k)^2 / 12] + var(D_k)) / t_k^2
// (shot + read noise in the linear domain; the bracketed quantisation term only for a
// nonlinear response, whose steps in linear units vary with z).
//
// The merge is a weighted mean of the x_k:
//  - kInverseVariance (default): weights 1 / var_k, the optimal estimator for a linear sensor
//    (Granados et al. 2010); variance 1 / sum(w).
//  - kHat: Debevec & Malik 1997 Eq. 6 weights w(z) = min(z, z_sat - z) (or a given table);
//    variance sum(w^2 var_k) / sum(w)^2. With log_domain = true the mean is taken of ln x_k,
//    exactly Debevec & Malik Eq. 6 (and OpenCV's MergeDebevec).
// Unlike OpenCV's MergeDebevec (triangle weights 1 at z = 0 and z = 255), samples at or above
// saturation get zero weight whatever the weighting. A pixel whose unsaturated samples all have
// zero weight takes the longest unsaturated exposure's estimate; a pixel saturated in every
// frame keeps the estimate of the shortest exposure at its saturation level (a lower bound) and
// is flagged.
//
// Speed: when the frames declare their bit depth and hold integer raw values, each exposure's
// x, weight and w^2 var are tabulated over all 2^bit_depth raw values once, and the merge is a
// single pass over the pixels with table look-ups, split over rows between threads.
#pragma once

#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include "thinslab/calib/exposure_check.h"
#include "thinslab/calib/frame_noise.h"
#include "thinslab/calib/response_io.h"
#include "thinslab/core/image.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"
#include "thinslab/core/parallel.h"

namespace thinslab {

struct HdrFrame {
  HdrFrame() = default;
  HdrFrame(const Image* frame_dn, double exposure_us) : dn(frame_dn), exposure_time_us(exposure_us) {}

  const Image* dn = nullptr;  // Black level already subtracted.
  double exposure_time_us = 0;
  // Optional dark signal at this exposure in linear DN (black level subtracted, linearised
  // with the same response, averaged over dark_count frames); subtracted in the linear domain.
  const Image* dark_linear_dn = nullptr;
  int dark_count = 1;
  // Optional per-pixel variance of dn (the frame's own noise, e.g. a renderer's or HDR tool's
  // variance channel; docs/format.md variance_file), replacing the shot + read model for this
  // frame. Same size as dn; must outlive the call.
  const Image* variance_dn2 = nullptr;
  int bit_depth = 0;  // 0 = not declared. Declared depths must agree across the bracket.
  std::string name;   // For messages (e.g. the frame file); "" = "frame <k>".
};

enum class HdrWeighting { kInverseVariance, kHat };

struct HdrMergeOptions {
  double saturation_dn = 0;   // Raw saturation minus black level: samples at or above are dropped.
  double gain_e_per_dn = 0;   // 0: unknown, shot noise then taken as DN (gain 1).
  double read_noise_dn = 1;   // RMS read noise in DN.
  HdrWeighting weighting = HdrWeighting::kInverseVariance;
  bool log_domain = false;    // Average ln x_k (Debevec & Malik Eq. 6); only with kHat.
  // Inverse response; nullptr = linear camera. Must outlive the call.
  const CameraResponse* response = nullptr;
  // Black level (raw DN) of the frames: raw = z + black_level_dn indexes the tables.
  double black_level_dn = 0;
  // Optional weights per raw DN value (size 2^bit_depth) replacing the hat of kHat, e.g.
  // OpenCV's triangle. Saturated samples still get zero weight.
  std::vector<double> weight_table;
  int num_threads = DefaultThreadCount();        // Rows are split between this many threads.
  bool use_lookup_tables = true;

  bool Check(std::string* error) const;
};

struct HdrImage {
  Image radiance;        // Linear DN per microsecond.
  Image variance;        // (DN per microsecond)^2.
  Image all_saturated;   // 1 where every frame saturated.
  int64_t pixels_all_saturated = 0;
  int64_t pixels_fallback = 0;  // Unsaturated samples all had zero weight.
  bool used_lookup_tables = false;
};

Status MergeExposureBracket(const std::vector<HdrFrame>& frames, const HdrMergeOptions& options, HdrImage* hdr);

// Session level: loads `frames` (one camera's bracket of one scene) and `darks` of a capture,
// linearises the dark frames with `response` (nullptr = linear) and averages those of each
// exposure (dark frames with the frame's exposure within 0.1 %; otherwise those of the nearest
// exposure, counted in dark_exposure_mismatches), estimates the read noise in linear DN from the
// shortest exposure's darks (half the variance of the difference of two, or the spread of one;
// `fallback_read_noise_dn` without darks) unless `noise` (ResolveFrameNoise) knows the floor,
// takes the shot noise from `noise` when the camera declares no gain, uses each frame's
// variance_file where it has one, and merges. Saturation, black level, gain and
// bit depth come from the camera. Errors name the frame file.
struct SessionMergeInfo {
  int num_frames = 0;
  int num_exposures = 0;
  int num_darks = 0;
  int dark_exposure_mismatches = 0;  // Frames whose darks had another exposure.
  double read_noise_dn = 0;
  std::vector<double> exposures_us;
  // Unless ExposureCheckMode::kNone: measured / reported exposure per distinct exposure
  // (calib/exposure_check.h) of the reported exposures; Warning() says when the camera does not
  // apply what it reports.
  ExposureCheck exposure_check;
  bool merged_with_measured_exposures = false;
  FrameNoiseModel noise;   // The model the merge used (calib/frame_noise.h).
  int num_variance_files = 0;  // Frames that brought their own variance (variance_file).
};
enum class ExposureCheckMode {
  kNone,
  kCheck,         // Measure and report; merge with the reported exposures.
  kUseMeasured,   // Measure, and merge with reported x measured factor where it was measured.
};
Status MergeSessionBracket(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                           const std::vector<const FrameRecord*>& frames, const std::vector<const FrameRecord*>& darks,
                           const CameraResponse* response, HdrMergeOptions options, double fallback_read_noise_dn,
                           const FrameNoiseModel& noise, HdrImage* hdr, SessionMergeInfo* info,
                           ExposureCheckMode exposure_check = ExposureCheckMode::kNone);

// The dark frames of MergeSessionBracket loaded, linearised and averaged per exposure once, for
// a caller that merges many brackets against the same darks (a dot scan: one bracket per dot;
// reading and averaging the darks again for each cost as much as its merge).
struct SessionDarks {
  std::map<double, Image> linear;  // Mean linearised dark per exposure [us].
  std::map<double, int> count;     // Dark frames averaged into each.
  int num_frames = 0;
  double read_noise_dn = 0;        // DarkFrameReadNoise of the shortest exposure's; 0 without darks.
};
Status LoadSessionDarks(const std::string& session_dir, const Session& session,
                        const std::vector<const FrameRecord*>& darks, const CameraResponse* response,
                        SessionDarks* out);
Status MergeSessionBracket(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                           const std::vector<const FrameRecord*>& frames, const SessionDarks& darks,
                           const CameraResponse* response, HdrMergeOptions options, double fallback_read_noise_dn,
                           const FrameNoiseModel& noise, HdrImage* hdr, SessionMergeInfo* info,
                           ExposureCheckMode exposure_check = ExposureCheckMode::kNone);

// Read noise in linear DN from dark frames of one exposure (the shortest has the least dark
// current and ambient shot noise): half the variance of the difference of two of them (no fixed
// pattern), or the spread of a single one; at least 0.5 DN (the quantisation of integer frames).
double DarkFrameReadNoise(const std::vector<Image>& darks, const CameraResponse* response);

// The hat weight of Debevec & Malik 1997 (Eq. 4) on black-subtracted z in [0, z_sat],
// normalised to 1 at mid-range; 0 at and beyond both ends.
double HatWeight(double z_dn, double saturation_dn);

}  // namespace thinslab
