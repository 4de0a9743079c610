// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/dmf_clustering.h"

#include <glog/logging.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numeric>
#include <random>
#include <sstream>

#include "thinslab/fit/nearest_rows.h"

namespace thinslab {
namespace {

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

}  // namespace

Eigen::VectorXd AffineNonNegativeWeights(const Eigen::MatrixXd& g, const Eigen::VectorXd& y, double* residual) {
  // Active set (Lawson and Hanson's NNLS with the affine constraint): solve the equality-
  // constrained problem on the free set via its KKT system [G^T G 1; 1^T 0] [w; l] = [G^T y; 1];
  // while a free weight is negative, step from the last feasible point towards the solution
  // until a weight reaches 0 and fix that one; when all are >= 0, free the fixed weight whose
  // multiplier g_j^T r + l (r = G w - y) is most negative, or stop: the KKT conditions hold.
  const int k = static_cast<int>(g.cols());
  std::vector<char> free(k, 0);
  Eigen::VectorXd w = Eigen::VectorXd::Zero(k);
  // Start from the single best column (feasible: one weight of 1).
  int start = 0;
  for (int j = 1; j < k; ++j) {
    if ((g.col(j) - y).squaredNorm() < (g.col(start) - y).squaredNorm()) start = j;
  }
  free[start] = 1;
  w[start] = 1;
  auto solve_free = [&](Eigen::VectorXd* z, double* l) {
    std::vector<int> idx;
    for (int j = 0; j < k; ++j) {
      if (free[j]) idx.push_back(j);
    }
    const int m = static_cast<int>(idx.size());
    Eigen::MatrixXd kkt = Eigen::MatrixXd::Zero(m + 1, m + 1);
    Eigen::VectorXd rhs(m + 1);
    for (int a = 0; a < m; ++a) {
      for (int c = 0; c < m; ++c) kkt(a, c) = g.col(idx[a]).dot(g.col(idx[c]));
      kkt(a, a) += 1e-9;  // Coincident representatives.
      kkt(a, m) = kkt(m, a) = 1;
      rhs[a] = g.col(idx[a]).dot(y);
    }
    rhs[m] = 1;
    const Eigen::VectorXd x = kkt.fullPivLu().solve(rhs);
    z->setZero(k);
    for (int a = 0; a < m; ++a) (*z)[idx[a]] = x[a];
    *l = x[m];
  };
  for (int outer = 0; outer < 4 * k; ++outer) {
    Eigen::VectorXd z;
    double l = 0;
    for (int inner = 0; inner < k; ++inner) {
      solve_free(&z, &l);
      int blocking = -1;
      double step = 1;
      for (int j = 0; j < k; ++j) {
        if (free[j] && z[j] < 0) {
          const double t = w[j] / (w[j] - z[j]);
          if (blocking < 0 || t < step) {
            step = t;
            blocking = j;
          }
        }
      }
      if (blocking < 0) break;
      w += step * (z - w);
      w[blocking] = 0;
      free[blocking] = 0;
    }
    for (int j = 0; j < k; ++j) w[j] = free[j] ? std::max(0.0, z[j]) : 0.0;
    const Eigen::VectorXd r = g * w - y;
    int entering = -1;
    double most_negative = -1e-12 * std::max(1.0, y.squaredNorm());
    for (int j = 0; j < k; ++j) {
      if (free[j]) continue;
      const double multiplier = g.col(j).dot(r) + l;
      if (multiplier < most_negative) {
        most_negative = multiplier;
        entering = j;
      }
    }
    if (entering < 0) break;
    free[entering] = 1;
  }
  const double sum = w.sum();
  if (sum > 0) w /= sum;
  *residual = (g * w - y).norm();
  return w;
}

bool DmfClusteringOptions::Check(std::string* error) const {
  std::ostringstream e;
  if (!(fraction > 0 && fraction <= 1)) e << "cluster fraction must be in (0, 1], got " << fraction;
  else if (min_representatives < 1) e << "min_representatives must be >= 1, got " << min_representatives;
  else if (pca_dims < 1) e << "pca_dims must be >= 1, got " << pca_dims;
  else if (num_neighbors < 1 || num_neighbors > 16) e << "num_neighbors must be in [1, 16], got " << num_neighbors;
  else if (subsample < 100) e << "subsample must be >= 100, got " << subsample;
  else if (num_threads < 1 || num_threads > kMaxThreads)
    e << "num_threads must be in 1.." << kMaxThreads;
  *error = e.str();
  return error->empty();
}

DmfShapeClusterer::DmfShapeClusterer(const std::vector<uint8_t>& valid, const DmfClusteringOptions& options)
    : options_(options), num_points_(static_cast<int>(valid.size())), rng_(options.seed) {
  row_of_point_.assign(num_points_, -1);
  for (int p = 0; p < num_points_; ++p) {
    if (!valid[p]) continue;
    row_of_point_[p] = static_cast<int>(points_.size());
    points_.push_back(p);
  }
  if (points_.empty()) return;
  // Principal components of the shapes, from a subsample.
  sample_ = points_;
  std::shuffle(sample_.begin(), sample_.end(), rng_);
  sample_.resize(std::min<size_t>(sample_.size(), options.subsample));
}

void DmfShapeClusterer::FitProjection(const Eigen::MatrixXf& sample_shapes) {
  if (points_.empty()) return;
  CHECK_EQ(static_cast<size_t>(sample_shapes.rows()), sample_.size());
  const int dims = static_cast<int>(sample_shapes.cols());
  Eigen::VectorXd mean = Eigen::VectorXd::Zero(dims);
  for (size_t s = 0; s < sample_.size(); ++s) mean += sample_shapes.row(s).transpose().cast<double>();
  mean /= sample_.size();
  Eigen::MatrixXd centred(sample_.size(), dims);
  for (size_t s = 0; s < sample_.size(); ++s) centred.row(s) = sample_shapes.row(s).cast<double>() - mean.transpose();
  // The lower triangle in blocks of columns on the threads: each block is one product whose sums
  // do not depend on the threads (a single product of the whole matrix ran on one core and
  // computed both triangles: 4.7 of the 9.7 s of 1600 nodes).
  Eigen::MatrixXd covariance = Eigen::MatrixXd::Zero(dims, dims);  // Upper triangle unused, but defined.
  constexpr int kBlockColumns = 64;
  const int blocks = (dims + kBlockColumns - 1) / kBlockColumns;
  const double scale = 1.0 / std::max<size_t>(1, sample_.size() - 1);
  // Blocks of the lower triangle shrink towards the right: largest first, for the threads' balance.
  ParallelFor(blocks, options_.num_threads, [&](int b) {
    const int j0 = b * kBlockColumns, width = std::min(kBlockColumns, dims - j0);
    covariance.block(j0, j0, dims - j0, width).noalias() =
        scale * (centred.rightCols(dims - j0).transpose() * centred.middleCols(j0, width));
  });
  // The eigen-solver reads the lower triangle only.
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> eig(covariance);
  const int pca = std::min(options_.pca_dims, dims);
  basis_ = eig.eigenvectors().rightCols(pca).cast<float>();
  const double total_variance = std::max(1e-300, eig.eigenvalues().sum());
  pca_explained_ = eig.eigenvalues().tail(pca).sum() / total_variance;
  mean_ = mean.transpose().cast<float>();
  projected_.resize(points_.size(), pca);
  shape_norm_.assign(points_.size(), 0.0);
}

void DmfShapeClusterer::Project(int p, const Eigen::MatrixXf& shapes, int row) {
  const int k = row_of_point_[p];
  CHECK_GE(k, 0) << "DmfShapeClusterer::Project: point " << p << " is not valid";
  projected_.row(k) = (shapes.row(row) - mean_) * basis_;
  shape_norm_[k] = (shapes.row(row).cast<double>()).norm();
}

DmfClustering ClusterSlices(const Eigen::MatrixXf& shapes, const std::vector<uint8_t>& valid,
                            const DmfClusteringOptions& options) {
  CHECK_EQ(static_cast<size_t>(shapes.rows()), valid.size());
  DmfShapeClusterer clusterer(valid, options);
  const std::vector<int>& sample = clusterer.pca_sample();
  Eigen::MatrixXf sample_shapes(sample.size(), shapes.cols());
  for (size_t s = 0; s < sample.size(); ++s) sample_shapes.row(s) = shapes.row(sample[s]);
  clusterer.FitProjection(sample_shapes);
  for (size_t p = 0; p < valid.size(); ++p) {
    if (valid[p]) clusterer.Project(static_cast<int>(p), shapes, static_cast<int>(p));
  }
  return clusterer.Cluster();
}

DmfClustering DmfShapeClusterer::Cluster(ProgressTracker* progress) {
  int step = kProjectionSteps;
  auto next_step = [&]() { return progress == nullptr || progress->Report(++step); };
  DmfClustering out;
  out.num_neighbors = options_.num_neighbors;
  out.neighbors.assign(static_cast<size_t>(num_points_) * options_.num_neighbors, -1);
  out.weights.assign(out.neighbors.size(), 0.0);
  out.cluster.assign(num_points_, -1);
  if (points_.empty()) return out;
  const DmfClusteringOptions& options = options_;
  const std::vector<int>& points = points_;
  const RowMatrix& projected = projected_;
  std::mt19937_64& rng = rng_;
  const int pca = static_cast<int>(basis_.cols());
  out.pca_explained = pca_explained_;

  const int num_clusters = std::min<int>(
      static_cast<int>(points.size()),
      std::max(options.min_representatives, static_cast<int>(std::lround(options.fraction * points.size()))));

  // k-means++ seeding and Lloyd iterations on the subsample (in projected coordinates).
  std::vector<int> sample_rows(points.size());
  std::iota(sample_rows.begin(), sample_rows.end(), 0);
  std::shuffle(sample_rows.begin(), sample_rows.end(), rng);
  sample_rows.resize(std::max<size_t>(std::min<size_t>(sample_rows.size(), options.subsample),
                                      std::min<size_t>(sample_rows.size(), num_clusters)));
  RowMatrix sub(sample_rows.size(), pca);
  for (size_t s = 0; s < sample_rows.size(); ++s) sub.row(s) = projected.row(sample_rows[s]);
  RowMatrix centres(num_clusters, pca);
  {
    std::vector<double> d2(sub.rows(), std::numeric_limits<double>::max());
    std::uniform_int_distribution<int> first(0, static_cast<int>(sub.rows()) - 1);
    centres.row(0) = sub.row(first(rng));
    // The distances to the newest centre on the threads in slabs of rows; the total in row order.
    constexpr int kSlab = 1024;
    const int slabs = static_cast<int>((sub.rows() + kSlab - 1) / kSlab);
    for (int c = 1; c < num_clusters; ++c) {
      ParallelFor(slabs, options.num_threads, [&](int slab) {
        const int end = std::min<int>(static_cast<int>(sub.rows()), (slab + 1) * kSlab);
        for (int s = slab * kSlab; s < end; ++s) {
          d2[s] = std::min<double>(d2[s], (sub.row(s) - centres.row(c - 1)).squaredNorm());
        }
      });
      double total = 0;
      for (int s = 0; s < sub.rows(); ++s) total += d2[s];
      std::uniform_real_distribution<double> u(0, total);
      double target = u(rng);
      int pick = 0;
      while (pick < sub.rows() - 1 && target > d2[pick]) target -= d2[pick++];
      centres.row(c) = sub.row(pick);
    }
  }
  if (!next_step()) return out;
  std::vector<int> label(sub.rows(), 0);
  for (int it = 0; it < options.kmeans_iterations; ++it) {
    out.exhaustive_searches +=
        ForEachNearestRows(sub, centres, 1, options.num_threads,
                           [&](int s, const int* nearest, const float*, int) { label[s] = nearest[0]; });
    RowMatrix sum = RowMatrix::Zero(num_clusters, pca);
    std::vector<int> count(num_clusters, 0);
    for (int s = 0; s < sub.rows(); ++s) {
      sum.row(label[s]) += sub.row(s);
      ++count[label[s]];
    }
    for (int c = 0; c < num_clusters; ++c) {
      if (count[c] > 0) centres.row(c) = sum.row(c) / count[c];
    }
    if (!next_step()) return out;
  }

  // Assign every point (on the threads); the member nearest its centre represents the cluster
  // (in point order: the first of equally near members).
  std::vector<float> centre_d(points.size());
  out.exhaustive_searches += ForEachNearestRows(projected, centres, 1, options.num_threads,
                                                [&](int k, const int* nearest, const float* d2, int) {
                                                  centre_d[k] = d2[0];
                                                  out.cluster[points[k]] = nearest[0];
                                                });
  std::vector<int> nearest_point(num_clusters, -1);
  std::vector<float> nearest_d(num_clusters, std::numeric_limits<float>::max());
  for (size_t k = 0; k < points.size(); ++k) {
    const int c = out.cluster[points[k]];
    if (centre_d[k] < nearest_d[c]) {
      nearest_d[c] = centre_d[k];
      nearest_point[c] = static_cast<int>(k);
    }
  }
  std::vector<float>().swap(centre_d);
  if (!next_step()) return out;
  std::vector<int> rep_rows;
  for (int c = 0; c < num_clusters; ++c) {
    if (nearest_point[c] >= 0) rep_rows.push_back(nearest_point[c]);
  }
  RowMatrix reps(rep_rows.size(), pca);
  for (size_t r = 0; r < rep_rows.size(); ++r) {
    reps.row(r) = projected.row(rep_rows[r]);
    out.representatives.push_back(points[rep_rows[r]]);
  }
  std::vector<int> rep_of_row(points.size(), -1);
  for (size_t r = 0; r < rep_rows.size(); ++r) rep_of_row[rep_rows[r]] = static_cast<int>(r);

  // Eqs. 20-22: nearest representatives and their affine, non-negative weights.
  const int k_nn = std::min<int>(options.num_neighbors, static_cast<int>(rep_rows.size()));
  // Each point's relative residual (-1: none), summed in point order after the threads.
  std::vector<double> relative_residual(points.size(), -1);
  // Representatives themselves are their own neighbour (weight 1); the search skips nothing, so
  // a representative's row costs one search it does not use.
  out.exhaustive_searches +=
      ForEachNearestRows(projected, reps, k_nn, options.num_threads, [&](int k, const int* order, const float*, int) {
        const size_t base = static_cast<size_t>(points[k]) * options.num_neighbors;
        if (rep_of_row[k] >= 0) {
          out.neighbors[base] = rep_of_row[k];
          out.weights[base] = 1;
          return;
        }
        Eigen::MatrixXd g(pca, k_nn);
        for (int j = 0; j < k_nn; ++j) g.col(j) = reps.row(order[j]).transpose().cast<double>();
        const Eigen::VectorXd y = projected.row(k).transpose().cast<double>();
        double residual = 0;
        const Eigen::VectorXd w = AffineNonNegativeWeights(g, y, &residual);
        for (int j = 0; j < k_nn; ++j) {
          out.neighbors[base + j] = order[j];
          out.weights[base + j] = w[j];
        }
        if (shape_norm_[k] > 0) relative_residual[k] = residual / shape_norm_[k];
      });
  double residual_sum = 0;
  int residual_count = 0;
  for (const double r : relative_residual) {
    if (r < 0) continue;
    residual_sum += r;
    ++residual_count;
  }
  out.mean_weight_residual = residual_count > 0 ? residual_sum / residual_count : 0;
  next_step();
  return out;
}

}  // namespace thinslab
