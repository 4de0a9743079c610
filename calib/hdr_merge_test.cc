// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/hdr_merge.h"

#include <gtest/gtest.h>

#include <opencv2/photo.hpp>

#include <cmath>
#include <random>

#include "thinslab/calib/response_recovery.h"
#include "thinslab/sim/exposure_bracket_sim.h"

namespace thinslab {
namespace {

// A radiance ramp over 6 decades seen through a 3-exposure bracket of a 12-bit linear sensor
// with shot and read noise: the merge is linear (re-exposing it reproduces every unsaturated
// frame within noise), unbiased, never uses saturated samples, and flags pixels saturated in
// every frame.
TEST(HdrMerge, LinearUnbiasedAndIgnoresSaturation) {
  const int w = 600, h = 20;
  const double gain = 8, read = 3, saturation = 4000;
  const std::vector<double> exposures = {10, 100, 1000};
  Image truth(w, h);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) truth.at(x, y) = static_cast<float>(std::pow(10.0, -2.5 + 6.0 * x / (w - 1)));
  }
  std::mt19937 rng(4);
  std::normal_distribution<double> normal(0, 1);
  std::vector<Image> frames(exposures.size(), Image(w, h));
  std::vector<HdrFrame> bracket;
  for (size_t k = 0; k < exposures.size(); ++k) {
    for (size_t i = 0; i < truth.data().size(); ++i) {
      const double mean = truth.data()[i] * exposures[k];
      const double dn = mean + std::sqrt(mean / gain + read * read) * normal(rng);
      frames[k].data()[i] = static_cast<float>(std::min(std::round(dn), saturation));
    }
    bracket.push_back({&frames[k], exposures[k]});
  }
  HdrMergeOptions options;
  options.saturation_dn = saturation;
  options.gain_e_per_dn = gain;
  options.read_noise_dn = read;
  HdrImage hdr;
  ASSERT_TRUE(MergeExposureBracket(bracket, options, &hdr).ok());
  int flagged = 0, reexposed = 0, merged = 0;
  double sum_z = 0, sum_z2 = 0;
  for (size_t i = 0; i < truth.data().size(); ++i) {
    const double r = truth.data()[i];
    const double mean0 = r * exposures[0];
    // Within 5 sigma of saturation the noise decides: skip.
    if (std::abs(mean0 - saturation) < 5 * std::sqrt(mean0 / gain + read * read)) continue;
    if (mean0 >= saturation) {
      EXPECT_EQ(hdr.all_saturated.data()[i], 1) << i;
      ++flagged;
      continue;
    }
    EXPECT_EQ(hdr.all_saturated.data()[i], 0);
    const double z = (hdr.radiance.data()[i] - r) / std::sqrt(hdr.variance.data()[i]);
    ++merged;
    sum_z += z;
    sum_z2 += z * z;
    for (size_t k = 0; k < exposures.size(); ++k) {
      const double dn = frames[k].data()[i];
      if (dn >= saturation || r * exposures[k] < 50) continue;
      const double predicted = hdr.radiance.data()[i] * exposures[k];
      EXPECT_NEAR(predicted, dn, 5 * std::sqrt(dn / gain + read * read)) << "pixel " << i << " exposure " << k;
      ++reexposed;
    }
  }
  const double n = std::max(1, merged);
  EXPECT_GT(flagged, 0);
  EXPECT_GT(reexposed, 10000);
  EXPECT_NEAR(sum_z / n, 0.0, 0.1);                   // Unbiased.
  EXPECT_NEAR(std::sqrt(sum_z2 / n), 1.0, 0.15);      // The variance channel is calibrated.
}

