// SPDX-License-Identifier: Apache-2.0
// Exact k-nearest-neighbour search between the rows of two small-dimensional point sets (the
// clustering's projected slice shapes against k-means centres or representatives, issue #29).
//
// Comparing every query with every target costs queries x targets, which at a fixed fraction of
// representatives grows as the square of the map's points (593 s of the clustering at 1200^2
// points). Instead, a few anchors are taken among the targets (every (m / A)-th target, A =
// sqrt(m)), each with the list of its L nearest targets and the distance R beyond which the list
// stops. A query is compared with the anchors, then with its nearest anchor's list only: by the
// triangle inequality a target outside the list lies at least R - |q - a| from the query, so when
// the k-th best listed distance is below that bound (with a margin for float rounding) the list
// holds the exact k nearest. Otherwise (rare on clustered data; the count is returned) the query
// is compared with every target. Distances are direct sums of squared differences, ties are broken
// by target index, and every query's answer is the same whatever the threads.
#pragma once

#include <Eigen/Core>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <vector>

#include "thinslab/core/parallel.h"

namespace thinslab {

using NearestRowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

namespace nearest_rows_internal {

inline float SquaredDistance(const float* a, const float* b, int dims) {
  // Eight partial sums: the compiler keeps them in vector registers (a single running sum is a
  // dependency chain the loop cannot be vectorised over without reordering the additions).
  float part[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  int i = 0;
  for (; i + 8 <= dims; i += 8) {
    for (int j = 0; j < 8; ++j) {
      const float d = a[i + j] - b[i + j];
      part[j] += d * d;
    }
  }
  for (; i < dims; ++i) {
    const float d = a[i] - b[i];
    part[0] += d * d;
  }
  return ((part[0] + part[1]) + (part[2] + part[3])) + ((part[4] + part[5]) + (part[6] + part[7]));
}

// The k best (squared distance, index) pairs seen so far, ascending; ties by index.
struct Best {
  explicit Best(int count) : k(count) {}
  void Offer(float d2, int index) {
    if (static_cast<int>(d2s.size()) == k && !Less(d2, index, d2s.back(), indices.back())) return;
    int pos = static_cast<int>(d2s.size());
    if (pos == k)
      --pos;
    else {
      d2s.push_back(0);
      indices.push_back(0);
    }
    while (pos > 0 && Less(d2, index, d2s[pos - 1], indices[pos - 1])) {
      d2s[pos] = d2s[pos - 1];
      indices[pos] = indices[pos - 1];
      --pos;
    }
    d2s[pos] = d2;
    indices[pos] = index;
  }
  static bool Less(float d2a, int a, float d2b, int b) { return d2a < d2b || (d2a == d2b && a < b); }
  void Clear() {
    d2s.clear();
    indices.clear();
  }
  int k;
  std::vector<float> d2s;
  std::vector<int> indices;
};

}  // namespace nearest_rows_internal

// For every row q of `queries`: visit(q, indices, squared_distances, count) with the
// min(k, targets) nearest rows of `targets`, nearest first (called on `num_threads` threads, so it
// must be safe for distinct q). Returns the number of queries that needed the exhaustive search.
template <typename Visit>
int64_t ForEachNearestRows(const NearestRowMatrix& queries, const NearestRowMatrix& targets, int k, int num_threads,
                           const Visit& visit) {
  using nearest_rows_internal::Best;
  using nearest_rows_internal::SquaredDistance;
  const int n = static_cast<int>(queries.rows()), m = static_cast<int>(targets.rows());
  const int dims = static_cast<int>(targets.cols());
  k = std::min(k, m);
  if (n == 0 || m == 0 || k <= 0) return 0;
  // sqrt(m) anchors, each listing the targets of about 8 anchors' cells (on the clustering
  // benchmark's shapes: 3.0 s at 360 000 points against 3.6-4.5 s with twice the anchors or longer
  // lists, 28 s at 1.44 million with 8 % of the queries exhaustive).
  constexpr int kListCells = 8;
  const int num_anchors = std::clamp(static_cast<int>(std::ceil(std::sqrt(static_cast<double>(m)))), 1, m);
  const int list_size = std::min(m, std::max(64, kListCells * ((m + num_anchors - 1) / num_anchors)));
  std::vector<int> anchors(num_anchors);
  for (int a = 0; a < num_anchors; ++a) anchors[a] = static_cast<int>(static_cast<int64_t>(a) * m / num_anchors);
  // Each anchor's list of its nearest targets and the distance R no unlisted target is nearer than.
  std::vector<int> lists(static_cast<size_t>(num_anchors) * list_size);
  std::vector<float> radius(num_anchors, std::numeric_limits<float>::infinity());
  ParallelFor(num_anchors, num_threads, [&](int a) {
    std::vector<std::pair<float, int>> d(m);
    const float* anchor = targets.row(anchors[a]).data();
    for (int t = 0; t < m; ++t) d[t] = {SquaredDistance(anchor, targets.row(t).data(), dims), t};
    if (list_size < m) {
      std::nth_element(d.begin(), d.begin() + list_size, d.end());
      radius[a] = std::sqrt(std::min_element(d.begin() + list_size, d.end())->first);
    }
    for (int j = 0; j < list_size; ++j) lists[static_cast<size_t>(a) * list_size + j] = d[j].second;
  });
  // A relative margin far above float rounding of the distances (about 1e-7 of their size).
  constexpr float kMargin = 1e-4f;
  std::atomic<int64_t> exhaustive{0};
  constexpr int kBlock = 256;
  ParallelFor((n + kBlock - 1) / kBlock, num_threads, [&](int block) {
    Best best(k), nearest_anchor(1);
    const int end = std::min(n, (block + 1) * kBlock);
    for (int q = block * kBlock; q < end; ++q) {
      const float* query = queries.row(q).data();
      nearest_anchor.Clear();
      for (int a = 0; a < num_anchors; ++a)
        nearest_anchor.Offer(SquaredDistance(query, targets.row(anchors[a]).data(), dims), a);
      const int a = nearest_anchor.indices[0];
      const float to_anchor = std::sqrt(nearest_anchor.d2s[0]);
      best.Clear();
      const int* list = &lists[static_cast<size_t>(a) * list_size];
      for (int j = 0; j < list_size; ++j)
        best.Offer(SquaredDistance(query, targets.row(list[j]).data(), dims), list[j]);
      const float kth = std::sqrt(best.d2s[k - 1]);
      const bool exact = list_size == m || kth * (1 + kMargin) + to_anchor * (1 + kMargin) < radius[a] * (1 - kMargin);
      if (!exact) {
        ++exhaustive;
        best.Clear();
        for (int t = 0; t < m; ++t) best.Offer(SquaredDistance(query, targets.row(t).data(), dims), t);
      }
      visit(q, best.indices.data(), best.d2s.data(), k);
    }
  });
  return exhaustive.load();
}

}  // namespace thinslab
