// SPDX-License-Identifier: Apache-2.0
// Two `fit dmf` output folders hold the same fit: maps.exr and the NDF atlas bit for bit, the
// ground-truth comparison byte for byte, and summary.json's results (not its timings or memory).
// For the streamed and the multi-process fits (issue #29), which must change nothing.
#pragma once

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "tests/testing/json_file.h"
#include "tests/testing/run_ok.h"
#include "tests/testing/temp_dir.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"

namespace thinslab {

// The small dot scan these comparisons fit (10 x 10 dots, 6 validation dots, 240 x 180 camera;
// a few seconds): regions of every kind, so that a difference anywhere shows.
inline void SimulateSmallDotScan(const std::string& capture) {
  RunThinslabOk("sim dot-scan " + capture +
                " --quiet --grid-nx 10 --grid-ny 10 --validation-dots 6 --photons-k 10 --table-bins 24 "
                "--camera-width-px 240 --camera-height-px 180");
}

inline void ExpectSameExr(const std::string& a, const std::string& b) {
  Image x, y;
  ASSERT_TRUE(ReadExr(a, &x).ok()) << a;
  ASSERT_TRUE(ReadExr(b, &y).ok()) << b;
  EXPECT_EQ(x.channel_names(), y.channel_names()) << a;
  ASSERT_EQ(x.data().size(), y.data().size()) << a;
  size_t differ = 0;
  for (size_t k = 0; k < x.data().size(); ++k) differ += x.data()[k] != y.data()[k];
  EXPECT_EQ(differ, 0u) << a << " and " << b << " differ in " << differ << " of " << x.data().size() << " values";
}

// Everything but the memory figures and timings of the two fits' outputs is the same.
inline void ExpectSameFit(const TempDir& dir, const std::string& a, const std::string& b) {
  ExpectSameExr(dir / (a + "/maps.exr"), dir / (b + "/maps.exr"));
  ExpectSameExr(dir / (a + "/ndf_atlas.exr"), dir / (b + "/ndf_atlas.exr"));
  std::string ca, cb;
  ASSERT_TRUE(ReadFileToString(dir / (a + "/comparison.json"), &ca).ok());
  ASSERT_TRUE(ReadFileToString(dir / (b + "/comparison.json"), &cb).ok());
  EXPECT_EQ(ca, cb);
  const nlohmann::json sa = ReadJsonFile(dir / (a + "/summary.json")), sb = ReadJsonFile(dir / (b + "/summary.json"));
  for (const char* key :
       {"status_counts", "validation", "hold_out", "equivalent_ndf", "clustering", "points_fitted_directly"}) {
    EXPECT_EQ(sa.value(key, nlohmann::json()), sb.value(key, nlohmann::json())) << key;
  }
}

}  // namespace thinslab
