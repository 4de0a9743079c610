// SPDX-License-Identifier: Apache-2.0
// `thinslab bench sweep --quick` through the real binary (issue #8, part 2): it simulates a dot
// scan, a shadow map and a laser lobe, sweeps the fit knobs, and must write CSV files whose Pareto flags are
// right, charts, and a summary; the measured trade-offs must show what the fits are known to do.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "tests/testing/run_thinslab.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;

struct Row {
  std::string knob, value;
  double seconds = 0, error = 0, truth_error = 0;
  bool pareto = false;
};

// Splits one CSV line with RFC 4180 quoting.
std::vector<std::string> CsvFields(const std::string& line) {
  std::vector<std::string> fields(1);
  bool quoted = false;
  for (size_t k = 0; k < line.size(); ++k) {
    const char c = line[k];
    if (quoted && c == '"' && k + 1 < line.size() && line[k + 1] == '"') {
      fields.back() += '"';
      ++k;
    } else if (c == '"') {
      quoted = !quoted;
    } else if (c == ',' && !quoted) {
      fields.emplace_back();
    } else {
      fields.back() += c;
    }
  }
  return fields;
}

std::vector<Row> ReadRows(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::getline(in, line);
  EXPECT_EQ(line, "method,knob,value,seconds,error,truth_error,parameters,fitted_points,pareto") << path;
  std::vector<Row> rows;
  while (std::getline(in, line)) {
    const std::vector<std::string> f = CsvFields(line);
    EXPECT_EQ(f.size(), 9u) << path << ": " << line;
    if (f.size() != 9) continue;
    Row r;
    r.knob = f[1];
    r.value = f[2];
    r.seconds = std::stod(f[3]);
    r.error = std::stod(f[4]);
    r.truth_error = std::stod(f[5]);
    r.pareto = f[8] == "1";
    rows.push_back(r);
  }
  return rows;
}

const Row* Find(const std::vector<Row>& rows, const std::string& knob, const std::string& value_prefix) {
  for (const Row& r : rows) {
    if (r.knob == knob && r.value.rfind(value_prefix, 0) == 0) return &r;
  }
  return nullptr;
}

// Every row is timed and scored, and a row is flagged Pareto exactly when no other row is at
// least as fast and as accurate and strictly better in one.
void ExpectScoredWithAConsistentFront(const std::vector<Row>& rows, const std::string& what) {
  ASSERT_GE(rows.size(), 5u) << what;
  int front = 0;
  for (const Row& a : rows) {
    EXPECT_TRUE(std::isfinite(a.seconds) && a.seconds >= 0) << what << " " << a.knob << "=" << a.value;
    EXPECT_TRUE(std::isfinite(a.error) && a.error >= 0) << what << " " << a.knob << "=" << a.value;
    bool dominated = false;
    for (const Row& b : rows) {
      dominated |= &a != &b && b.seconds <= a.seconds && b.error <= a.error &&
                   (b.seconds < a.seconds || b.error < a.error);
    }
    EXPECT_EQ(a.pareto, !dominated) << what << " " << a.knob << "=" << a.value;
    front += a.pareto;
  }
  EXPECT_GE(front, 1) << what;
}

