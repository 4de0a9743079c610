// SPDX-License-Identifier: Apache-2.0
// Exposure planning from a probe (issue #28, item 2). A fixed bracket is right for one rig and
// one sample: on a display whose black is not black, the screen's glow seen through the sample
// fills most of the range in the long exposure a rough lobe's tails need, so the lobes saturate
// and drown (docs/known_gaps.md: 11 of 100 dot-scan points fitted instead of 26). Before the
// session a short probe measures, in DN per microsecond,
//  - the brightest state the session will show (the all-dots frame without the sample: every
//    dot seen directly, brighter than any dot through the sample),
//  - the darkest (the display black with the sample in: the glow every dot frame carries), and
//  - a few dots through the sample (their lobes' peaks),
// and the bracket is chosen so that
//  - the shortest exposure keeps the brightest peak at `peak_fill` of the range,
//  - the longest lets the dimmest probed lobe's edge (edge_fraction of its peak) clear
//    `edge_sigmas` noise sigmas (shot noise of the lobe and the glow, read noise), but keeps the
//    glow below max_dark_fraction of the range and stays within max_exposure_us,
//  - neighbouring exposures are at most max_step_ratio apart (a pixel that saturates in one
//    is above 1/max_step_ratio of the range in the next shorter),
// all whole refresh periods of the display.
//
// The laser lobe's plan (ProbeAndPlanLaserExposures) probes the brightest state (the beam spot
// through clean glass), the darkest (laser off) and the lobe's ring at the fit's outermost angle,
// whose mean over its pixels is the signal of interest.
#pragma once

#include <string>
#include <vector>

#include "thinslab/acquire/exposure_bracket.h"
#include "thinslab/acquire/sample_changer.h"
#include "thinslab/core/status.h"
#include "thinslab/drivers/camera.h"
#include "thinslab/drivers/display.h"
#include "thinslab/drivers/laser.h"

