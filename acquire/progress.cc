// SPDX-License-Identifier: Apache-2.0
#include "thinslab/acquire/progress.h"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace thinslab {

std::string FormatProgress(int done, int total, int captured_this_run, double elapsed_s) {
  char buf[160];
  const double percent = total > 0 ? 100.0 * done / total : 100.0;
  int n = std::snprintf(buf, sizeof(buf), "%d/%d frames (%.0f%%)", done, total, percent);
  if (captured_this_run > 0 && elapsed_s > 0) {
    const double rate = captured_this_run / elapsed_s;
    const long remaining_s = std::lround(std::max(0, total - done) / rate);  // NOLINT(runtime/int)
    std::snprintf(buf + n, sizeof(buf) - n, ", %.2f frames/s, ETA %ld:%02ld", rate, remaining_s / 60,
                  remaining_s % 60);
  } else if (done < total) {
    std::snprintf(buf + n, sizeof(buf) - n, ", ETA ?");
  }
  return buf;
}

ProgressReporter::ProgressReporter(std::string label, int total, std::ostream* out, bool is_terminal,
                                   double line_interval_s)
    : label_(std::move(label)), total_(total), out_(out), is_terminal_(is_terminal),
      line_interval_s_(line_interval_s), start_(std::chrono::steady_clock::now()), last_print_(start_) {}

void ProgressReporter::Update(int done, int skipped) {
  // Frames skipped on resume arrive before any capture: restart the clock so they do not count.
  if (skipped > skipped_ && done == skipped) start_ = std::chrono::steady_clock::now();
  done_ = done;
  skipped_ = skipped;
  if (out_ == nullptr) return;
  const auto now = std::chrono::steady_clock::now();
  const double since = std::chrono::duration<double>(now - last_print_).count();
  if (!printed_ || since >= (is_terminal_ ? 0.25 : line_interval_s_) || done_ == total_) Print(false);
}

void ProgressReporter::Finish(const std::string& outcome) {
  if (out_ == nullptr) return;
  if (printed_done_ != done_ || is_terminal_) Print(true);
  *out_ << label_ << ": " << outcome << "\n";
  out_->flush();
}

void ProgressReporter::Print(bool final_line) {
  const auto now = std::chrono::steady_clock::now();
  last_print_ = now;
  printed_ = true;
  printed_done_ = done_;
  const double elapsed = std::chrono::duration<double>(now - start_).count();
  const std::string line = label_ + ": " + FormatProgress(done_, total_, done_ - skipped_, elapsed) +
                           (skipped_ > 0 ? " (" + std::to_string(skipped_) + " already on disk)" : "");
  if (is_terminal_) {
    *out_ << "\r" << line << "\x1b[K" << (final_line ? "\n" : "");
  } else {
    *out_ << line << "\n";
  }
  out_->flush();
}

}  // namespace thinslab
