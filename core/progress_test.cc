// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/progress.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <thread>
#include <vector>

#include "thinslab/core/parallel.h"

namespace thinslab {
namespace {

TEST(Progress, ParallelForReportsOnTheCallingThreadUpToTheTotal) {
  const std::thread::id caller = std::this_thread::get_id();
  std::vector<ProgressUpdate> updates;
  bool off_thread = false;
  const ProgressCallback callback = [&](const ProgressUpdate& u) {
    off_thread |= std::this_thread::get_id() != caller;
    updates.push_back(u);
    return true;
  };
  ProgressTracker tracker(callback, "items", 200, 0.0);
  std::atomic<int> ran{0};
  EXPECT_TRUE(ParallelFor(200, 4, [&](int) { ++ran; }, &tracker));
  EXPECT_EQ(ran, 200);
  EXPECT_FALSE(off_thread);
  ASSERT_FALSE(updates.empty());
  EXPECT_EQ(updates.back().done, 200);
  EXPECT_EQ(updates.back().total, 200);
  EXPECT_EQ(updates.back().stage, "items");
  for (size_t k = 1; k < updates.size(); ++k) EXPECT_GE(updates[k].done, updates[k - 1].done);
}

TEST(Progress, CancellingStopsTheLoopEarly) {
  int calls = 0;
  const ProgressCallback callback = [&](const ProgressUpdate& u) {
    ++calls;
    return u.done < 5;
  };
  ProgressTracker tracker(callback, "items", 100000, 0.0);
  std::atomic<int> ran{0};
  // Each item takes a little time: on a loaded machine the worker thread could otherwise run all
  // the items before the calling thread, which reports and so cancels, is scheduled at all.
  EXPECT_FALSE(ParallelFor(
      100000, 2,
      [&](int) {
        std::this_thread::sleep_for(std::chrono::microseconds(10));
        ++ran;
      },
      &tracker));
  EXPECT_TRUE(tracker.cancelled());
  EXPECT_LT(ran, 100000);
  EXPECT_FALSE(tracker.Report(6));  // Sticky.
  const int after = calls;
  tracker.Report(7);
  EXPECT_EQ(calls, after);  // No callback once cancelled.
}

// A callback that keeps every update and never cancels.
ProgressCallback RecordInto(std::vector<ProgressUpdate>* updates) {
  return [updates](const ProgressUpdate& u) {
    updates->push_back(u);
    return true;
  };
}

TEST(Progress, EtaFromTheRateAndRateLimitedCalls) {
  std::vector<ProgressUpdate> updates;
  const ProgressCallback callback = RecordInto(&updates);
  ProgressTracker tracker(callback, "slow", 10, 3600.0);
  for (int k = 0; k <= 10; ++k) tracker.Report(k);
  // First and last only: the interval is an hour.
  ASSERT_EQ(updates.size(), 2u);
  EXPECT_EQ(updates.front().done, 0);
  EXPECT_EQ(updates.front().eta_s, -1);
  EXPECT_EQ(updates.back().done, 10);
  EXPECT_EQ(updates.back().eta_s, 0);
}

// A stage whose first report comes after its first item (the set-up before it is not the items'
// rate): no ETA until a second count, then the rate since that first report.
TEST(Progress, EtaStartsAtTheFirstReport) {
  std::vector<ProgressUpdate> updates;
  const ProgressCallback callback = RecordInto(&updates);
  ProgressTracker tracker(callback, "banded", 1000, 0.0);
  tracker.Report(1);
  tracker.Report(500);
  tracker.Report(1000);
  ASSERT_EQ(updates.size(), 3u);
  EXPECT_EQ(updates[0].eta_s, -1);
  EXPECT_GE(updates[1].eta_s, 0);
  // At most the time since the first report (499 items took it, 500 are left): not scaled by the
  // total time over 1 item.
  EXPECT_LE(updates[1].eta_s, 1.01 * (updates[1].elapsed_s - updates[0].elapsed_s) + 1e-9);
  EXPECT_EQ(updates[2].eta_s, 0);
}

TEST(Progress, NoCallbackNeverCancels) {
  const ProgressCallback none;
  ProgressTracker tracker(none, "quiet", 3);
  std::atomic<int> ran{0};
  EXPECT_TRUE(ParallelFor(3, 2, [&](int) { ++ran; }, &tracker));
  EXPECT_EQ(ran, 3);
}

}  // namespace
}  // namespace thinslab
