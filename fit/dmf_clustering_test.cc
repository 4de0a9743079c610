// SPDX-License-Identifier: Apache-2.0
// The k-means interpolation weights of the clustered dual-microfacet fit (Dai et al. 2009,
// Sec. 4.3): for a non-representative point i, w_ij over its nearest representatives N_i solve
// sum_j w_ij rho_j = rho_i (Eq. 21) with sum_j w_ij = 1 (Eq. 22), and thinslab adds w_ij >= 0 so
// that the interpolated NDFs of Eq. 20 stay non-negative (fit/dmf_clustering.h).
//
// The shapes here are built so that the answer is known: six prototype slices (lobes centred on
// different dots, non-negative and summing to 1 like the map fit's normalised slices), many
// identical copies of each (so every prototype is a tight cluster and one copy becomes its
// representative), and a few points that are known combinations of prototypes. Lobes that
// barely overlap keep the nearest representatives of a combination predictable: its own
// prototypes come first.
#include "thinslab/fit/dmf_clustering.h"

#include <gtest/gtest.h>

#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>
#include <vector>

namespace thinslab {
namespace {

constexpr int kDims = 30;         // Training dots per slice.
constexpr int kPrototypes = 6;
constexpr int kCopies = 50;       // Points per prototype.

class DmfClusteringWeights : public ::testing::Test {
 protected:
  void SetUp() override {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<double> u(0.5, 1.5);
    prototypes_.resize(kPrototypes);
    for (int k = 0; k < kPrototypes; ++k) {
      // A lobe of width ~1.5 dots at dot 2.5 + 5 k, with a random amplitude per dot (so that
      // the slices are not merely shifted copies of each other).
      const double centre = 2.5 + 5 * k;
      prototypes_[k] = Eigen::VectorXd::NullaryExpr(kDims, [&](Eigen::Index q) {
        return u(rng) * std::exp(-0.5 * (q - centre) * (q - centre) / (1.5 * 1.5));
      });
      prototypes_[k] /= prototypes_[k].sum();  // Normalised, as FitDualMicrofacetMaps builds them.
    }
  }

  // Rows: kCopies copies of each prototype (prototype k at rows k * kCopies ...), then `extra`.
  Eigen::MatrixXf Shapes(const std::vector<Eigen::VectorXd>& extra) const {
    Eigen::MatrixXf shapes(kPrototypes * kCopies + static_cast<int>(extra.size()), kDims);
    for (int k = 0; k < kPrototypes; ++k) {
      for (int c = 0; c < kCopies; ++c) shapes.row(k * kCopies + c) = prototypes_[k].transpose().cast<float>();
    }
    for (size_t e = 0; e < extra.size(); ++e) shapes.row(kPrototypes * kCopies + e) = extra[e].transpose().cast<float>();
    return shapes;
  }

  static DmfClusteringOptions Options() {
    DmfClusteringOptions options;
    options.fraction = 0.01;
    options.min_representatives = kPrototypes;  // One representative per prototype.
    options.num_neighbors = 4;                  // |N_i| < the number of representatives.
    return options;
  }

  // Weight of each prototype (through its representative) in point p's Eq. 20 combination;
  // checks on the way that every representative is a copy of a prototype.
  static std::map<int, double> PrototypeWeights(const DmfClustering& c, int p) {
    std::map<int, double> w;
    for (int k = 0; k < c.num_neighbors; ++k) {
      const int j = c.neighbors[static_cast<size_t>(p) * c.num_neighbors + k];
      if (j < 0) continue;
      const int rep = c.representatives[j];
      EXPECT_LT(rep, kPrototypes * kCopies) << "representative " << rep << " is not a prototype copy";
      w[rep / kCopies] += c.weights[static_cast<size_t>(p) * c.num_neighbors + k];
    }
    return w;
  }