TEST(HdrMerge, BadInputNamesTheProblem) {
  Image a(4, 4), b(5, 4);
  HdrMergeOptions options;
  options.saturation_dn = 100;
  HdrImage hdr;
  Status status = MergeExposureBracket({{&a, 10}, {&b, 100}}, options, &hdr);
  EXPECT_NE(status.message().find("5x4"), std::string::npos);
  status = MergeExposureBracket({{&a, 10}, {&a, 0}}, options, &hdr);
  EXPECT_NE(status.message().find("exposure_time_us"), std::string::npos);
  options.saturation_dn = 0;
  status = MergeExposureBracket({{&a, 10}}, options, &hdr);
  EXPECT_NE(status.message().find("HdrMergeOptions::saturation_dn"), std::string::npos);
  options.saturation_dn = 100;
  std::vector<HdrFrame> frames = {{&a, 10}, {&a, 100}};
  frames[0].bit_depth = 8;
  frames[1].bit_depth = 12;
  frames[1].name = "frames/cam0/b/1.png";
  status = MergeExposureBracket(frames, options, &hdr);
  EXPECT_NE(status.message().find("mixed bit depths: frame 'frames/cam0/b/1.png' has bit_depth 12"), std::string::npos)
      << status.message();
  frames[1].bit_depth = 8;
  frames[1].dn = nullptr;
  status = MergeExposureBracket(frames, options, &hdr);
  EXPECT_NE(status.message().find("frame 'frames/cam0/b/1.png': image missing"), std::string::npos) << status.message();
  status = MergeExposureBracket({}, options, &hdr);
  EXPECT_NE(status.message().find("no frames"), std::string::npos);
  frames[1].dn = &a;
  options.weighting = HdrWeighting::kHat;
  options.weight_table.assign(100, 1.0);
  status = MergeExposureBracket(frames, options, &hdr);
  EXPECT_NE(status.message().find("weight_table has 100 entries"), std::string::npos) << status.message();
  options.weight_table.clear();
  options.weighting = HdrWeighting::kInverseVariance;
  options.log_domain = true;
  status = MergeExposureBracket(frames, options, &hdr);
  EXPECT_NE(status.message().find("log_domain"), std::string::npos) << status.message();
}

// A bracket of a nonlinear camera (gamma 2.2 curve after the noise, 12 bits), simulated with
// shot/read noise, quantisation and saturation.
struct NonlinearBracket {
  BracketSimOptions sim;
  SimulatedBracket raw;
  std::vector<Image> dn;
  double saturation_dn = 0;

  explicit NonlinearBracket(int bit_depth, SimResponseCurve curve, double black_level_dn, double ambient = 0,
                            int darks = 0, double exposure_step_us = 1, double exposure_offset_us = 0) {
    sim.width_px = 200;
    sim.height_px = 100;
    sim.min_e_per_us = 0.03;
    sim.max_e_per_us = 300;
    sim.exposures_us = {30, 120, 480, 1920, 7680};
    sim.sensor.bit_depth = bit_depth;
    sim.sensor.black_level_dn = black_level_dn;
    sim.sensor.response = curve;
    sim.sensor.exposure_step_us = exposure_step_us;
    sim.sensor.exposure_offset_us = exposure_offset_us;
    sim.ambient_e_per_us = ambient;
    sim.dark_frames_per_exposure = darks;
    sim.seed = 21;
    EXPECT_TRUE(SimulateBracket(sim, &raw).ok());
    saturation_dn = sim.sensor.saturation_dn() - black_level_dn;
    for (const Image& r : raw.frames) dn.push_back(Subtract(r));
  }
  Image Subtract(const Image& raw_frame) const {
    Image out = raw_frame;
    for (float& v : out.data()) v -= static_cast<float>(sim.sensor.black_level_dn);
    return out;
  }
  std::vector<HdrFrame> Frames() const {
    std::vector<HdrFrame> frames;
    for (size_t k = 0; k < dn.size(); ++k) {
      HdrFrame f(&dn[k], raw.frame_exposures_us[k]);
      f.bit_depth = sim.sensor.bit_depth;
      frames.push_back(f);
    }
    return frames;
  }
  std::vector<ResponseFrame> ResponseFrames() const {
    std::vector<ResponseFrame> frames;
    for (size_t k = 0; k < dn.size(); ++k) frames.push_back({&dn[k], raw.frame_exposures_us[k], sim.sensor.bit_depth, ""});
    return frames;
  }
};

// Linearity through a recovered nonlinear response: re-exposing the merged radiance R gives
// R t_k, which must reproduce each unsaturated frame's linearised value L(z_k) within noise.
// Chi-square-like check: with inverse-variance weights cov(L(z_k) / t_k, R) = var(R), so
// (L(z_k) - R t_k)^2 / (var_k - var(R) t_k^2) averages to 1 (stated: within [0.8, 1.25]); the
// merge is also compared with the true scene (median ratio within 2 %). The whole chain
// (response recovery, merge) sees the frames labelled with `exposures_us`.
struct MergeLinearity {
  double chi2 = 0;
  int64_t samples = 0;
  double median_ratio_to_truth = 0;
};

