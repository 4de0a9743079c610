// SPDX-License-Identifier: Apache-2.0
// ParallelFor: body(k) for k in [0, n) on num_threads threads (the caller's included), items
// handed out one at a time by an atomic counter, so uneven per-item costs balance themselves.
// body must be safe to call concurrently for different k.
#pragma once

#include <algorithm>
#include <atomic>
#include <thread>
#include <vector>

namespace thinslab {

template <typename Body>
void ParallelFor(int n, int num_threads, const Body& body) {
  std::atomic<int> next{0};
  auto worker = [&]() {
    for (int k = next++; k < n; k = next++) body(k);
  };
  std::vector<std::thread> threads;
  for (int t = 1; t < std::max(1, num_threads); ++t) threads.emplace_back(worker);
  worker();
  for (auto& t : threads) t.join();
}

}  // namespace thinslab
