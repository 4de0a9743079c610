// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/verbosity.h"

#include <glog/logging.h>

#include <iostream>

namespace thinslab {
namespace {

struct State {
  bool quiet = false, verbose = false;
};
State& Current() {
  static State state;
  return state;
}

// Swallows what a --quiet command writes to stdout.
class NullBuffer : public std::streambuf {
 protected:
  int overflow(int c) override { return traits_type::not_eof(c); }
  std::streamsize xsputn(const char*, std::streamsize n) override { return n; }
};

}  // namespace

void SetVerbosity(bool quiet, bool verbose) {
  static NullBuffer null_buffer;
  Current() = {quiet, verbose};
  if (quiet) std::cout.rdbuf(&null_buffer);
  if (verbose) FLAGS_minloglevel = 0;
}

bool QuietRun() { return Current().quiet; }
bool VerboseRun() { return Current().verbose; }

VerbosityScope::VerbosityScope() : stdout_buffer_(std::cout.rdbuf()), min_log_level_(FLAGS_minloglevel) {}

VerbosityScope::~VerbosityScope() {
  std::cout.flush();
  std::cout.rdbuf(stdout_buffer_);
  FLAGS_minloglevel = min_log_level_;
  Current() = {};
}

}  // namespace thinslab
