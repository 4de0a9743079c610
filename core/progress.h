// SPDX-License-Identifier: Apache-2.0
// Progress and cancellation of long operations (issue #25 item 5), in the manner of Ceres's
// IterationCallback: an option `ProgressCallback progress` of the operation's options struct,
// called with what is done so far; returning false cancels the operation, which then returns an
// error ending in "cancelled" (a pipeline writes nothing: its staged output folder is dropped).
//
// The callback runs on the thread that called the operation, never on a worker thread, so a
// Python callable (which needs the interpreter lock the caller holds) is safe.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <string>

namespace thinslab {

struct ProgressUpdate {
  std::string stage;     // What runs, e.g. "fit dmf: representative fits".
  int64_t done = 0;      // Items done of `total` (points, dots, iterations).
  int64_t total = 0;
  double elapsed_s = 0;  // Since the stage started.
  double eta_s = -1;     // Estimated seconds left; -1 = not known yet.
};

// Returns false to cancel.
using ProgressCallback = std::function<bool(const ProgressUpdate&)>;

// One stage's reports: elapsed time, ETA from the rate since the first report, at most one call per
// `min_interval_s` (and always at the first and the last item). Cancellation is sticky and may
// be read from any thread (cancelled()); Report() must be called on the calling thread only.
class ProgressTracker {
 public:
  ProgressTracker(const ProgressCallback& callback, std::string stage, int64_t total, double min_interval_s = 0.25)
      : callback_(callback), start_(std::chrono::steady_clock::now()), min_interval_s_(min_interval_s) {
    update_.stage = std::move(stage);
    update_.total = total;
  }

  // Reports `done` of total; false once cancelled.
  bool Report(int64_t done) {
    if (cancelled_) return false;
    if (!callback_) return true;
    // The same count again (a stage's last item reported by two loops): nothing new to say.
    if (reported_ && std::clamp<int64_t>(done, 0, update_.total) == update_.done) return true;
    const double now = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    const bool edge = done <= 0 || done >= update_.total || !reported_;
    if (!edge && now - last_report_s_ < min_interval_s_) return true;
    update_.done = std::clamp<int64_t>(done, 0, update_.total);
    update_.elapsed_s = now;
    if (!reported_) {
      origin_s_ = now;
      origin_done_ = update_.done;
    }
    // The rate since the first report: work before it (a band read from disk, a set-up) is not
    // the rate of the items (an ETA of 968 248 s after 1 point in 3 s of reading a band).
    update_.eta_s = update_.done > origin_done_
                        ? (now - origin_s_) * static_cast<double>(update_.total - update_.done) /
                              static_cast<double>(update_.done - origin_done_)
                        : -1;
    last_report_s_ = now;
    reported_ = true;
    if (!callback_(update_)) cancelled_ = true;
    return !cancelled_;
  }

  bool cancelled() const { return cancelled_; }

 private:
  const ProgressCallback& callback_;
  ProgressUpdate update_;
  std::chrono::steady_clock::time_point start_;
  double min_interval_s_;
  double last_report_s_ = 0;
  double origin_s_ = 0;  // Time and count of the first report, where the rate starts.
  int64_t origin_done_ = 0;
  bool reported_ = false;
  std::atomic<bool> cancelled_{false};
};

}  // namespace thinslab
