// SPDX-License-Identifier: Apache-2.0
// Runs the real `thinslab` binary and expects it to succeed (the command line and its output in
// the failure message).
#pragma once

#include <gtest/gtest.h>

#include <string>

#include "tests/testing/run_thinslab.h"

namespace thinslab {

inline RunResult RunThinslabOk(const std::string& args) {
  const RunResult run = RunThinslab(args);
  EXPECT_EQ(run.exit_code, 0) << "thinslab " << args << "\n" << run.output;
  return run;
}

}  // namespace thinslab