MergeLinearity MeasureMergeLinearity(const NonlinearBracket& b, const std::vector<double>& exposures_us) {
  std::vector<ResponseFrame> response_frames = b.ResponseFrames();
  std::vector<HdrFrame> hdr_frames = b.Frames();
  for (size_t k = 0; k < exposures_us.size(); ++k) {
    response_frames[k].exposure_time_us = exposures_us[k];
    hdr_frames[k].exposure_time_us = exposures_us[k];
  }
  ResponseRecoveryOptions recovery;
  recovery.saturation_dn = b.saturation_dn;
  recovery.black_level_dn = b.sim.sensor.black_level_dn;
  CameraResponse response;
  EXPECT_TRUE(RecoverResponse(response_frames, recovery, &response, nullptr).ok());
  // The sensor's gain and read noise expressed in linear DN of the recovered response.
  const SimSensorOptions& sensor = b.sim.sensor;
  const double s_ref = sensor.InverseResponseCurve(response.reference_dn / b.saturation_dn);
  const double e_per_linear_dn = sensor.full_well_e * s_ref / response.reference_dn;
  HdrMergeOptions options;
  options.saturation_dn = b.saturation_dn;
  options.black_level_dn = b.sim.sensor.black_level_dn;
  options.gain_e_per_dn = e_per_linear_dn;
  options.read_noise_dn = sensor.read_noise_e / e_per_linear_dn;
  options.response = &response;
  HdrImage hdr;
  EXPECT_TRUE(MergeExposureBracket(hdr_frames, options, &hdr).ok());
  EXPECT_TRUE(hdr.used_lookup_tables);
  double sum_chi2 = 0;
  MergeLinearity out;
  std::vector<double> ratios;
  for (size_t i = 0; i < b.dn[0].data().size(); ++i) {
    const double r = hdr.radiance.data()[i], var_r = hdr.variance.data()[i];
    if (hdr.all_saturated.data()[i] > 0) continue;
    ratios.push_back(r * e_per_linear_dn / b.raw.scene_e_per_us.data()[i]);
    for (size_t k = 0; k < b.dn.size(); ++k) {
      const double z = b.dn[k].data()[i];
      const double t = exposures_us[k];
      if (z >= b.saturation_dn - 0.5 || z < 0.05 * b.saturation_dn) continue;  // Unsaturated, above the toe.
      const double l = response.Linearize(z);
      const double var_k = (std::max(l, 0.0) / options.gain_e_per_dn + options.read_noise_dn * options.read_noise_dn +
                            response.Slope(z) * response.Slope(z) / 12.0);
      const double denominator = var_k - var_r * t * t;
      if (denominator <= 0.05 * var_k) continue;  // The frame dominates the merge: no test power.
      sum_chi2 += (l - r * t) * (l - r * t) / denominator;
      ++out.samples;
    }
  }
  out.chi2 = out.samples > 0 ? sum_chi2 / out.samples : 0;
  if (!ratios.empty()) {
    std::nth_element(ratios.begin(), ratios.begin() + ratios.size() / 2, ratios.end());
    out.median_ratio_to_truth = ratios[ratios.size() / 2];
  }
  std::cout << "reduced chi2 " << out.chi2 << " over " << out.samples << " samples; median R / truth "
            << out.median_ratio_to_truth << "\n";
  return out;
}

TEST(HdrMerge, NonlinearResponseMergeIsLinearAndCalibrated) {
  const NonlinearBracket b(12, SimResponseCurve::kGamma, 64);
  const MergeLinearity m = MeasureMergeLinearity(b, b.raw.frame_exposures_us);
  ASSERT_GT(m.samples, 20000);
  EXPECT_GT(m.chi2, 0.8);
  EXPECT_LT(m.chi2, 1.25);
  EXPECT_NEAR(m.median_ratio_to_truth, 1.0, 0.02);
}

