// SPDX-License-Identifier: Apache-2.0
// Child processes: another program (Blender for the render round trip) or thinslab itself (one
// fit per capture in `thinslab batch`), with its output in a log file and stdin from /dev/null.
#pragma once

#include <sys/types.h>

#include <string>
#include <vector>

#include "thinslab/core/status.h"

namespace thinslab {

// Starts `argv` (argv[0] looked up on PATH unless it holds a '/') with stdout and stderr appended
// to `log_path`. The error names argv[0] and why it could not start (ENOENT: not found).
Status StartProgram(const std::vector<std::string>& argv, const std::string& log_path, pid_t* pid);

// Waits for `pid` (or, with pid -1, any child) to end: its pid and exit code (128 + the signal
// when a signal ended it).
Status WaitProgram(pid_t pid, pid_t* ended, int* exit_code);

// Whether `pid` has ended, without waiting: *ended true with its exit code (as WaitProgram's).
Status PollProgram(pid_t pid, bool* ended, int* exit_code);

// StartProgram then WaitProgram.
Status RunProgram(const std::vector<std::string>& argv, const std::string& log_path, int* exit_code);

// This process's own executable (/proc/self/exe), to run thinslab's commands as child processes.
Status SelfExecutable(std::string* path);

}  // namespace thinslab
