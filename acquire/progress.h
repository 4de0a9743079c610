// SPDX-License-Identifier: Apache-2.0
// Progress of an acquisition on stderr: frames done of planned, capture rate and ETA. The rate
// counts only frames captured in this run, so frames skipped on resume (already on disk, taken
// in no time) do not make the ETA optimistic. On a terminal the line is rewritten in place
// (at most 4 times a second); otherwise one line is printed every `line_interval_s`.
#pragma once

#include <chrono>
#include <ostream>
#include <string>

namespace thinslab {

// "12/40 frames (30%), 2.0 frames/s, ETA 0:14" ; "ETA ?" until a frame was captured.
std::string FormatProgress(int done, int total, int captured_this_run, double elapsed_s);

class ProgressReporter {
 public:
  // `out` may be null (quiet).
  ProgressReporter(std::string label, int total, std::ostream* out, bool is_terminal, double line_interval_s = 5);
  // `done` steps of `total` (skipped ones included); `skipped` of them came from disk.
  void Update(int done, int skipped);
  // Final line (always printed unless quiet).
  void Finish(const std::string& outcome);

 private:
  void Print(bool final_line);

  std::string label_;
  int total_;
  std::ostream* out_;
  bool is_terminal_;
  double line_interval_s_;
  int done_ = 0, skipped_ = 0, printed_done_ = -1;
  std::chrono::steady_clock::time_point start_, last_print_;
  bool printed_ = false;
};

}  // namespace thinslab
