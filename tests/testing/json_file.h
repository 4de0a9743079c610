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

// The element of a summary's `regions` array whose "region" is `name`; a test failure and a null
// value when there is none.
inline const nlohmann::json& Region(const nlohmann::json& regions, const std::string& name) {
  for (const nlohmann::json& r : regions) {
    if (r["region"] == name) return r;
  }
  ADD_FAILURE() << "no region " << name << " in " << regions.dump();
  static const nlohmann::json none;
  return none;
}

}  // namespace thinslab