TEST(CliBenchSweep, QuickSweepWritesConsistentFrontsAndTheKnownTradeOffs) {
  TempDir dir;
  const std::string out = dir / "sweep";
  const RunResult run = RunThinslab("bench sweep " + out + " --quick true");
  ASSERT_EQ(run.exit_code, 0) << run.output;
  for (const char* file : {"knob_sweep_dmf.png", "knob_sweep_tau.png", "knob_sweep_phase.png"}) {
    ASSERT_TRUE(fs::exists(fs::path(out) / file)) << file;
    EXPECT_GT(fs::file_size(fs::path(out) / file), 10000u) << file;
  }
  EXPECT_FALSE(fs::exists(fs::path(out) / "captures")) << "simulated captures left behind";
  std::ifstream summary(out + "/knob_sweep.txt");
  std::stringstream text;
  text << summary.rdbuf();
  EXPECT_NE(text.str().find("dmf Pareto front"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("tau Pareto front"), std::string::npos) << text.str();
  EXPECT_NE(text.str().find("phase Pareto front"), std::string::npos) << text.str();

  const std::vector<Row> dmf = ReadRows(out + "/knob_sweep_dmf.csv");
  ExpectScoredWithAConsistentFront(dmf, "dmf");
  const Row* single = Find(dmf, "model_rung", "3");
  const Row* tabulated = Find(dmf, "model_rung", "5");
  const Row* coarse = Find(dmf, "ndf_resolution", "16");
  const Row* fine = Find(dmf, "default", "-");
  ASSERT_TRUE(single && tabulated && coarse && fine);
  // The nine-region sample has two-sided, Beckmann and anisotropic regions that one GGX face
  // cannot predict (the Fig. 5 claim of Dai et al.): on held-out dots the tabulated NDF at
  // every point is at least 20 % better (measured 0.17 against 0.26).
  EXPECT_LT(tabulated->error, 0.8 * single->error);
  // A 16 x 16 NDF grid cannot hold the narrow lobes: its NDF error against the truth is larger
  // than the default 32 x 32 (measured 0.70 against 0.40).
  EXPECT_GT(coarse->truth_error, fine->truth_error);

  const std::vector<Row> tau = ReadRows(out + "/knob_sweep_tau.csv");
  ExpectScoredWithAConsistentFront(tau, "tau");
  const Row* plain = Find(tau, "model", "plain");
  const Row* refined = Find(tau, "default", "-");
  const Row* one_pass = Find(tau, "max_outer_iterations", "1");
  ASSERT_TRUE(plain && refined && one_pass);
  // Plain Eq. 7 is the fastest and reads low; the Eq. 5-6 refinement is at least 3x more
  // accurate (measured 0.197 against 0.041), and one outer pass is not yet converged.
  EXPECT_TRUE(plain->pareto);
  EXPECT_LT(plain->truth_error, -0.1);
  EXPECT_LT(3 * refined->error, plain->error);
  EXPECT_GT(one_pass->error, refined->error);

  const std::vector<Row> phase = ReadRows(out + "/knob_sweep_phase.csv");
  ExpectScoredWithAConsistentFront(phase, "phase");
  const Row* chosen = Find(phase, "default", "-");
  const Row* wide = Find(phase, "max_theta_deg", "60");
  const Row* narrow = Find(phase, "max_theta_deg", "30");
  ASSERT_TRUE(chosen && wide && narrow);
  // Eq. 8 is single scattering: the layer's multiple scattering widens the lobe's tail, so rings
  // out to 60 degrees read g low; up to 30 degrees the fit is at least 2x closer (measured 0.0048
  // against 0.0167 for g 0.8), and the 60-degree sigma_g (truth_error column) covers its error
  // within 1.5 sigma. The default picks the angle by the smallest sigma_g: as close as 30 degrees.
  EXPECT_LT(2 * narrow->error, wide->error);
  EXPECT_LT(wide->error, 1.5 * wide->truth_error);
  EXPECT_LE(chosen->error, narrow->error + 1e-9);
}

TEST(CliBenchSweep, BadOptionsAreNamed) {
  TempDir dir;
  RunResult r = RunThinslab("bench sweep " + dir / "a" + " --methods dmf,bogus");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--methods: unknown method 'bogus'"), std::string::npos) << r.output;
  r = RunThinslab("bench sweep " + dir / "b" + " --dots 2");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("--dots"), std::string::npos) << r.output;
  fs::create_directories(fs::path(dir / "c") / "captures");
  r = RunThinslab("bench sweep " + dir / "c" + " --methods tau");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("captures: exists"), std::string::npos) << r.output;
  r = RunThinslab("bench frobnicate");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("thinslab bench sweep OUTDIR"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace thinslab
