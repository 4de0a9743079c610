// SPDX-License-Identifier: Apache-2.0
// Stability matrix of the dual-microfacet fit (issue #8, part 3): roughness near 0 and large,
// sparse lights, under- and over-exposure, low light (noise) and a camera pose a few pixels off,
// each on a capture of the simulated dot rig (Monte Carlo through both faces, sensor noise,
// 12-bit frames). Every point must either meet the tolerance or carry a status that says why
// it was not fitted; no map value may be NaN or inf. A point with status ok whose held-out
// prediction is far off is a silent wrong answer: the matrix counts them.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <nlohmann/json.hpp>

#include "fit/dmf_evaluation.h"
#include "fit/dmf_map_fit.h"
#include "fit/dmf_processing.h"
#include "sim/synthesize_dot_scan_session.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

// Held-out in-lobe relative RMS a status-ok point must meet. The unperturbed capture gives
// 0.09-0.25 on the nine-region sample (tests/e2e_dmf_test); twice its worst is a fit that
// no longer describes the lobe.
constexpr double kHeldOutTolerance = 0.5;

SlabRegion Region(const std::string& name, double x0, double y0, double x1, double y1, const SlabFace& top,
                  const SlabFace& bottom) {
  SlabRegion r;
  r.name = name;
  r.min_m = Eigen::Vector2d(x0, y0);
  r.max_m = Eigen::Vector2d(x1, y1);
  r.material.top = top;
  r.material.bottom = bottom;
  return r;
}

SlabFace Ggx(double alpha) { return SlabFace{RoughSlabNdf::kGgx, alpha, alpha}; }

// Four roughness extremes, 2 x 2 over the 80 mm sample.
std::vector<SlabRegion> RoughnessRegions() {
  const SlabFace flat;
  return {Region("alpha_0.03_top", -0.04, -0.04, 0, 0, Ggx(0.03), flat),
          Region("alpha_0.2_both", 0, -0.04, 0.04, 0, Ggx(0.2), Ggx(0.2)),
          Region("alpha_0.6_top", -0.04, 0, 0, 0.04, Ggx(0.6), flat),
          Region("alpha_1.2_both", 0, 0, 0.04, 0.04, Ggx(1.2), Ggx(1.2))};
}

struct CaseResult {
  Status status;  // Processing or fitting error (a clear refusal is an allowed outcome).
  std::map<std::string, DmfRegionAccuracy> regions;
  int non_finite = 0;  // Map values that are NaN or inf.
};

int Count(const DmfRegionAccuracy& r, DmfStatus status) {
  const auto it = r.statuses.find(static_cast<int>(status));
  return it == r.statuses.end() ? 0 : it->second;
}

class DmfStability : public ::testing::Test {
 protected:
  static SyntheticDotScanOptions BaseRig() {
    SyntheticDotScanOptions sim;
    sim.sample.regions = RoughnessRegions();
    sim.session.grid_nx = sim.session.grid_ny = 16;
    return sim;
  }

  // Simulates, optionally edits the manifest, processes (pitch 8 mm: 10 x 10 points) and fits
  // every point; tallies per region, points at least 8 mm inside it.
  // `sim` null: a copy of the base capture (simulated once per suite).
  CaseResult Run(const std::string& name, const SyntheticDotScanOptions* sim,
                 const std::function<void(nlohmann::json*)>& edit_manifest = nullptr) {
    CaseResult result;
    const std::string session = *suite_dir_ / name;
    if (sim == nullptr) {
      if (!base_simulated_) {
        const Status s = SynthesizeDotScanSession(BaseRig(), *suite_dir_ / "base");
        EXPECT_TRUE(s.ok()) << s.message();
        if (!s.ok()) return result;
        base_simulated_ = true;
      }
      std::filesystem::copy(*suite_dir_ / "base", session, std::filesystem::copy_options::recursive);
    } else {
      const Status s = SynthesizeDotScanSession(*sim, session);
      EXPECT_TRUE(s.ok()) << s.message();
      if (!s.ok()) return result;
    }
    if (edit_manifest) {
      nlohmann::json manifest;
      std::ifstream(session + "/session.json") >> manifest;
      edit_manifest(&manifest);
      std::ofstream(session + "/session.json") << manifest.dump(2);
    }
    DmfProcessingOptions processing;
    processing.pitch_m = 0.008;
    processing.hold_out = true;
    DmfSliceSet slices;
    DmfProcessingReport report;
    result.status = PrepareDotScanSlices(session, processing, &slices, &report);
    if (!result.status.ok()) {
      std::printf("%s: refused: %s\n", name.c_str(), result.status.message().c_str());
      return result;
    }
    DmfMapFitOptions options;
    options.cluster = false;
    DmfMaps maps;
    result.status = FitDualMicrofacetMaps(slices, options, &maps);
    if (!result.status.ok()) return result;
    const Image image = maps.ToImage();
    for (float v : image.data()) result.non_finite += !std::isfinite(v);
    std::vector<DmfTruthRegion> truth;
    result.status = ReadDmfTruth(session, &truth);
    if (!result.status.ok()) return result;
    std::printf("%s: fitted\n", name.c_str());
    for (const DmfRegionAccuracy& a : CompareDmfWithTruth(slices, maps, truth, kHeldOutTolerance)) {
      result.regions[a.name] = a;
      std::printf("  %-16s points %2d ok %2d flagged %2d silent-wrong %d; held-out median %.3f; statuses", a.name.c_str(),
                  a.points, a.ok, a.flagged, a.silent_wrong, a.median_held_out);
      for (const auto& [code, n] : a.statuses) std::printf(" %d:%d", code, n);
      std::printf("\n");
    }
    return result;
  }

