// SPDX-License-Identifier: Apache-2.0
// Response recovery on simulated brackets (sim/exposure_bracket_sim): a known nonlinear camera
// curve, photon and read noise, quantisation and saturation. The forward model (noise before the
// curve, Poisson at low counts, rounding, clipping) is more complete than the noise-free
// g(z) = ln E + ln t that Debevec & Malik fit.
#include "thinslab/calib/response_recovery.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "tests/testing/temp_dir.h"

#include "thinslab/calib/hdr_merge.h"
#include "thinslab/sim/exposure_bracket_sim.h"

namespace thinslab {
namespace {

struct Bracket {
  BracketSimOptions sim;
  SimulatedBracket raw;
  std::vector<Image> dn;  // Black subtracted.
  double saturation_dn = 0;

  std::vector<ResponseFrame> Frames(const std::vector<int>& which = {}) const {
    std::vector<ResponseFrame> frames;
    for (size_t k = 0; k < dn.size(); ++k) {
      if (!which.empty() && std::find(which.begin(), which.end(), static_cast<int>(k)) == which.end()) continue;
      frames.push_back({&dn[k], raw.frame_exposures_us[k], sim.sensor.bit_depth, "f" + std::to_string(k)});
    }
    return frames;
  }
  // True inverse response, in the normalisation of CameraResponse (L(ref) = ref).
  double TrueLinear(double z, double reference) const {
    auto inverse = [&](double v) { return sim.sensor.InverseResponseCurve(v / saturation_dn); };
    return reference * inverse(z) / inverse(reference);
  }
};

// The scene spans `min_e_per_us`..`max_e_per_us` (the defaults: ~4 decades, a wide-range scene).
Bracket MakeBracket(int bit_depth, SimResponseCurve curve, uint64_t seed = 3, double min_e_per_us = 0.03,
                    double max_e_per_us = 300, double texture_amplitude = 0.2) {
  Bracket b;
  b.sim.width_px = 200;
  b.sim.height_px = 120;
  b.sim.min_e_per_us = min_e_per_us;
  b.sim.max_e_per_us = max_e_per_us;
  b.sim.texture_amplitude = texture_amplitude;
  b.sim.exposures_us = {30, 120, 480, 1920, 7680};
  b.sim.sensor.bit_depth = bit_depth;
  b.sim.sensor.black_level_dn = bit_depth == 8 ? 4 : 64;
  b.sim.sensor.response = curve;
  b.sim.sensor.response_gamma = 2.2;
  b.sim.seed = seed;
  EXPECT_TRUE(SimulateBracket(b.sim, &b.raw).ok());
  const double black = b.sim.sensor.black_level_dn;
  b.saturation_dn = b.sim.sensor.saturation_dn() - black;
  for (const Image& raw : b.raw.frames) {
    Image dn = raw;
    for (float& v : dn.data()) v -= static_cast<float>(black);
    b.dn.push_back(dn);
  }
  return b;
}

// Largest relative error of L over the well-exposed range (hat weight >= 0.1, i.e. z in
// [5 %, 95 %] of the range), where both papers' weights put their trust.
double MaxRelativeError(const CameraResponse& r, const Bracket& b) {
  double worst = 0;
  for (double u = 0.05; u <= 0.95; u += 0.01) {
    const double z = u * b.saturation_dn;
    const double truth = b.TrueLinear(z, r.reference_dn);
    worst = std::max(worst, std::abs(r.Linearize(z) / truth - 1));
  }
  return worst;
}

double MaxRelativeDifference(const CameraResponse& a, const CameraResponse& b, double saturation_dn) {
  double worst = 0;
  for (double u = 0.05; u <= 0.95; u += 0.01) {
    const double z = u * saturation_dn;
    worst = std::max(worst, std::abs(a.Linearize(z) / b.Linearize(z) - 1));
  }
  return worst;
}

ResponseRecoveryOptions Options(const Bracket& b, ResponseMethod method) {
  ResponseRecoveryOptions options;
  options.method = method;
  options.saturation_dn = b.saturation_dn;
  options.black_level_dn = b.sim.sensor.black_level_dn;
  return options;
}

struct Case {
  int bit_depth;
  SimResponseCurve curve;
  ResponseMethod method;
};

class RecoverKnownResponse : public ::testing::TestWithParam<Case> {};

// Stated tolerance: max relative error of L(z) over z in [5 %, 95 %] of the range < 2 %.
TEST_P(RecoverKnownResponse, WithinTwoPercent) {
  const Case c = GetParam();
  const Bracket b = MakeBracket(c.bit_depth, c.curve);
  CameraResponse response;
  ResponseRecoverySummary summary;
  ASSERT_TRUE(RecoverResponse(b.Frames(), Options(b, c.method), &response, &summary).ok());
  const double error = MaxRelativeError(response, b);
  std::cout << "bits " << c.bit_depth << " method " << response.method << ": max rel error " << error << "; "
            << summary.BriefReport() << "\n";
  EXPECT_LT(error, 0.02);
  EXPECT_EQ(response.bit_depth, c.bit_depth);
  EXPECT_NEAR(response.Linearize(response.reference_dn), response.reference_dn, 1e-9 * response.reference_dn);
}

INSTANTIATE_TEST_SUITE_P(
    BitDepthsAndMethods, RecoverKnownResponse,
    ::testing::Values(Case{8, SimResponseCurve::kGamma, ResponseMethod::kDebevec},
                      Case{8, SimResponseCurve::kGamma, ResponseMethod::kRobertson},
                      Case{12, SimResponseCurve::kSCurve, ResponseMethod::kDebevec},
                      Case{12, SimResponseCurve::kSCurve, ResponseMethod::kRobertson},
                      Case{16, SimResponseCurve::kGamma, ResponseMethod::kDebevec},
                      Case{16, SimResponseCurve::kGamma, ResponseMethod::kRobertson},
                      Case{12, SimResponseCurve::kLinear, ResponseMethod::kRobertson}));

// OpenCV's CalibrateDebevec draws its pixels at random, so its curve moves between runs and
// with the sample count. Stated tolerance: the curves from 500 and 4000 samples, from three
// seeds and from three four-frame subsets of the bracket agree within 1 % (max relative
// difference over z in [5 %, 95 %] of the range).
TEST(ResponseRecovery, StableAcrossSampleCountsSeedsAndFrameSubsets) {
  const Bracket b = MakeBracket(12, SimResponseCurve::kGamma, 11);
  for (ResponseMethod method : {ResponseMethod::kDebevec, ResponseMethod::kRobertson}) {
    ResponseRecoveryOptions options = Options(b, method);
    CameraResponse reference;
    options.num_samples = 4000;
    ASSERT_TRUE(RecoverResponse(b.Frames(), options, &reference, nullptr).ok());
    std::vector<std::pair<std::string, CameraResponse>> variants;
    for (int n : {500, 1000}) {
      options.num_samples = n;
      CameraResponse r;
      ASSERT_TRUE(RecoverResponse(b.Frames(), options, &r, nullptr).ok());
      variants.emplace_back("samples " + std::to_string(n), r);
    }
    options.num_samples = 1000;
    for (uint64_t seed : {2, 3}) {
      options.seed = seed;
      CameraResponse r;
      ASSERT_TRUE(RecoverResponse(b.Frames(), options, &r, nullptr).ok());
      variants.emplace_back("seed " + std::to_string(seed), r);
    }
    options.seed = 1;
    for (const std::vector<int>& subset : {std::vector<int>{0, 1, 2, 3}, std::vector<int>{1, 2, 3, 4},
                                           std::vector<int>{0, 2, 3, 4}}) {
      CameraResponse r;
      ASSERT_TRUE(RecoverResponse(b.Frames(subset), options, &r, nullptr).ok());
      variants.emplace_back("subset starting " + std::to_string(subset[0]), r);
    }
    for (const auto& [name, r] : variants) {
      const double difference = MaxRelativeDifference(r, reference, b.saturation_dn);
      std::cout << reference.method << " " << name << ": " << difference << "\n";
      EXPECT_LT(difference, 0.01) << reference.method << " " << name;
    }
  }
}

// A near-uniform scene (a flat or clean-glass bracket) bracketed with as many exposures as a
// wide-range scene gives one cluster of values per exposure: the curve between the clusters rests
// on smoothness. BracketDnCoverage tells the two apart, and the automatic bracket choice of
// `thinslab calib response` (ChooseResponseBracket) prefers the wide one where exposure counts
// tie, in either order; more exposures still come first.
TEST(ResponseRecovery, BracketChoicePrefersTheWidestDnCoverage) {
  const Bracket wide = MakeBracket(12, SimResponseCurve::kGamma);
  const Bracket flat = MakeBracket(12, SimResponseCurve::kGamma, 3, 1.0, 1.05, 0.0);
  const double wide_coverage = BracketDnCoverage(wide.Frames(), wide.saturation_dn);
  const double flat_coverage = BracketDnCoverage(flat.Frames(), flat.saturation_dn);
  CameraResponse from_wide, from_flat;
  ResponseRecoverySummary wide_summary, flat_summary;
  ASSERT_TRUE(RecoverResponse(wide.Frames(), Options(wide, ResponseMethod::kDebevec), &from_wide, &wide_summary).ok());
  ASSERT_TRUE(RecoverResponse(flat.Frames(), Options(flat, ResponseMethod::kDebevec), &from_flat, &flat_summary).ok());
  const double wide_error = MaxRelativeError(from_wide, wide), flat_error = MaxRelativeError(from_flat, flat);
  std::cout << "DN coverage: wide scene " << wide_coverage << " (max rel error of L " << wide_error
            << "), flat scene " << flat_coverage << " (max rel error of L " << flat_error << ")\n";
  // Measured: coverage 1.0 (wide) and 0.22 (flat: 7 of 32 bins); max relative error of L 1.2 %
  // from the wide bracket, 65 % from the flat one.
  EXPECT_GT(wide_coverage, 0.9);
  EXPECT_LT(flat_coverage, 0.3);
  EXPECT_LT(flat_coverage, kMinBracketDnCoverage);
  EXPECT_DOUBLE_EQ(wide_summary.dn_coverage, wide_coverage);
  // Why it matters: the flat bracket's curve is off by several times the wide one's.
  EXPECT_GT(flat_error, 3 * wide_error);

  // Same exposure and frame counts; "flat" sorts first among the session's groups.
  std::vector<BracketCandidate> candidates = {{"flat", 5, 5, flat_coverage}, {"reference", 5, 5, wide_coverage}};
  EXPECT_EQ(ChooseResponseBracket(candidates), 1);
  std::swap(candidates[0], candidates[1]);
  EXPECT_EQ(ChooseResponseBracket(candidates), 0);
  candidates = {{"flat", 6, 6, flat_coverage}, {"reference", 5, 5, wide_coverage}};
  EXPECT_EQ(ChooseResponseBracket(candidates), 0);
  candidates = {{"a", 5, 5, 0.5}, {"b", 5, 10, 0.5}};
  EXPECT_EQ(ChooseResponseBracket(candidates), 1);  // Equal coverage: more frames.
  EXPECT_EQ(ChooseResponseBracket({}), -1);
}

// Bad brackets end in a Status naming the frame or field.
TEST(ResponseRecovery, BadInputNamesTheProblem) {
  const Bracket b = MakeBracket(12, SimResponseCurve::kGamma);
  const ResponseRecoveryOptions options = Options(b, ResponseMethod::kDebevec);
  CameraResponse r;
  auto message = [&](const std::vector<ResponseFrame>& frames) {
    const Status status = RecoverResponse(frames, options, &r, nullptr);
    EXPECT_FALSE(status.ok());
    return status.message();
  };
  EXPECT_NE(message(b.Frames({0, 1})).find("too few exposures: got 2"), std::string::npos);
  std::vector<ResponseFrame> frames = b.Frames();
  std::swap(frames[2], frames[3]);
  EXPECT_NE(message(frames).find("non-monotonic exposures: frame 'f2'"), std::string::npos) << message(frames);
  frames = b.Frames();
  frames[3].exposure_time_us = frames[2].exposure_time_us;
  EXPECT_NE(message(frames).find("duplicate exposure: frame 'f3'"), std::string::npos) << message(frames);
  // Exposures in order, but the images say otherwise: frame 3 holds frame 1's image.
  frames = b.Frames();
  frames[3].dn = frames[1].dn;
  EXPECT_NE(message(frames).find("frame 'f3' (1920 us) is darker"), std::string::npos) << message(frames);
  frames = b.Frames();
  frames[4].bit_depth = 8;
  EXPECT_NE(message(frames).find("mixed bit depths: frame 'f4' has bit_depth 8"), std::string::npos) << message(frames);
  frames = b.Frames();
  frames[1].dn = nullptr;
  EXPECT_NE(message(frames).find("frame 'f1': image missing"), std::string::npos) << message(frames);
  Image saturated(b.dn[0].width(), b.dn[0].height(), static_cast<float>(b.saturation_dn));
  frames = b.Frames();
  frames[4].dn = &saturated;
  EXPECT_NE(message(frames).find("frame 'f4': every pixel is saturated"), std::string::npos) << message(frames);
  ResponseRecoveryOptions bad = options;
  bad.max_knots = 3;
  EXPECT_NE(RecoverResponse(b.Frames(), bad, &r, nullptr).message().find("ResponseRecoveryOptions::max_knots"),
            std::string::npos);
}

// response.json round-trips, and the reader refuses broken files naming file and field.
TEST(ResponseIo, RoundTripAndRefusals) {
  const Bracket b = MakeBracket(8, SimResponseCurve::kGamma);
  CameraResponse r;
  ASSERT_TRUE(RecoverResponse(b.Frames(), Options(b, ResponseMethod::kRobertson), &r, nullptr).ok());
  r.camera_id = "cam0";
  TempDir dir;
  const std::string path = dir / "response.json";
  ASSERT_TRUE(WriteResponse(path, r).ok());
  CameraResponse back;
  const Status read = ReadResponse(path, &back);
  ASSERT_TRUE(read.ok()) << read.message();
  EXPECT_EQ(back.method, "robertson");
  EXPECT_EQ(back.camera_id, "cam0");
  EXPECT_EQ(back.knots_dn.size(), r.knots_dn.size());
  for (double z = -3; z < 260; z += 0.7) EXPECT_DOUBLE_EQ(back.Linearize(z), r.Linearize(z));
  std::string text = ResponseToJson(r);
  const std::string version_field = "\"format_version\": \"1.0\"";
  ASSERT_NE(text.find(version_field), std::string::npos) << text.substr(0, 200);
  std::string v2 = text;
  v2.replace(v2.find(version_field), version_field.size(), "\"format_version\": \"2.0\"");
  EXPECT_NE(ResponseFromJson(v2, "x/response.json", &back).message().find("x/response.json: format_version: 2.0"),
            std::string::npos);
  CameraResponse decreasing = r;
  decreasing.linear_dn[10] = decreasing.linear_dn[9] - 1;
  EXPECT_NE(WriteResponse(path, decreasing).message().find("linear_dn[10]"), std::string::npos);
  EXPECT_NE(ResponseFromJson("{\"format\": \"thinslab-response\", \"format_version\": \"1.0\", \"method\": \"debevec\", "
                             "\"black_level_dn\": 0, \"knots_dn\": [0, 1], \"linear_dn\": [0]}",
                             "y.json", &back)
                .message()
                .find("y.json: linear_dn: has 1 values"),
            std::string::npos);
  EXPECT_FALSE(ReadResponse(dir / "missing.json", &back).ok());
}

}  // namespace
}  // namespace thinslab