// A sensor that exposes whole 37 us line periods applies 37, 111, 481, 1924 and 7696 us for
// the requested 30, 120, 480, 1920 and 7680 us (-19 % to +23 % on the short ones). The chain
// calibrated with the applied exposures (what the camera reports, FrameRecord::exposure_time_us)
// meets the same linearity and scale tolerances; labelled with the requested ones it fails
// them, which shows the check can see an exposure error of this size.
TEST(HdrMerge, CoarseExposureStepsMergeLinearlyWithTheAppliedExposures) {
  const NonlinearBracket b(12, SimResponseCurve::kGamma, 64, 0, 0, 37.0);
  const std::vector<double> expected_applied = {37, 111, 481, 1924, 7696};
  ASSERT_EQ(b.raw.frame_exposures_us.size(), expected_applied.size());
  for (size_t k = 0; k < expected_applied.size(); ++k) EXPECT_DOUBLE_EQ(b.raw.frame_exposures_us[k], expected_applied[k]);
  const MergeLinearity applied = MeasureMergeLinearity(b, b.raw.frame_exposures_us);
  ASSERT_GT(applied.samples, 20000);
  EXPECT_GT(applied.chi2, 0.8);
  EXPECT_LT(applied.chi2, 1.25);
  EXPECT_NEAR(applied.median_ratio_to_truth, 1.0, 0.02);
  const MergeLinearity requested = MeasureMergeLinearity(b, b.sim.exposures_us);
  EXPECT_TRUE(requested.chi2 > 1.25 || std::abs(requested.median_ratio_to_truth - 1.0) > 0.02)
      << "labelled with the requested exposures: chi2 " << requested.chi2 << ", median R / truth "
      << requested.median_ratio_to_truth;
}

// The exposure check (calib/exposure_check.h) on a linear 12-bit camera.
ExposureCheck CheckExposures(const NonlinearBracket& b, const std::vector<double>& labels_us) {
  std::vector<HdrFrame> frames = b.Frames();
  for (size_t k = 0; k < frames.size(); ++k) frames[k].exposure_time_us = labels_us[k];
  HdrMergeOptions options;
  options.saturation_dn = b.saturation_dn;
  options.black_level_dn = b.sim.sensor.black_level_dn;
  options.read_noise_dn = b.sim.sensor.read_noise_e / b.sim.sensor.gain_e_per_dn();
  ExposureCheck check;
  EXPECT_TRUE(CheckBracketExposures(frames, options, &check).ok());
  return check;
}

// Dots of one scan share a bracket; each lobe measures the exposures it exposes well. Per
// exposure the factor from more pixels wins, unmeasured (-1) ones are filled from the other
// check, and a bracket of other exposures is refused.
TEST(ExposureCheck, ChecksOfOneBracketCombinePerExposure) {
  ExposureCheck a, b, combined;
  a.reported_us = b.reported_us = {10, 100, 1000};
  a.measured_over_reported = {-1, 1.02, 1};
  a.pixels = {20, 500, 0};
  b.measured_over_reported = {1.30, 1.05, 1};
  b.pixels = {150, 200, 0};
  ASSERT_TRUE(CombineExposureChecks(a, &combined));
  ASSERT_TRUE(CombineExposureChecks(b, &combined));
  EXPECT_EQ(combined.measured_over_reported, (std::vector<double>{1.30, 1.02, 1}));
  EXPECT_EQ(combined.pixels, (std::vector<int>{150, 500, 0}));
  EXPECT_TRUE(combined.measured);
  EXPECT_NEAR(combined.max_deviation, 0.30, 1e-12);
  EXPECT_NE(combined.Warning().find("10 us reported"), std::string::npos) << combined.Warning();
  ExposureCheck other = a;
  other.reported_us = {10, 100, 2000};
  EXPECT_FALSE(CombineExposureChecks(other, &combined));
  EXPECT_EQ(combined.measured_over_reported[0], 1.30);
}