  static void ExpectNoSilentWrongAnswers(const CaseResult& r) {
    EXPECT_EQ(r.non_finite, 0);
    for (const auto& [region, a] : r.regions) EXPECT_EQ(a.silent_wrong, 0) << region;
  }

  static void SetUpTestSuite() { suite_dir_ = new TempDir; }
  static void TearDownTestSuite() {
    delete suite_dir_;
    base_simulated_ = false;
  }
  static TempDir* suite_dir_;
  static bool base_simulated_;
};
TempDir* DmfStability::suite_dir_ = nullptr;
bool DmfStability::base_simulated_ = false;

// Roughness near 0 and large: a lobe narrower than the dot spacing is flagged specular; a lobe
// wider than the monitor's directions predicts the dots it saw, but its k_s is flagged.
TEST_F(DmfStability, RoughnessExtremes) {
  const CaseResult r = Run("roughness", nullptr);
  ASSERT_TRUE(r.status.ok()) << r.status.message();
  ExpectNoSilentWrongAnswers(r);
  const DmfRegionAccuracy& smooth = r.regions.at("alpha_0.03_top");
  EXPECT_EQ(Count(smooth, DmfStatus::kSpecular), smooth.points);
  const DmfRegionAccuracy& moderate = r.regions.at("alpha_0.2_both");
  EXPECT_EQ(moderate.ok, moderate.points);
  const DmfRegionAccuracy& very_rough = r.regions.at("alpha_1.2_both");
  EXPECT_EQ(very_rough.ok, 0) << "k_s of a lobe wider than the monitor passed as measured";
}

// Sparse lights: 8 x 8 and 6 x 6 dots (4 and 6 x wider spacing than the paper's 40 x 40 over
// the same monitor) leave the tabulated NDF mostly filled in by Eq. 17; before the
// measured-fraction check these points passed as ok with held-out errors of 1-120.
TEST_F(DmfStability, SparseLights) {
  for (int dots : {8, 6}) {
    SyntheticDotScanOptions sim = BaseRig();
    sim.session.grid_nx = sim.session.grid_ny = dots;
    const CaseResult r = Run("sparse_" + std::to_string(dots), &sim);
    ASSERT_TRUE(r.status.ok()) << r.status.message();
    ExpectNoSilentWrongAnswers(r);
    int undersampled = 0;
    for (const auto& [region, a] : r.regions) undersampled += Count(a, DmfStatus::kUndersampled);
    EXPECT_GT(undersampled, 0) << dots << " x " << dots << " dots";
  }
}

// Exposure: dot radiance 0.02x and 30x the rig's default are refused by the dot calibration
// with a message naming what is wrong; 0.25x and 4x fit with no silent wrong answers and most
// points of the two-sided region ok.
TEST_F(DmfStability, UnderAndOverExposure) {
  for (double scale : {0.02, 30.0}) {
    SyntheticDotScanOptions sim = BaseRig();
    sim.rig.dot_radiance *= scale;
    const CaseResult r = Run("exposure_x" + std::to_string(scale), &sim);
    ASSERT_FALSE(r.status.ok());
    EXPECT_NE(r.status.message().find("dot geometry"), std::string::npos) << r.status.message();
  }
  for (double scale : {0.25, 4.0}) {
    SyntheticDotScanOptions sim = BaseRig();
    sim.rig.dot_radiance *= scale;
    const CaseResult r = Run("exposure_x" + std::to_string(scale), &sim);
    ASSERT_TRUE(r.status.ok()) << r.status.message();
    ExpectNoSilentWrongAnswers(r);
    // Measured: 9 of 9 ok at 0.25x; 7 of 9 at 4x (2 flagged unphysical, k_s > 4).
    const DmfRegionAccuracy& moderate = r.regions.at("alpha_0.2_both");
    EXPECT_GE(2 * moderate.ok, moderate.points) << "exposure x" << scale;
  }
}

// A camera pose 2 and 4 camera pixels off (1 and 2 mm at the sample): the dot positions are
// back-projected with the same wrong pose, so light directions stay consistent and the fit
// holds (held-out median of the two-sided region within 0.03 of the true pose's).
TEST_F(DmfStability, CameraPoseAFewPixelsOff) {
  const CaseResult reference = Run("pose_0", nullptr);
  ASSERT_TRUE(reference.status.ok()) << reference.status.message();
  for (double shift_mm : {1.0, 2.0}) {
    const CaseResult r = Run("pose_" + std::to_string(shift_mm), nullptr, [&](nlohmann::json* m) {
      auto& t = (*m)["rig"]["cameras"][0]["cam_from_sample"]["translation_m"];
      t[0] = t[0].get<double>() + shift_mm * 1e-3;
    });
    ASSERT_TRUE(r.status.ok()) << r.status.message();
    ExpectNoSilentWrongAnswers(r);
    const double reference_error = reference.regions.at("alpha_0.2_both").median_held_out;
    EXPECT_GT(reference_error, 0);
    EXPECT_LT(std::abs(r.regions.at("alpha_0.2_both").median_held_out - reference_error), 0.03);
  }
}

}  // namespace
}  // namespace thinslab
