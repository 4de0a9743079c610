// SPDX-License-Identifier: Apache-2.0
// A JSON file the test expects to exist and parse (summary.json, session.json).
#pragma once

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "thinslab/core/file.h"

namespace thinslab {

// The parsed file, or a discarded value (with a test failure naming the file) when it cannot be read.
inline nlohmann::json ReadJsonFile(const std::string& path) {
  std::string text;
  EXPECT_TRUE(ReadFileToString(path, &text).ok()) << path;
  return nlohmann::json::parse(text, nullptr, false);
}

}  // namespace thinslab