  std::vector<Eigen::VectorXd> prototypes_;
};

TEST_F(DmfClusteringWeights, ReproduceRepresentativesAndConvexCombinations) {
  // A point inside the triangle of prototypes 0, 1, 2, one on the segment 3-4, and one outside
  // every convex hull (an affine but not convex combination of 0 and 5).
  const Eigen::VectorXd inside = 0.5 * prototypes_[0] + 0.3 * prototypes_[1] + 0.2 * prototypes_[2];
  const Eigen::VectorXd segment = 0.65 * prototypes_[3] + 0.35 * prototypes_[4];
  const Eigen::VectorXd outside = 1.3 * prototypes_[0] - 0.3 * prototypes_[5];
  const Eigen::MatrixXf shapes = Shapes({inside, segment, outside});
  const int num_points = static_cast<int>(shapes.rows());
  std::vector<uint8_t> valid(num_points, 1);
  const int invalid = 7;  // A copy of prototype 0 kept out (PrecheckSlice failed): no neighbours.
  valid[invalid] = 0;
  const DmfClustering c = ClusterSlices(shapes, valid, Options());

  // One representative per prototype.
  ASSERT_EQ(c.representatives.size(), static_cast<size_t>(kPrototypes));
  std::vector<int> reps_of(kPrototypes, 0);
  for (int rep : c.representatives) {
    ASSERT_LT(rep, kPrototypes * kCopies);
    ++reps_of[rep / kCopies];
  }
  for (int k = 0; k < kPrototypes; ++k) EXPECT_EQ(reps_of[k], 1) << "prototype " << k;

  // Every valid point: non-negative weights (thinslab's constraint on Eqs. 21-22) that sum to 1
  // (Eq. 22); the excluded point has none.
  for (int p = 0; p < num_points; ++p) {
    double sum = 0;
    for (int k = 0; k < c.num_neighbors; ++k) {
      const size_t idx = static_cast<size_t>(p) * c.num_neighbors + k;
      EXPECT_GE(c.weights[idx], 0) << "point " << p;
      if (c.neighbors[idx] < 0) {
        EXPECT_EQ(c.weights[idx], 0) << "point " << p;
      }
      sum += c.weights[idx];
    }
    if (valid[p]) {
      EXPECT_NEAR(sum, 1, 1e-6) << "point " << p;
    } else {
      EXPECT_EQ(sum, 0) << "point " << p;
      EXPECT_EQ(c.neighbors[static_cast<size_t>(p) * c.num_neighbors], -1);
    }
  }

  // A representative has itself with weight 1; a point identical to a representative's slice
  // (another copy) is reproduced by that representative alone (the unique solution of Eqs.
  // 21-22 for affinely independent slices).
  for (int p = 0; p < kPrototypes * kCopies; ++p) {
    if (!valid[p]) continue;
    const std::map<int, double> w = PrototypeWeights(c, p);
    EXPECT_NEAR(w.count(p / kCopies) ? w.at(p / kCopies) : 0.0, 1, 1e-4) << "point " << p;
  }

  // Convex combinations of representatives: the weights are the combination's (tolerance 1e-4,
  // measured errors below 1e-5: the shapes are stored as floats; the projection keeps all of
  // their variance here).
  const int first_extra = kPrototypes * kCopies;
  const std::map<int, double> w_inside = PrototypeWeights(c, first_extra);
  const std::map<int, double> expected_inside = {{0, 0.5}, {1, 0.3}, {2, 0.2}};
  for (int k = 0; k < kPrototypes; ++k) {
    const double got = w_inside.count(k) ? w_inside.at(k) : 0.0;
    const double want = expected_inside.count(k) ? expected_inside.at(k) : 0.0;
    EXPECT_NEAR(got, want, 1e-4) << "inside, prototype " << k;
  }
  const std::map<int, double> w_segment = PrototypeWeights(c, first_extra + 1);
  for (int k = 0; k < kPrototypes; ++k) {
    const double got = w_segment.count(k) ? w_segment.at(k) : 0.0;
    EXPECT_NEAR(got, k == 3 ? 0.65 : k == 4 ? 0.35 : 0.0, 1e-4) << "segment, prototype " << k;
  }
  // Outside every hull: the unconstrained affine solution of Eqs. 21-22 over N_i (prototype 0
  // and three others; prototype 5 is farther) would give prototype 0 a weight above 1 and the
  // others negative ones. With w >= 0 (non-negative weights and sum 1 checked above) the nearest
  // admissible combination is the vertex, prototype 0 alone: the lobes barely overlap, so the
  // other prototypes point away from the point.
  const std::map<int, double> w_outside = PrototypeWeights(c, first_extra + 2);
  EXPECT_NEAR(w_outside.count(0) ? w_outside.at(0) : 0.0, 1, 1e-4);
}

// The solver of Eqs. 21-22 with w >= 0 against brute force: every subset of the columns, the
// equality-constrained least squares on it, the best feasible one. 400 random problems of 4
// and 8 columns in 6 dimensions (rank-deficient and over-determined mixes), y often outside the
// hull so that the bound constraints are active. The earlier solver, which only dropped the most
// negative weight and never re-freed one, missed the optimum on 40 of the 400.
double BruteForceAffineResidual(const Eigen::MatrixXd& g, const Eigen::VectorXd& y) {
  const int k = static_cast<int>(g.cols());
  double best = 1e300;
  for (int mask = 1; mask < (1 << k); ++mask) {
    std::vector<int> idx;
    for (int j = 0; j < k; ++j) {
      if (mask & (1 << j)) idx.push_back(j);
    }
    const int m = static_cast<int>(idx.size());
    Eigen::MatrixXd kkt = Eigen::MatrixXd::Zero(m + 1, m + 1);
    Eigen::VectorXd rhs(m + 1);
    for (int a = 0; a < m; ++a) {
      for (int c = 0; c < m; ++c) kkt(a, c) = g.col(idx[a]).dot(g.col(idx[c]));
      kkt(a, a) += 1e-9;
      kkt(a, m) = kkt(m, a) = 1;
      rhs[a] = g.col(idx[a]).dot(y);
    }
    rhs[m] = 1;
    const Eigen::VectorXd x = kkt.fullPivLu().solve(rhs);
    Eigen::VectorXd w = Eigen::VectorXd::Zero(k);
    bool feasible = true;
    for (int a = 0; a < m; ++a) {
      feasible = feasible && x[a] >= -1e-12;
      w[idx[a]] = x[a];
    }
    if (feasible) best = std::min(best, (g * w - y).norm());
  }
  return best;
}

TEST(AffineNonNegativeWeights, MatchesBruteForceOnRandomProblems) {
  std::mt19937_64 rng(7);
  std::normal_distribution<double> normal;
  int worse = 0;
  for (int trial = 0; trial < 400; ++trial) {
    const int k = trial % 2 == 0 ? 4 : 8;
    Eigen::MatrixXd g(6, k);
    for (int r = 0; r < 6; ++r) {
      for (int c = 0; c < k; ++c) g(r, c) = normal(rng);
    }
    Eigen::VectorXd y(6);
    for (int r = 0; r < 6; ++r) y[r] = 2 * normal(rng);
    double residual = 0;
    const Eigen::VectorXd w = AffineNonNegativeWeights(g, y, &residual);
    ASSERT_NEAR(w.sum(), 1, 1e-9) << "trial " << trial;
    ASSERT_GE(w.minCoeff(), 0) << "trial " << trial;
    EXPECT_NEAR(residual, (g * w - y).norm(), 1e-9);
    const double best = BruteForceAffineResidual(g, y);
    EXPECT_LE(residual, best + 1e-6 * (1 + best)) << "trial " << trial << ": " << residual << " vs " << best;
    worse += residual > best + 1e-6 * (1 + best);
  }
  EXPECT_EQ(worse, 0);
}

}  // namespace
}  // namespace thinslab

