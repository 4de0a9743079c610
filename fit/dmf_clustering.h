// SPDX-License-Identifier: Apache-2.0
// k-means acceleration of the dual-microfacet fit (Dai et al. 2009, Sec. 4.3): the BTDF slices
// of all points are clustered, only one representative point per cluster is fitted, and every
// other point's model is the combination of its nearby representatives' models with the
// weights that best reproduce its own slice (Eqs. 20-22).
//
// Choices the paper leaves open (docs/models/dual_microfacet_fit.md):
//  - Slices are compared by shape: each point's training measurements (R - rho_d, clipped at 0)
//    divided by their sum, so that k_s and rho_d stay per point.
//  - Distances and Eq. 21 are evaluated in the span of the leading principal components of those
//    shapes (Eq. 21 is linear and Eq. 22 makes it affine, so it holds in any affine projection;
//    the truncation error is reported). This makes the clustering cost independent of the
//    number of dots.
//  - Cluster centres are found by k-means++ and Lloyd iterations on a random subsample, then
//    every point is assigned; the representative of a cluster is its member nearest the centre
//    (a real point, fitted with its own data).
//  - Nearest centres and representatives are found exactly but without comparing every point with
//    every one of them (fit/nearest_rows.h), so the cost grows about as points^1.5, not points^2.
//  - N_i: the num_neighbors representatives nearest to point i; weights solve Eqs. 21-22 in the
//    least-squares sense with w >= 0 (AffineNonNegativeWeights, an exact active-set solver), so
//    interpolated NDFs stay non-negative.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#include "thinslab/core/parallel.h"
#include "thinslab/core/progress.h"

namespace thinslab {

struct DmfClusteringOptions {
  double fraction = 0.01;      // Representatives per point (Dai: 1 %).
  // At least this many (capped at the point count): 1 % of a small grid is too few to cover
  // its materials (16 representatives for 40 x 40 points smeared nine regions together).
  int min_representatives = 64;
  int pca_dims = 24;
  int kmeans_iterations = 15;
  int subsample = 20000;       // Points used to place the centres.
  int num_neighbors = 4;       // |N_i|.
  uint64_t seed = 1;
  // Threads of the distance computations (the result does not depend on it).
  int num_threads = DefaultThreadCount();
  bool Check(std::string* error) const;
};

struct DmfClustering {
  std::vector<int> representatives;  // Point index of each representative.
  int num_neighbors = 0;
  // For point p: neighbors[p * num_neighbors + k] is an index into `representatives` (or -1)
  // and weights[...] its Eq. 20 weight; representatives have themselves with weight 1.
  std::vector<int> neighbors;
  std::vector<double> weights;
  std::vector<int> cluster;         // k-means cluster of each point (-1 for excluded points).
  double pca_explained = 0;         // Fraction of the shape variance the projection keeps.
  double mean_weight_residual = 0;  // Mean relative residual of Eq. 21 in the projection.
  // Nearest-neighbour queries (Lloyd iterations, assignment, Eq. 20) that the anchors' lists could
  // not settle and that compared every target (fit/nearest_rows.h).
  int64_t exhaustive_searches = 0;
};

// `shapes`: one row per point (normalised training slice, see above); `valid[p]` false excludes
// a point (it gets no neighbours).
DmfClustering ClusterSlices(const Eigen::MatrixXf& shapes, const std::vector<uint8_t>& valid,
                            const DmfClusteringOptions& options);

// ClusterSlices in steps, for maps whose shapes are never all in memory at once (issue #29,
// `fit dmf --max-memory`): the principal components from the subsample's shapes, then every
// valid point's shape projected (in any order, e.g. one band of points at a time), then the
// clustering. The same random draws in the same order as ClusterSlices, so the same result.
class DmfShapeClusterer {
 public:
  DmfShapeClusterer(const std::vector<uint8_t>& valid, const DmfClusteringOptions& options);
  // The points whose shapes FitProjection needs, in the order it needs them.
  const std::vector<int>& pca_sample() const { return sample_; }
  // Row s of `sample_shapes`: the shape of pca_sample()[s].
  void FitProjection(const Eigen::MatrixXf& sample_shapes);
  // Row `row` of `shapes` is the shape of valid point p (after FitProjection; thread-safe for
  // distinct points).
  void Project(int p, const Eigen::MatrixXf& shapes, int row);
  // After every valid point was projected. Reports to `progress` (optional) the steps done of
  // num_steps(), counting the projection's kProjectionSteps as done; stops early once cancelled
  // (progress->cancelled(): the result is then incomplete).
  DmfClustering Cluster(ProgressTracker* progress = nullptr);
  // The principal components and the projection, the k-means++ seeding, the Lloyd iterations,
  // the assignment of every point and the Eq. 20 neighbours.
  static constexpr int kProjectionSteps = 2;
  int num_steps() const { return kProjectionSteps + 1 + options_.kmeans_iterations + 2; }

 private:
  using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  DmfClusteringOptions options_;
  int num_points_ = 0;
  std::mt19937_64 rng_;
  std::vector<int> points_, row_of_point_, sample_;
  Eigen::RowVectorXf mean_;
  Eigen::MatrixXf basis_;
  double pca_explained_ = 0;
  RowMatrix projected_;
  std::vector<double> shape_norm_;  // |shape| of each valid point, for the Eq. 21 residual's scale.
};

// Eqs. 21-22 with w >= 0: the least-squares solution of G w = y (columns of G: the neighbouring
// representatives' slices, y: the point's) subject to sum w = 1 and w >= 0, exact (an active set
// that also re-frees weights whose KKT multiplier says so); `residual` = |G w - y|.
Eigen::VectorXd AffineNonNegativeWeights(const Eigen::MatrixXd& g, const Eigen::VectorXd& y, double* residual);

}  // namespace thinslab
