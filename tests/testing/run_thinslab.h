// SPDX-License-Identifier: Apache-2.0
// Runs the real `thinslab` binary of the build tree (THINSLAB_BINARY_DIR, set by
// thinslab_add_test) and captures its exit code and combined stdout + stderr.
#pragma once

#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <string>

namespace thinslab {

inline std::string ThinslabBinary() {
  const char* bin_dir = std::getenv("THINSLAB_BINARY_DIR");
  return std::string(bin_dir ? bin_dir : ".") + "/app/thinslab";
}

struct RunResult {
  int exit_code = -1;  // -1: killed by a signal or not started.
  std::string output;
};

// Any command line (a shell parses it), its stdout and stderr combined; stdin is empty, or the
// file `stdin_path` (e.g. the operator's Enter presses of `thinslab acquire` at a real rig).
inline RunResult RunShell(const std::string& command_line, const std::string& stdin_path = "/dev/null") {
  const std::string command = command_line + " 2>&1 <'" + stdin_path + "'";
  RunResult result;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return result;
  std::array<char, 4096> buffer;
  while (fgets(buffer.data(), buffer.size(), pipe) != nullptr) result.output += buffer.data();
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return result;
}

// `args` are appended to the command line as given (a shell parses them).
inline RunResult RunThinslab(const std::string& args, const std::string& stdin_path = "/dev/null") {
  return RunShell(ThinslabBinary() + " " + args, stdin_path);
}

}  // namespace thinslab