namespace thinslab {
namespace {

// The clustering's distance loops run on threads in fixed blocks: the result must not depend on
// the thread count (fit dmf's maps, under any --threads or mpirun, bit for bit).
TEST(DmfClusteringThreads, SameClusteringWhateverTheThreads) {
  constexpr int kPoints = 6000, kNodes = 40;
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> uniform(0, 1);
  Eigen::MatrixXf materials(5, kNodes);
  for (int m = 0; m < 5; ++m) {
    for (int n = 0; n < kNodes; ++n) materials(m, n) = uniform(rng);
  }
  Eigen::MatrixXf shapes(kPoints, kNodes);
  for (int p = 0; p < kPoints; ++p) {
    const float t = uniform(rng);
    shapes.row(p) = t * materials.row(p % 5) + (1 - t) * materials.row((p / 5) % 5);
    for (int n = 0; n < kNodes; ++n) shapes(p, n) += 0.01f * uniform(rng);
  }
  std::vector<uint8_t> valid(kPoints, 1);
  valid[17] = 0;
  DmfClusteringOptions options;
  options.subsample = 2500;  // Seeding over three slabs of rows, assignment over three blocks.
  options.num_threads = 1;
  const DmfClustering one = ClusterSlices(shapes, valid, options);
  options.num_threads = 3;
  const DmfClustering three = ClusterSlices(shapes, valid, options);
  EXPECT_EQ(one.representatives.size(), 64u);
  EXPECT_EQ(one.representatives, three.representatives);
  EXPECT_EQ(one.cluster, three.cluster);
  EXPECT_EQ(one.neighbors, three.neighbors);
  EXPECT_EQ(one.weights, three.weights);
  EXPECT_EQ(one.mean_weight_residual, three.mean_weight_residual);
}

}  // namespace
}  // namespace thinslab
