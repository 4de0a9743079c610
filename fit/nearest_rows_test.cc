// SPDX-License-Identifier: Apache-2.0
// The anchor-pruned nearest-neighbour search (fit/nearest_rows.h) against comparing every query
// with every target: the same neighbours, in the same order, on clustered data (where the lists
// settle almost every query), on uniform noise in 24 dimensions (where many queries fall back to
// the exhaustive search), with duplicate targets, and on any number of threads.
#include "thinslab/fit/nearest_rows.h"

#include <gtest/gtest.h>

#include <random>

namespace thinslab {
namespace {

std::vector<std::vector<int>> BruteForce(const NearestRowMatrix& q, const NearestRowMatrix& t, int k) {
  std::vector<std::vector<int>> out(q.rows());
  for (int i = 0; i < q.rows(); ++i) {
    std::vector<std::pair<float, int>> d;
    for (int j = 0; j < t.rows(); ++j) {
      d.push_back(
          {nearest_rows_internal::SquaredDistance(q.row(i).data(), t.row(j).data(), static_cast<int>(t.cols())), j});
    }
    std::sort(d.begin(), d.end());
    for (int j = 0; j < std::min<int>(k, static_cast<int>(t.rows())); ++j) out[i].push_back(d[j].second);
  }
  return out;
}

int64_t Search(const NearestRowMatrix& q, const NearestRowMatrix& t, int k, int threads,
               std::vector<std::vector<int>>* found) {
  found->assign(q.rows(), {});
  return ForEachNearestRows(q, t, k, threads, [&](int i, const int* idx, const float* d2, int count) {
    for (int j = 0; j < count; ++j) {
      (*found)[i].push_back(idx[j]);
      if (j > 0) {
        EXPECT_LE(d2[j - 1], d2[j]);
      }
    }
  });
}

// Points on segments between nine "materials" in 24 dimensions, with a little noise: the shape
// of the clustering's projected slices.
NearestRowMatrix Clustered(int rows, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uniform(0, 1);
  std::normal_distribution<float> noise(0, 0.01f);
  NearestRowMatrix materials(9, 24);
  std::mt19937 material_rng(1);
  for (int i = 0; i < materials.size(); ++i)
    materials.data()[i] = std::uniform_real_distribution<float>(0, 1)(material_rng);
  NearestRowMatrix out(rows, 24);
  for (int r = 0; r < rows; ++r) {
    const int a = r % 9, b = (r / 9) % 9;
    const float s = uniform(rng);
    for (int c = 0; c < 24; ++c) out(r, c) = s * materials(a, c) + (1 - s) * materials(b, c) + noise(rng);
  }
  return out;
}

TEST(NearestRows, ClusteredDataIsExactAndPruned) {
  const NearestRowMatrix targets = Clustered(3000, 2), queries = Clustered(6000, 3);
  for (int k : {1, 4}) {
    std::vector<std::vector<int>> found;
    const int64_t exhaustive = Search(queries, targets, k, 2, &found);
    EXPECT_EQ(found, BruteForce(queries, targets, k)) << "k " << k;
    // The lists settle almost every query; exhaustive searches on all would still be exact.
    EXPECT_LT(exhaustive, queries.rows() / 10) << "k " << k;
  }
}

TEST(NearestRows, UniformNoiseFallsBackAndStaysExact) {
  std::mt19937 rng(4);
  std::normal_distribution<float> normal(0, 1);
  NearestRowMatrix targets(500, 24), queries(2000, 24);
  for (int i = 0; i < targets.size(); ++i) targets.data()[i] = normal(rng);
  for (int i = 0; i < queries.size(); ++i) queries.data()[i] = normal(rng);
  std::vector<std::vector<int>> found;
  const int64_t exhaustive = Search(queries, targets, 4, 2, &found);
  EXPECT_EQ(found, BruteForce(queries, targets, 4));
  EXPECT_GT(exhaustive, 0);  // In 24 noise dimensions the triangle bound rarely holds.
}

TEST(NearestRows, DuplicatesTiesAndFewTargetsKeepTheIndexOrder) {
  NearestRowMatrix targets = Clustered(200, 5);
  for (int r = 100; r < 200; ++r) targets.row(r) = targets.row(r - 100);  // Every target twice.
  const NearestRowMatrix queries = Clustered(500, 6);
  std::vector<std::vector<int>> found;
  Search(queries, targets, 4, 1, &found);
  EXPECT_EQ(found, BruteForce(queries, targets, 4));
  // Fewer targets than k: all of them.
  const NearestRowMatrix three = targets.topRows(3);
  Search(queries, three, 4, 2, &found);
  EXPECT_EQ(found, BruteForce(queries, three, 4));
  EXPECT_EQ(found[0].size(), 3u);
}

TEST(NearestRows, ThreadsDoNotChangeTheAnswer) {
  const NearestRowMatrix targets = Clustered(2000, 7), queries = Clustered(5000, 8);
  std::vector<std::vector<int>> one, two;
  EXPECT_EQ(Search(queries, targets, 4, 1, &one), Search(queries, targets, 4, 2, &two));
  EXPECT_EQ(one, two);
}

}  // namespace
}  // namespace thinslab