// A camera that applies what it reports passes, also with coarse (reported) exposure steps.
TEST(ExposureCheck, ACameraThatAppliesWhatItReportsPasses) {
  for (double step_us : {1.0, 37.0}) {
    const NonlinearBracket b(12, SimResponseCurve::kLinear, 64, 0, 0, step_us);
    const ExposureCheck check = CheckExposures(b, b.raw.frame_exposures_us);
    ASSERT_TRUE(check.measured);
    ASSERT_EQ(check.reported_us.size(), 5u);
    for (size_t k = 0; k < 5; ++k) {
      EXPECT_GE(check.pixels[k], k + 1 < 5 ? kExposureCheckMinPixels : 0) << k;
      EXPECT_NEAR(check.measured_over_reported[k], 1.0, 0.003) << check.reported_us[k] << " us, step " << step_us;
    }
    EXPECT_EQ(check.Warning(), "");
  }
}

// A camera that integrates 15 us longer than it reports (e.g. a reset time), and one that
// rounds to 37 us lines but reports the requested exposure: the check measures each exposure's
// factor relative to the longest (within 0.5 % of the true one) and names them.
TEST(ExposureCheck, AnUnreportedOffsetOrRoundingIsMeasuredAndNamed) {
  const NonlinearBracket offset(12, SimResponseCurve::kLinear, 64, 0, 0, 1, 15);
  const std::vector<double>& reported = offset.raw.frame_exposures_us;  // 30 ... 7680.
  ExposureCheck check = CheckExposures(offset, reported);
  const double longest = reported.back();
  for (size_t k = 0; k < reported.size(); ++k) {
    const double truth = ((reported[k] + 15) / (longest + 15)) / (reported[k] / longest);
    std::printf("offset 15 us: %g us measured x%.4f, true x%.4f\n", reported[k], check.measured_over_reported[k], truth);
    EXPECT_NEAR(check.measured_over_reported[k] / truth, 1.0, 0.005) << reported[k];
  }
  EXPECT_NE(check.Warning().find("30 us reported"), std::string::npos) << check.Warning();
  EXPECT_NE(check.Warning().find("120 us reported"), std::string::npos) << check.Warning();

  const NonlinearBracket rounding(12, SimResponseCurve::kLinear, 64, 0, 0, 37);
  check = CheckExposures(rounding, rounding.sim.exposures_us);  // Labelled with the requests.
  const std::vector<double>& applied = rounding.raw.frame_exposures_us;  // 37, 111, 481, 1924, 7696.
  for (size_t k = 0; k < applied.size(); ++k) {
    const double truth = (applied[k] / applied.back()) / (rounding.sim.exposures_us[k] / rounding.sim.exposures_us.back());
    std::printf("37 us lines reported as requested: %g us measured x%.4f, true x%.4f\n", rounding.sim.exposures_us[k],
                check.measured_over_reported[k], truth);
    EXPECT_NEAR(check.measured_over_reported[k] / truth, 1.0, 0.005) << rounding.sim.exposures_us[k];
  }
  EXPECT_NE(check.Warning().find("30 us reported"), std::string::npos) << check.Warning();
}

// Saturated samples get zero weight: where the long exposures saturate, the merge equals the
// merge of the short exposures alone, for both weightings.
TEST(HdrMerge, SaturatedSamplesHaveZeroWeight) {
  const NonlinearBracket b(12, SimResponseCurve::kLinear, 64);
  for (HdrWeighting weighting : {HdrWeighting::kInverseVariance, HdrWeighting::kHat}) {
    HdrMergeOptions options;
    options.saturation_dn = b.saturation_dn;
    options.black_level_dn = 64;
    options.weighting = weighting;
    HdrImage all, short_only;
    std::vector<HdrFrame> frames = b.Frames();
    ASSERT_TRUE(MergeExposureBracket(frames, options, &all).ok());
    frames.resize(3);
    ASSERT_TRUE(MergeExposureBracket(frames, options, &short_only).ok());
    int tested = 0;
    for (size_t i = 0; i < b.dn[0].data().size(); ++i) {
      const bool long_saturated = b.dn[3].data()[i] >= b.saturation_dn && b.dn[4].data()[i] >= b.saturation_dn;
      const bool short_unsaturated = b.dn[2].data()[i] < b.saturation_dn;
      if (!long_saturated || !short_unsaturated) continue;
      ASSERT_EQ(all.radiance.data()[i], short_only.radiance.data()[i]) << i;
      ASSERT_EQ(all.variance.data()[i], short_only.variance.data()[i]) << i;
      ++tested;
    }
    EXPECT_GT(tested, 1000);
  }
}

