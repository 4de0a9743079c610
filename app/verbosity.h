// SPDX-License-Identifier: Apache-2.0
// --quiet and --verbose, which every command takes (OptionParser registers them unless a
// command has its own option of that name). --quiet: nothing on stdout and no progress; errors
// and warnings still go to stderr. --verbose: progress even when stderr is not a terminal, and
// the libraries' informational log (glog INFO).
#pragma once

#include <streambuf>

namespace thinslab {

void SetVerbosity(bool quiet, bool verbose);
bool QuietRun();
bool VerboseRun();

// Restores stdout, the log level and the verbosity at the end of a command (main, Python's
// run_command), so one command's --quiet does not outlive it.
class VerbosityScope {
 public:
  VerbosityScope();
  ~VerbosityScope();
  VerbosityScope(const VerbosityScope&) = delete;
  VerbosityScope& operator=(const VerbosityScope&) = delete;

 private:
  std::streambuf* stdout_buffer_;
  int min_log_level_;
};

}  // namespace thinslab
