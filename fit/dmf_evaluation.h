// SPDX-License-Identifier: Apache-2.0
// Accuracy of dual-microfacet maps against the ground truth of a simulated dot scan
// (<session>/ground_truth/truth.json, docs/format.md): per region, the fitted alpha, the NDF
// against the true face NDF (one-sided regions: a two-sided slab has no single true NDF) and
// the prediction of held-out dots.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "thinslab/core/progress.h"
#include "thinslab/core/status.h"
#include "thinslab/fit/dmf_map_fit.h"

namespace thinslab {

struct DmfTruthFace {
  std::string ndf = "ggx";  // "ggx" or "beckmann".
  double alpha_x = 0, alpha_y = 0;
  bool flat = true;
};

struct DmfTruthRegion {
  std::string name;
  Eigen::Vector2d min_m = Eigen::Vector2d::Zero(), max_m = Eigen::Vector2d::Zero();
  DmfTruthFace top, bottom;  // Top = monitor side.
  double rho_d = 0, k_s = 1;
  // The one rough face of a one-sided region (nullptr for smooth and two-sided regions).
  const DmfTruthFace* SingleRoughFace() const;
};

// Reads ground_truth/truth.json of a simulated session; an error names the file and field.
Status ReadDmfTruth(const std::string& session_dir, std::vector<DmfTruthRegion>* regions);

// True D(m) of a face in the optical frame of the fit (m.z > 0; the sample's y is flipped, which
// leaves the axis-aligned distributions unchanged).
double TrueNdf(const DmfTruthFace& face, const Eigen::Vector3d& m);

// Relative L2 distance over the disk, sqrt(sum (D_fit - D_true)^2 / sum D_true^2) over the grid
// cells; -1 when the point has no NDF.
double NdfRelativeL2(const DmfPointFit& fit, const DmfNdfGrid& grid, const DmfTruthFace& face);

struct DmfRegionAccuracy {
  std::string name;
  int points = 0, fitted = 0;     // Points at least one grid pitch inside the region; with an NDF.
  double median_alpha = -1;
  double median_ndf_l2 = -1;      // One-sided regions.
  double median_held_out = -1;    // Captures fitted with held-out dots.
  double median_k_s = -1, true_k_s = 1;
  double median_rho_d = -1, true_rho_d = 0;
  // Stability tally (docs/stability.md): points with status ok or interpolated, points with any
  // other status (flagged), and ok points whose held-out error exceeds the tolerance (silent
  // wrong answers); per status code, the number of points.
  int ok = 0, flagged = 0, silent_wrong = 0;
  std::map<int, int> statuses;
  // What the flags mean (issue #24 section 3), over the points with a fitted NDF: a point is
  // correct when its held-out error (captures with held-out dots) is within the tolerance, its
  // k_s within kDmfCorrectKsRatio of the truth and, on a one-sided region, alpha on the rough
  // face's side of 0.5; otherwise wrong. A flagged point (any status but ok and interpolated)
  // that is correct is a false alarm; a flagged wrong point is detected.
  int correct = 0, false_alarms = 0, wrong = 0, detected = 0;
  // The analytic NDF nearest to the tabulated one (fit/dmf_equivalent_roughness.h) against the
  // truth of a one-sided region (its face's roughness, sqrt(alpha_x alpha_y) when anisotropic;
  // -1 elsewhere): median equivalent roughness, and the share of fitted points whose family is
  // the true one, undecided, and whose rough face (from alpha) is the true one.
  double median_roughness = -1, true_roughness = -1;
  double family_right = -1, family_undecided = -1, face_right = -1;
  // Coverage of the error bars (issue #24 section 4), over the status-ok points with an NDF:
  // the share whose |estimate - truth| is within 1 and 2 sigma; -1 where the region has no
  // truth for it. Roughness: one-sided isotropic regions. alpha (top_face_weight): 1 on a
  // rough-top region, 0 on a rough-bottom one, 0.5 where both faces are the same.
  double roughness_within_1_sigma = -1, roughness_within_2_sigma = -1;
  double alpha_within_1_sigma = -1, alpha_within_2_sigma = -1;
  double FalseAlarmRate() const { return correct > 0 ? static_cast<double>(false_alarms) / correct : 0; }
};

// A fitted k_s within [1/r, r] times the true one counts as correct (the clean slab reads 0.75-1.3
// on the simulated rig, docs/models/dual_microfacet_fit.md; k_s is a model quantity).
constexpr double kDmfCorrectKsRatio = 1.5;

// `held_out_tolerance`: the held-out error above which an ok point counts as silently wrong.
// Slices in memory; the Status form also reads streamed slices band by band (ForEachPointBand)
// and returns the spill's read errors.
std::vector<DmfRegionAccuracy> CompareDmfWithTruth(const DmfSliceSet& slices, const DmfMaps& maps,
                                                   const std::vector<DmfTruthRegion>& regions,
                                                   double held_out_tolerance = 0.5);
// `progress` (core/progress.h) hears of the points done, in every Status form below.
// `held_out_errors` (optional): every point's held-out error as EvaluateHeldOutDots' point_errors
// gives it (the same as DmfHeldOutError's); without it each is predicted here again.
Status CompareDmfWithTruth(const DmfSliceSet& slices, const DmfMaps& maps, const std::vector<DmfTruthRegion>& regions,
                           double held_out_tolerance, std::vector<DmfRegionAccuracy>* accuracy,
                           const ProgressCallback& progress = ProgressCallback(),
                           const std::vector<double>* held_out_errors = nullptr);
std::string DmfComparisonJson(const std::vector<DmfRegionAccuracy>& accuracy);

// How well the fitted maps predict the capture's validation dots (DmfValidationDots; issue #23
// section 4), pooled over the (point, validation dot) pairs inside each point's lobe (measured
// R - rho_d at or above `lobe_fraction` of the point's largest over the validation dots), over
// the points with a fitted model (status ok or interpolated):
//   relative_rms = sqrt(sum (predicted - measured)^2 / sum (measured - rho_d)^2),
// and beside it what noise alone would give, sqrt(sum sigma^2 / sum (measured - rho_d)^2).
//
// The pooled figure is dominated by the brightest measurements. A point whose predicted dot is
// more than kUnsampledPeakFactor times above every training dot of that point has a lobe peak
// between the training dots (a specular component, a point mixing a smooth and a rough region
// at a region edge): no fit of those dots can predict it, and one such dot can outweigh all other
// points. Those points are counted, with their share of the pooled squared error, and the median
// of the points' own relative RMS is given beside the pooled one.
inline constexpr double kUnsampledPeakFactor = 3;
struct DmfValidationError {
  std::string region;  // "all", or a ground-truth region's name.
  int points = 0, pairs = 0;
  double relative_rms = -1, noise_relative_rms = -1;  // -1: no pair.
  double median_point_relative_rms = -1;              // -1: no pair.
  int unsampled_peak_points = 0;                      // Points with a peak between training dots.
  double unsampled_peak_error_share = 0;              // Their share of sum (predicted - measured)^2.
};
// "all" first, then one entry per region of `regions` (ground truth of a simulated capture; may
// be empty), points at least one grid pitch inside it as CompareDmfWithTruth.
// (The vector form: slices in memory; the Status form reads a streamed fit's bands.)
std::vector<DmfValidationError> EvaluateValidationDots(const DmfSliceSet& slices, const DmfMaps& maps,
                                                       const std::vector<DmfTruthRegion>& regions,
                                                       double lobe_fraction = 0.1);
// The points are scored on `num_threads` threads; the sums are the same whatever their number.
Status EvaluateValidationDots(const DmfSliceSet& slices, const DmfMaps& maps,
                              const std::vector<DmfTruthRegion>& regions, double lobe_fraction, int num_threads,
                              std::vector<DmfValidationError>* out,
                              const ProgressCallback& progress = ProgressCallback());

// The same for the grid's held-out dots (DmfSliceSet::train 0; `fit dmf --hold-out`): reported
// whenever dots are held out, with or without the model ladder.
// (Slices in memory; the Status form as CompareDmfWithTruth's.)
std::vector<DmfValidationError> EvaluateHeldOutDots(const DmfSliceSet& slices, const DmfMaps& maps,
                                                    const std::vector<DmfTruthRegion>& regions,
                                                    double lobe_fraction = 0.1);
// `point_errors` (optional): every point's relative RMS error on its held-out in-lobe dots
// (DmfHeldOutError's figure, flagged points included; -1 where none), for CompareDmfWithTruth.
Status EvaluateHeldOutDots(const DmfSliceSet& slices, const DmfMaps& maps, const std::vector<DmfTruthRegion>& regions,
                           double lobe_fraction, int num_threads, std::vector<DmfValidationError>* out,
                           const ProgressCallback& progress = ProgressCallback(),
                           std::vector<double>* point_errors = nullptr);

}  // namespace thinslab