// The table look-up path and the per-sample path compute the same merge.
TEST(HdrMerge, LookupTablesMatchDirectEvaluation) {
  const NonlinearBracket b(8, SimResponseCurve::kSCurve, 4);
  ResponseRecoveryOptions recovery;
  recovery.saturation_dn = b.saturation_dn;
  recovery.black_level_dn = 4;
  CameraResponse response;
  ASSERT_TRUE(RecoverResponse(b.ResponseFrames(), recovery, &response, nullptr).ok());
  for (bool log_domain : {false, true}) {
    HdrMergeOptions options;
    options.saturation_dn = b.saturation_dn;
    options.black_level_dn = 4;
    options.response = &response;
    options.weighting = log_domain ? HdrWeighting::kHat : HdrWeighting::kInverseVariance;
    options.log_domain = log_domain;
    HdrImage fast, slow;
    ASSERT_TRUE(MergeExposureBracket(b.Frames(), options, &fast).ok());
    options.use_lookup_tables = false;
    options.num_threads = 1;
    ASSERT_TRUE(MergeExposureBracket(b.Frames(), options, &slow).ok());
    EXPECT_TRUE(fast.used_lookup_tables);
    EXPECT_FALSE(slow.used_lookup_tables);
    for (size_t i = 0; i < fast.radiance.data().size(); ++i) {
      ASSERT_NEAR(fast.radiance.data()[i], slow.radiance.data()[i], 1e-5 * std::abs(slow.radiance.data()[i]) + 1e-9) << i;
    }
  }
}

// Dark frames (ambient light with the scene light off) are subtracted in the linear domain:
// with them the merge is unbiased against the scene; without them it carries the ambient.
TEST(HdrMerge, DarkFrameSubtraction) {
  const double ambient = 0.2;  // e-/us, about the scene's darker tenth.
  const NonlinearBracket b(12, SimResponseCurve::kLinear, 64, ambient, 2);
  const double gain = b.sim.sensor.gain_e_per_dn();
  std::vector<Image> dark_mean;
  for (size_t k = 0; k < b.sim.exposures_us.size(); ++k) {
    Image mean(b.dn[0].width(), b.dn[0].height());
    for (int d = 0; d < 2; ++d) {
      const Image dark = b.Subtract(b.raw.darks[2 * k + d]);
      for (size_t i = 0; i < mean.data().size(); ++i) mean.data()[i] += 0.5f * dark.data()[i];
    }
    dark_mean.push_back(mean);
  }
  HdrMergeOptions options;
  options.saturation_dn = b.saturation_dn;
  options.black_level_dn = 64;
  options.gain_e_per_dn = gain;
  options.read_noise_dn = b.sim.sensor.read_noise_e / gain;
  std::vector<HdrFrame> with_dark = b.Frames();
  for (size_t k = 0; k < with_dark.size(); ++k) {
    with_dark[k].dark_linear_dn = &dark_mean[k];
    with_dark[k].dark_count = 2;
  }
  HdrImage corrected, uncorrected;
  ASSERT_TRUE(MergeExposureBracket(with_dark, options, &corrected).ok());
  ASSERT_TRUE(MergeExposureBracket(b.Frames(), options, &uncorrected).ok());
  double sum_z = 0, sum_z2 = 0, bias_uncorrected = 0;
  int64_t n = 0;
  for (size_t i = 0; i < corrected.radiance.data().size(); ++i) {
    if (corrected.all_saturated.data()[i] > 0) continue;
    const double truth = b.raw.scene_e_per_us.data()[i] / gain;
    const double z = (corrected.radiance.data()[i] - truth) / std::sqrt(corrected.variance.data()[i]);
    sum_z += z;
    sum_z2 += z * z;
    bias_uncorrected += uncorrected.radiance.data()[i] - truth;
    ++n;
  }
  std::cout << "dark-corrected mean z " << sum_z / n << ", rms z " << std::sqrt(sum_z2 / n)
            << "; uncorrected mean bias " << bias_uncorrected / n << " DN/us (ambient " << ambient / gain << ")\n";
  EXPECT_NEAR(sum_z / n, 0.0, 0.1);
  EXPECT_NEAR(std::sqrt(sum_z2 / n), 1.0, 0.2);
  EXPECT_NEAR(bias_uncorrected / n, ambient / gain, 0.2 * ambient / gain);
}

