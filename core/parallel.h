// SPDX-License-Identifier: Apache-2.0
// ParallelFor: body(k) for k in [0, n) on num_threads threads (the caller's included), items
// handed out one at a time by an atomic counter, so uneven per-item costs balance themselves.
// body must be safe to call concurrently for different k. The one thread loop of thinslab (the
// per-point fits, the model ladder, the HDR merge's row blocks, the slab tables' regions).
#pragma once

#include <algorithm>
#include <atomic>
#include <system_error>
#include <thread>
#include <vector>

#include "thinslab/core/progress.h"

namespace thinslab {

// The most threads any thinslab option accepts (--threads; docs/cli.md). Options::Check()
// refuses more; ParallelFor also never starts more threads than items.
inline constexpr int kMaxThreads = 256;

// The default of every `num_threads` option: all cores the system reports (1 when it reports
// none), at most kMaxThreads.
inline int DefaultThreadCount() {
  const unsigned cores = std::thread::hardware_concurrency();
  return std::clamp(static_cast<int>(cores), 1, kMaxThreads);
}

template <typename Body>
void ParallelFor(int n, int num_threads, const Body& body) {
  std::atomic<int> next{0};
  auto worker = [&]() {
    for (int k = next++; k < n; k = next++) body(k);
  };
  std::vector<std::thread> threads;
  const int count = std::min({std::max(1, num_threads), std::max(1, n), kMaxThreads});
  for (int t = 1; t < count; ++t) {
    // A system out of threads runs the work on the threads it could start.
    try {
      threads.emplace_back(worker);
    } catch (const std::system_error&) {
      break;
    }
  }
  worker();
  for (auto& t : threads) t.join();
}

// ParallelFor with progress: the calling thread reports the items done after each item it
// runs (core/progress.h: the callback never runs on a worker); once the callback cancels, no
// thread starts another item. Returns false when cancelled. `done_before`: items of the same
// stage finished by earlier calls (a stage run in parts, e.g. one band of map points at a time).
template <typename Body>
bool ParallelFor(int n, int num_threads, const Body& body, ProgressTracker* progress, int64_t done_before = 0) {
  if (progress == nullptr) {
    ParallelFor(n, num_threads, body);
    return true;
  }
  std::atomic<int> next{0};
  std::atomic<int64_t> done{0};
  auto worker = [&](bool reports) {
    for (int k = next++; k < n && !progress->cancelled(); k = next++) {
      body(k);
      const int64_t finished = ++done;
      if (reports) progress->Report(done_before + finished);
    }
  };
  std::vector<std::thread> threads;
  const int count = std::min({std::max(1, num_threads), std::max(1, n), kMaxThreads});
  for (int t = 1; t < count; ++t) {
    try {
      threads.emplace_back(worker, false);
    } catch (const std::system_error&) {
      break;
    }
  }
  worker(true);
  for (auto& t : threads) t.join();
  if (!progress->cancelled()) progress->Report(done_before + n);
  return !progress->cancelled();
}

}  // namespace thinslab
