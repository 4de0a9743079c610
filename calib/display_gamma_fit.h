// SPDX-License-Identifier: Apache-2.0
// Display gamma from a "display_gamma" session (acquire/display_gamma_session.h; docs/drivers.md,
// "Gamma"). Each level's exposure bracket (one per repeat) is dark-subtracted, linearised through
// the camera response and HDR-merged (calib/hdr_merge.h, MergeSessionBracket) into radiance
// [linear DN/us], without its frames that come near saturation. The signal of a bracket is a robust mean over the lit region: the pixels whose
// level-1 radiance exceeds `lit_fraction` of that image's `lit_percentile` percentile and that
// are not saturated in every exposure of any bracket (their estimate would be a lower bound).
// Within the region, pixels whose ratio to their level-1 radiance is further than
// `outlier_mads` scaled MADs from the median ratio (hot pixels, cosmic rays) are left out, and
// the kept pixels' sum is scaled by their share of the level-1 sum, so a level whose outliers
// differ is not biased. FitGammaTable (drivers/display_gamma.h) turns the (level, signal) pairs
// into the table.
#pragma once

#include <string>
#include <vector>

#include "thinslab/calib/response_io.h"
#include "thinslab/core/session.h"
#include "thinslab/core/status.h"
#include "thinslab/drivers/display_gamma.h"

namespace thinslab {

struct DisplayGammaFitOptions {
  double lit_fraction = 0.5;     // (0, 1): region threshold relative to the percentile below.
  double lit_percentile = 0.99;  // (0, 1]: percentile of the level-1 radiance the threshold refers to.
  // A frame with more than max_near_saturated_fraction of its pixels at or above near_saturation
  // of the saturation level (black level removed) is left out of its bracket (see the .cc).
  double near_saturation = 0.8;               // (0, 1].
  double max_near_saturated_fraction = 0.001;  // [0, 1).
  // [0, 1): more of the lit pixels saturated at every exposure of some level is an error (the
  // exposures are too long for the display).
  double max_saturated_fraction = 0.5;
  double outlier_mads = 5;       // > 0: half-width of the accepted ratio band, in scaled MADs (1.4826 MAD).
  double fallback_read_noise_dn = 1;  // Read noise for the merge when the session has no dark frames [DN].

  bool Check(std::string* error) const;
};

struct DisplayGammaMeasurement {
  double level = 0;          // Drive level of the pattern "flat:<level>".
  int repeat = 0;            // 0-based: the how-many-th bracket of this level.
  int num_frames = 0;        // Frames merged.
  double signal = 0;         // Robust mean radiance over the lit region [linear DN/us].
  double light = 0;          // (signal - signal(0)) / (signal(1) - signal(0)), means over repeats.
  double residual = 0;       // light - table value at `level` (fit residual, fraction of full light).
  std::string first_file;    // First frame of the bracket, for messages.
};

struct DisplayGammaFitSummary {
  bool ok = false;
  std::string message = "FitDisplayGammaSession was not called.";
  GammaTable table;
  std::vector<DisplayGammaMeasurement> measurements;  // In session order.
  int num_levels = 0;
  int num_darks = 0;
  int64_t lit_pixels = 0;            // Pixels of the lit region.
  int64_t pixels_saturated = 0;      // Above the threshold but saturated in every exposure of a bracket.
  int frames_near_saturation = 0;    // Frames left out of their bracket (near_saturation).
  int64_t outliers_rejected = 0;     // Region pixels left out by the ratio MAD band, summed over brackets.
  double rms_residual = 0;           // Over measurements, fraction of full light.
  double max_abs_residual = 0;
  double repeat_rms = 0;             // RMS difference of a repeat from its level's mean (0 without repeats).
  double power_exponent = 0;         // Least-squares gamma of light = level^gamma (information only).
  std::string response;              // Response used ("linear" or the file).

  std::string BriefReport() const;
  std::string FullReport() const;    // BriefReport plus one line per level.
};

// Fits the gamma table of the first camera's view of the session. Errors name the manifest or
// the frame file: no "level" frames, a level frame whose pattern is not "flat:<level>", no
// frame of level 1 (or 0), fewer than 3 levels, a level whose every exposure comes near
// saturation, most of the lit region saturated (more than
// max_saturated_fraction), and a display that is never lit (signal(1) - signal(0) not above
// five level-0 pixel sigmas, which includes signal(1) <= signal(0)).
Status FitDisplayGammaSession(const std::string& session_dir, const Session& session, const CameraResponse* response,
                              const DisplayGammaFitOptions& options, DisplayGammaFitSummary* summary);

}  // namespace thinslab