// Agreement with OpenCV's MergeDebevec on an 8-bit stack with the same response and weights
// (OpenCV's triangle, w(z) = z + 1 below 128 and 256 - z above, passed as the weight table, and
// the log-domain mean of Debevec & Malik Eq. 6). Where no frame is saturated or black, the
// two agree to float precision (stated: relative difference < 1e-4). Where the long frames
// saturate, OpenCV still gives the saturated samples weight 1 (its known defect) and is
// biased low, while this merge drops them.
TEST(HdrMerge, AgreesWithOpenCvMergeDebevec) {
  const NonlinearBracket b(8, SimResponseCurve::kGamma, 0);
  ResponseRecoveryOptions recovery;
  recovery.saturation_dn = b.saturation_dn;
  CameraResponse response;
  ASSERT_TRUE(RecoverResponse(b.ResponseFrames(), recovery, &response, nullptr).ok());
  cv::Mat cv_response(256, 1, CV_32F);
  std::vector<double> triangle(256);
  for (int z = 0; z < 256; ++z) {
    cv_response.at<float>(z) = static_cast<float>(std::max(response.Linearize(z), 1e-3));
    triangle[z] = z < 128 ? z + 1.0 : 256.0 - z;
  }
  std::vector<cv::Mat> images;
  std::vector<float> times;
  for (size_t k = 0; k < b.dn.size(); ++k) {
    cv::Mat image(b.dn[k].height(), b.dn[k].width(), CV_8U);
    for (int y = 0; y < image.rows; ++y) {
      for (int x = 0; x < image.cols; ++x) image.at<uint8_t>(y, x) = static_cast<uint8_t>(b.dn[k].at(x, y));
    }
    images.push_back(image);
    times.push_back(static_cast<float>(b.raw.frame_exposures_us[k]));
  }
  cv::Mat cv_hdr;
  cv::createMergeDebevec()->process(images, cv_hdr, times, cv_response);
  HdrMergeOptions options;
  options.saturation_dn = b.saturation_dn;
  options.response = &response;
  options.weighting = HdrWeighting::kHat;
  options.log_domain = true;
  options.weight_table = triangle;
  HdrImage hdr;
  ASSERT_TRUE(MergeExposureBracket(b.Frames(), options, &hdr).ok());
  int compared = 0, saturated_pixels = 0;
  double worst = 0, ours_error = 0, opencv_error = 0;
  const double gain = b.sim.sensor.full_well_e *
                      b.sim.sensor.InverseResponseCurve(response.reference_dn / b.saturation_dn) / response.reference_dn;
  for (int y = 0; y < cv_hdr.rows; ++y) {
    for (int x = 0; x < cv_hdr.cols; ++x) {
      bool clean = true, long_saturated = false;
      for (const Image& dn : b.dn) {
        const float z = dn.at(x, y);
        clean &= z > 0 && z < 255;
      }
      long_saturated = b.dn[2].at(x, y) >= 255 && b.dn[1].at(x, y) < 255;
      const double ours = hdr.radiance.at(x, y), theirs = cv_hdr.at<float>(y, x);
      if (clean) {
        worst = std::max(worst, std::abs(ours / theirs - 1));
        ++compared;
      } else if (long_saturated) {
        const double truth = b.raw.scene_e_per_us.at(x, y) / gain;
        ours_error += std::log(ours / truth);
        opencv_error += std::log(theirs / truth);
        ++saturated_pixels;
      }
    }
  }
  std::cout << compared << " unsaturated pixels: max relative difference " << worst << "; " << saturated_pixels
            << " pixels saturated in the three longest frames: mean log error thinslab " << ours_error / saturated_pixels
            << ", OpenCV " << opencv_error / saturated_pixels << "\n";
  EXPECT_GT(compared, 2000);
  EXPECT_LT(worst, 1e-4);
  ASSERT_GT(saturated_pixels, 1000);
  EXPECT_LT(std::abs(ours_error / saturated_pixels), 0.005);
  EXPECT_LT(opencv_error / saturated_pixels, -0.02);  // OpenCV's saturated samples pull it down.
}

}  // namespace
}  // namespace thinslab
