// SPDX-License-Identifier: Apache-2.0
// Issue #29 item 1 through the binary: `fit dmf` streams its slice matrix from disk in bands of
// map points when the grid exceeds --max-memory (or --stream-band-points asks for it), and
// writes the same maps bit for bit: maps.exr, the NDF atlas (interpolated NDFs rebuilt from the
// representatives), the ground-truth comparison with held-out errors, the validation and
// held-out predictions; clustered and unclustered. The spill file is never left behind, a
// budget too small for one band and the ladder on a streamed fit are refused with the reason.
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/testing/json_file.h"
#include "tests/testing/run_ok.h"
#include "tests/testing/same_fit.h"
#include "tests/testing/temp_dir.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"

namespace thinslab {
namespace {

TEST(CliDmfStreamed, SameMapsAsInMemoryBudgetHeldNothingLeftBehind) {
  TempDir dir;
  const std::string capture = dir / "capture";
  SimulateSmallDotScan(capture);
  const std::string fit = "fit dmf " + capture + " --pitch-mm 2.5 --hold-out true --threads 2";
  RunThinslabOk(fit + " --out " + (dir / "memory"));
  // Bands of 4 grid rows (the grid is 32 points wide): the band edges cut through regions.
  const RunResult streamed =
      RunThinslabOk(fit + " --stream-band-points 128 --verbose --out " + (dir / "streamed"));
  EXPECT_NE(streamed.output.find("streamed in bands of 128 points"), std::string::npos) << streamed.output;
  // Every stage of the fit reports its progress, over all bands (issue #26 item 4): the last
  // line of each counts the whole grid (32 x 32 points) or all its steps.
  for (const char* done :
       {"fit dmf: dot frames (HDR merge, Eq. 12): 100/100", "fit dmf: diffuse separation (Dai Eq. 14): 1024/1024",
        "fit dmf: clustering (PCA, k-means, Dai Eq. 20): 20/20", "fit dmf: clustering, projections: 1024/1024",
        "fit dmf: interpolation (Dai Eqs. 20-22): 1024/1024", "fit dmf: held-out dots: 1024/1024"}) {
    EXPECT_NE(streamed.output.find(done), std::string::npos) << done << "\n" << streamed.output;
  }
  EXPECT_NE(streamed.output.find("fit dmf: point fits (Dai Eqs. 14-19): "), std::string::npos) << streamed.output;
  // The ground-truth comparison takes each point's held-out error from the held-out dots' pass
  // (counted over all bands above: a count that restarted at each band never reached the
  // total) instead of predicting the dots again, then runs every region's pass over the points.
  EXPECT_EQ(streamed.output.find("fit dmf: ground truth, held-out errors"), std::string::npos) << streamed.output;
  const size_t compared = streamed.output.rfind("fit dmf: ground truth, regions: ");
  ASSERT_NE(compared, std::string::npos) << streamed.output;
  const size_t begin = compared + std::string("fit dmf: ground truth, regions: ").size();
  const std::string count = streamed.output.substr(begin, streamed.output.find_first_of(" ,\n", begin) - begin);
  EXPECT_EQ(count.substr(0, count.find('/')), count.substr(count.find('/') + 1)) << count;
  const nlohmann::json memory = ReadJsonFile(dir / "memory/summary.json")["memory"];
  const nlohmann::json banded = ReadJsonFile(dir / "streamed/summary.json")["memory"];
  EXPECT_FALSE(memory["streamed"].get<bool>()) << memory.dump();
  EXPECT_TRUE(banded["streamed"].get<bool>()) << banded.dump();
  EXPECT_EQ(banded["band_points"], 128) << banded.dump();
  ExpectSameFit(dir, "memory", "streamed");

  // Unclustered: every point fitted directly, band by band (a coarser grid: 16 x 16 points).
  const std::string all = "fit dmf " + capture +
                          " --pitch-mm 5 --hold-out true --threads 2 --cluster-fraction 0 "
                          "--split-half false";
  RunThinslabOk(all + " --out " + (dir / "all_memory"));
  RunThinslabOk(all + " --stream-band-points 48 --out " + (dir / "all_streamed"));
  ExpectSameFit(dir, "all_memory", "all_streamed");

  // A budget between the streamed estimate with bands of 4 rows and the in-memory one streams,
  // with bands the budget sets, and the process's peak stays under it.
  const double in_memory = memory["estimated_in_memory_bytes"].get<double>();
  const double budget_bytes = 0.5 * (in_memory + banded["estimated_peak_bytes"].get<double>());
  char budget[32];
  std::snprintf(budget, sizeof(budget), "%.6f", budget_bytes / (1u << 30));
  RunThinslabOk(fit + " --max-memory " + budget + " --out " + (dir / "budget"));
  const nlohmann::json summary = ReadJsonFile(dir / "budget/summary.json");
  EXPECT_TRUE(summary["memory"]["streamed"].get<bool>()) << summary["memory"].dump();
  EXPECT_GT(summary["memory"]["band_points"].get<int>(), 128) << summary["memory"].dump();
#ifndef __SANITIZE_ADDRESS__
  // (AddressSanitizer's shadow memory and quarantine add hundreds of MiB to any process's peak.)
  EXPECT_LT(summary["peak_memory_mib"].get<double>() * (1 << 20), budget_bytes) << summary.dump();
#endif
  ExpectSameFit(dir, "memory", "budget");

  // Nothing of the spill file is left in the output or beside it.
  for (const char* out : {"streamed", "all_streamed", "budget"}) {
    for (const auto& entry : std::filesystem::directory_iterator(dir / out)) {
      EXPECT_EQ(entry.path().filename().string().find("slices"), std::string::npos) << entry.path();
    }
  }
  for (const auto& entry : std::filesystem::directory_iterator(dir.path())) {
    EXPECT_EQ(entry.path().filename().string().find(".partial"), std::string::npos) << entry.path();
  }

  // Refused with the reason: a budget that cannot hold one grid row, the ladder on a streamed fit,
  // a spill folder that cannot take the file.
  const RunResult tiny = RunThinslab(fit + " --max-memory 0.01 --out " + (dir / "tiny"));
  EXPECT_NE(tiny.exit_code, 0);
  EXPECT_NE(tiny.output.find("--max-memory 0.01 GiB is too small"), std::string::npos) << tiny.output;
  const RunResult ladder = RunThinslab(fit + " --ladder true --stream-band-points 128 --out " + (dir / "ladder"));
  EXPECT_NE(ladder.exit_code, 0);
  EXPECT_NE(ladder.output.find("--ladder: not available on a fit streamed from disk"), std::string::npos)
      << ladder.output;
  const RunResult spill =
      RunThinslab(fit + " --stream-band-points 128 --spill-dir " + (dir / "no/such/folder") + " --out " + (dir / "x"));
  EXPECT_NE(spill.exit_code, 0);
  EXPECT_NE(spill.output.find("no/such/folder: cannot create the slice spill file"), std::string::npos) << spill.output;
  EXPECT_FALSE(std::filesystem::exists(dir / "tiny"));
  EXPECT_FALSE(std::filesystem::exists(dir / "x"));
}

}  // namespace
}  // namespace thinslab