namespace thinslab {

struct ExposurePlanOptions {
  double peak_fill = 0.5;  // Brightest peak in the shortest exposure, fraction of the range.
  // Glow (99th percentile of the black frame) in the longest exposure. High: a longer exposure
  // always gains signal to noise over the glow's shot noise, and the shorter exposures keep what
  // lobe and glow saturate together. Measured on the simulated 0.2 % black display (10 x 10
  // dots, 4 mm map, docs/acquisition.md "Exposure planning"): 0.1 -> 0 ok points at 8 mm,
  // 0.5 -> 79 correct of 400, 0.8 -> 86 (the cap then rules).
  double max_dark_fraction = 0.8;
  double edge_fraction = 0.05;   // A lobe's edge, fraction of its peak (the fit's alpha lobe core).
  double edge_sigmas = 10;       // Its signal to noise in the longest exposure.
  double min_exposure_us = 0;    // Floor of the shortest (0: one refresh period, or 1 us).
  double max_exposure_us = 1e7;  // Cap of the longest.
  double max_step_ratio = 16;
  // Frames the plan may take at the longest exposure, averaged: where the glow (or the cap)
  // stops the longest exposure before the dimmest lobe's edge reaches edge_sigmas, N frames
  // raise its signal to noise by sqrt(N) whatever the noise (shot or read). 1: never.
  int max_longest_frames = 1;
  double probe_exposure_us = 0;  // First probe exposure (0: one refresh period, or 1000 us).
  int settle_captures = 3;       // Captures per probe state; the last is measured.
  bool Check(std::string* error) const;
};

// One probed state and what it showed.
struct ProbeMeasurement {
  std::string label;          // "all dots without the sample", "black display", "dot (x, y)".
  double exposure_us = 0;     // The probe frame's exposure (unsaturated, or the shortest tried).
  double peak_dn_per_us = 0;  // Brightest pixel (bright states) or 99th percentile (black).
  bool saturated = false;     // Even the shortest probe exposure saturated: a lower bound.
  // > 0: the signal of interest is the measured level itself (a mean over pixels, e.g. a lobe's
  // ring), with this signal to noise at exposure_us, measured from the pixels' spread. The plan
  // scales it as sqrt(exposure) (shot noise; conservative where read noise dominates), so it
  // needs no gain. 0: the signal is edge_fraction of the peak, with the camera's noise model.
  double snr = 0;
};

struct ExposurePlan {
  std::vector<double> exposures_us;  // Ascending, whole refresh periods.
  int longest_frames = 1;            // Frames at the longest exposure (max_longest_frames).
  std::vector<ProbeMeasurement> probes;
  std::string why;  // One paragraph: which state set which end and by how much.
  // The laser plan with a flat-field source: the flat's own exposure (its brightest pixel at
  // peak_fill of the range, whole refresh periods); empty otherwise.
  std::vector<double> flat_exposures_us;
};

// Chooses the bracket from measured probes (pure; tested without devices). `brightest`: the
// brightest state; `black`: the darkest (may have peak 0); `lobes`: the signals of interest,
// dots through the sample or a lobe's ring (may be empty: then the longest is the glow limit or
// the cap). `camera`: saturation, black
// level and gain (1 e-/DN when unknown) of the frames.
Status PlanExposures(const ProbeMeasurement& brightest, const ProbeMeasurement& black,
                     const std::vector<ProbeMeasurement>& lobes, const CameraInfo& camera, double refresh_period_s,
                     const ExposurePlanOptions& options, ExposurePlan* plan);

// The probe on the devices: the all-dots pattern without the sample, the display black and
// `probe_dots` with the sample in `sample_state`, each at the probe exposure (halved while the
// peak saturates), then PlanExposures. Leaves the display black. Errors name the device.
Status ProbeAndPlanDotScanExposures(Camera* camera, Projector* projector, const SampleChanger& change_sample,
                                    const std::string& all_dots_pattern, const std::vector<Eigen::Vector2d>& probe_dots,
                                    const std::string& sample_state, double refresh_period_s,
                                    const ExposurePlanOptions& options, ExposurePlan* plan);

// Where the laser session's signal of interest lies: the lobe's ring at the fit's outermost
// angle on the board (Gu et al. 2007, Sec. 5.2, Fig. 9b).
struct LaserProbeGeometry {
  CameraInfo camera;  // Intrinsics and cam_from_sample (the manifest's camera).
  LaserInfo laser;    // The beam (origin and direction in the sample frame).
  double board_distance_m = 0;
  double outer_angle_deg = 60;  // The fit's outermost ring (PhaseFitOptions' largest candidate).
  double ring_width_deg = 2.5;  // The ring's pixels: angles in [outer - width, outer].
  bool Check(std::string* error) const;
};

// The camera pixels (row-major indices) of the ring: board points at scattering angles in
// [outer - width, outer] around where the beam meets the board. Empty when none is in view.
std::vector<int> LaserRingPixels(const LaserProbeGeometry& geometry);

// The probe on the devices: the laser on through `brightest_state` (clean glass when the session
// captures it: the unattenuated spot), the laser off with the contaminated sample, and the laser
// on through it at exposures growing max_step_ratio-fold from the spot's unsaturated one until
// the ring's mean clears edge_sigmas standard errors or the cap is reached; then PlanExposures.
// With a `flat_source` (nullptr: none), its flat field without the sample sets
// plan->flat_exposures_us. Leaves the laser off and the flat source dark. Errors name the device.
Status ProbeAndPlanLaserExposures(Camera* camera, Laser* laser, Projector* flat_source,
                                  const SampleChanger& change_sample, const std::string& brightest_state,
                                  const LaserProbeGeometry& geometry, const ExposurePlanOptions& options,
                                  ExposurePlan* plan);

// The exposure bracket for the camera's response (`acquire bracket`, kind "exposure_bracket";
// calib/response_recovery.h): the response is recovered where the frames' values fall, and the
// recovery's hat weights vanish outside [5 %, 95 %] of the range. So the shortest exposure puts
// the pattern's brightest pixel at `low_fill` of the range (the curve's low end is seen) and the
// longest its dimmest lit pixels (`dimmest_quantile` of the pixels above a tenth of the
// brightest) at `high_fill` (every lit pixel reaches its high end); exposures at most
// `max_step_ratio` apart (one stop: neighbouring exposures see each pixel at overlapping values),
// whole refresh periods, within the options' min..max_exposure_us.
struct ResponseBracketPlanOptions {
  double low_fill = 0.05;
  double high_fill = 0.95;
  double dimmest_quantile = 0.05;
  double max_step_ratio = 2;
  bool Check(std::string* error) const;
};
// Pure: from the brightest pixel's and the dimmest lit pixels' rates [DN/us].
Status PlanResponseBracket(const ProbeMeasurement& brightest, const ProbeMeasurement& dimmest, const CameraInfo& camera,
                           double refresh_period_s, const ExposurePlanOptions& options,
                           const ResponseBracketPlanOptions& response, ExposurePlan* plan);
// The probe on the devices: `pattern` without the sample (its brightest pixel and its dimmest lit
// pixels in one unsaturated frame), then PlanResponseBracket. Leaves the display black.
Status ProbeAndPlanResponseBracket(Camera* camera, Projector* projector, const SampleChanger& change_sample,
                                   const std::string& pattern, const ExposurePlanOptions& options,
                                   const ResponseBracketPlanOptions& response, ExposurePlan* plan);

// The display gamma session's bracket (`acquire gamma`; acquire/display_gamma_session.h): its
// brightest state, level 1, at `options.peak_fill` of the range in the shortest exposure; its
// dimmest signal, the first level above black (1/steps) less the display black, at
// `options.edge_sigmas` sigma in one pixel of the lit region (the pixels above half of level 1's
// 99th percentile, as calib gamma's region) in the longest; the black below max_dark_fraction
// (PlanExposures with edge_fraction 1). Leaves the display black.
Status ProbeAndPlanDisplayGammaExposures(Camera* camera, Projector* projector, const SampleChanger& change_sample,
                                         int steps, const ExposurePlanOptions& options, ExposurePlan* plan);

// The shadow-map session's one exposure (Gu et al. 2007, Sec. 5.1): its brightest state, the
// flat field through clean glass, at `options.peak_fill` of the range in its brightest pixel
// (whole refresh periods of the projector, within min..max_exposure_us); the projector-off
// frame's glow (99th percentile) is reported in the reasons when it fills more than
// max_dark_fraction. Leaves the projector dark. Errors name the device.
Status ProbeAndPlanShadowMapExposure(Camera* camera, Projector* projector, const SampleChanger& change_sample,
                                     const ExposurePlanOptions& options, ExposurePlan* plan);

}  // namespace thinslab
