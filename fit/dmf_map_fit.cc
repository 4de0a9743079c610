// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/dmf_map_fit.h"

#include <glog/logging.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <random>
#include <sstream>

#include "thinslab/core/math.h"
#include "thinslab/core/parallel.h"
#include "thinslab/core/process_group.h"
#include "thinslab/fit/dmf_slice_shape.h"

namespace thinslab {
namespace {

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// Points per process and round when a group shares a loop out (issue #29): a round's results
// (up to about 10 KB a point with its NDF) stay a few MB per process; alone, the whole band at
// once, its points balanced over the threads as before.
constexpr int kPointsPerProcessRound = 512;
int PointChunk(const ProcessGroup& group, int count) {
  return group.distributed() ? kPointsPerProcessRound * group.size() : count;
}

// The compute and chunk_done of a band's loop over items [0, n), `item(k)` each, with progress:
// alone, reported after every item (ParallelFor); in a group, after every round (each process
// reports the same counts). `done_before`: the stage's items in the bands before.
void SetReportedCompute(ProcessGroup& group, int num_threads, ProgressTracker* progress, int64_t done_before,
                        const std::function<void(int k)>& item, DistributedLoop* loop) {
  loop->compute = [&group, num_threads, progress, done_before, item](int begin, int end) {
    const bool going = ParallelFor(
        end - begin, num_threads, [&](int k) { item(begin + k); }, group.distributed() ? nullptr : progress,
        done_before + begin);
    return going ? Status::Ok() : Status::Error("FitDualMicrofacetMaps: cancelled");
  };
  loop->chunk_done = [&group, progress, done_before](int, int end) {
    if (group.distributed() && !progress->Report(done_before + end)) {
      return Status::Error("FitDualMicrofacetMaps: cancelled");
    }
    return Status::Ok();
  };
}

}  // namespace

Eigen::Vector3d DmfSliceSet::PointPosition(int p) const {
  const int col = p % width, row = p / width;
  return Eigen::Vector3d(grid_min_m.x() + (col + 0.5) * pitch_m, grid_min_m.y() + (row + 0.5) * pitch_m, 0);
}

Eigen::Vector3d SlabLightEntryPoint(const Eigen::Vector3d& x, const Eigen::Vector3d& camera_centre, double thickness,
                                    double eta) {
  if (!(thickness > 0)) return x;
  // Snell at the flat face: the transverse part of the unit direction shrinks by 1/eta.
  const Eigen::Vector3d o = (camera_centre - x).normalized();
  const Eigen::Vector2d inside_xy = -o.head<2>() / eta;
  const double inside_z = std::sqrt(std::max(1e-12, 1 - inside_xy.squaredNorm()));
  const Eigen::Vector2d lateral = thickness * inside_xy / inside_z;
  return Eigen::Vector3d(x.x() + lateral.x(), x.y() + lateral.y(), -thickness);
}

Eigen::Vector3d DmfSliceSet::LightEntryPoint(int p) const {
  return SlabLightEntryPoint(PointPosition(p), camera_centre, glass_thickness_m, eta);
}

DmfSlice DmfSliceSet::Slice(int p) const {
  const Eigen::Vector3d x = PointPosition(p);
  const Eigen::Vector3d entry = LightEntryPoint(p);
  DmfSlice slice;
  slice.o = SampleToOptical((camera_centre - x).normalized());
  const int nd = num_dots();
  slice.i.resize(nd);
  slice.value.resize(nd);
  slice.solid_angle.resize(nd);
  if (PointSigmas(p) != nullptr) slice.sigma.resize(nd);
  slice.train = train;
  if (static_cast<int>(nd) == dots_nx * dots_ny) {
    slice.edge.resize(nd);
    for (int q = 0; q < nd; ++q) {
      const int ix = q % dots_nx, iy = q / dots_nx;
      slice.edge[q] = (ix == 0 ? kFirstColumn : 0) | (ix == dots_nx - 1 ? kLastColumn : 0) |
                      (iy == 0 ? kFirstRow : 0) | (iy == dots_ny - 1 ? kLastRow : 0);
    }
  }
  const float* values = PointValues(p);
  const float* sigmas = PointSigmas(p);
  for (int q = 0; q < nd; ++q) {
    const Eigen::Vector3d to_dot = dot_positions[q] - entry;
    const double r = to_dot.norm();
    slice.i[q] = SampleToOptical(to_dot / r);
    slice.value[q] = values[q];
    if (sigmas != nullptr) slice.sigma[q] = sigmas[q];
    slice.solid_angle[q] = dot_cell_area_m2 * (std::abs(to_dot.z()) / r) / (r * r);
  }
  slice.rho_d = EstimateDiffuse(slice, dots_nx, dots_ny);
  return slice;
}

const float* DmfSliceSet::PointValues(int p) const {
  return spill ? spill->Values(p) : value.data() + static_cast<size_t>(p) * num_dots();
}

const float* DmfSliceSet::PointSigmas(int p) const {
  if (spill) return spill->Sigmas(p);
  return sigma.empty() ? nullptr : sigma.data() + static_cast<size_t>(p) * num_dots();
}

Status ForEachPointBand(const DmfSliceSet& slices, const std::function<Status(int first, int count)>& body) {
  const int np = slices.num_points();
  if (!slices.spill) return body(0, np);
  const int band = slices.spill->band_points();
  for (int first = 0; first < np; first += band) {
    const int count = std::min(band, np - first);
    THINSLAB_RETURN_IF_ERROR(slices.spill->LoadBand(first, count));
    THINSLAB_RETURN_IF_ERROR(body(first, count));
  }
  return Status::Ok();
}

Status LoadPoint(const DmfSliceSet& slices, int p) {
  return slices.spill ? slices.spill->LoadBand(p, 1) : Status::Ok();
}

Status DmfSliceSet::Check() const {
  if (width <= 0 || height <= 0) return Status::Error("slice set: empty sample grid");
  if (!(pitch_m > 0)) return Status::Error("slice set: sample pitch must be > 0");
  if (dots_nx * dots_ny != num_dots()) return Status::Error("slice set: dot grid size does not match the dot count");
  if (num_dots() < 16) {
    return Status::Error("slice set: " + std::to_string(num_dots()) + " dots; the fit needs at least 4 x 4");
  }
  if (spill) {
    if (spill->num_points() != num_points() || spill->num_dots() != num_dots() || !value.empty()) {
      return Status::Error("slice set: the spill's size does not match the grid");
    }
  } else {
    if (value.size() != static_cast<size_t>(num_points()) * num_dots()) return Status::Error("slice set: value size");
    if (!sigma.empty() && sigma.size() != value.size()) return Status::Error("slice set: sigma size");
  }
  if (static_cast<int>(train.size()) != num_dots()) return Status::Error("slice set: train mask size");
  if (static_cast<int>(point_status.size()) != num_points()) return Status::Error("slice set: point status size");
  for (const auto& p : dot_positions) {
    if (!(p.z() < 0)) return Status::Error("slice set: dot positions must lie behind the sample (z < 0)");
  }
  if (!(camera_centre.z() > 0)) return Status::Error("slice set: camera must be on the +z side of the sample");
  if (!(glass_thickness_m >= 0) || !(eta > 1)) return Status::Error("slice set: need thickness >= 0 and eta > 1");
  for (const auto& p : dot_positions) {
    if (!(p.z() < -glass_thickness_m)) {
      return Status::Error("slice set: a dot lies within the slab's thickness (" + std::to_string(glass_thickness_m) +
                           " m) of the sample; check rig.sample.glass_thickness_m and the monitor distance");
    }
  }
  return Status::Ok();
}

bool HoldOutPattern::Check(std::string* error) const {
  std::ostringstream e;
  if (kind != "checkerboard" && kind != "random" && kind != "blocks") {
    e << "HoldOutPattern::kind (--hold-out-pattern) = '" << kind << "': expected checkerboard, random or blocks";
  } else if (!(fraction > 0 && fraction <= 0.9)) {
    e << "HoldOutPattern::fraction (--hold-out-fraction) = " << fraction << ": expected (0, 0.9]";
  } else if (block < 1 || block > 64) {
    e << "HoldOutPattern::block (--hold-out-block) = " << block << ": expected 1..64";
  }
  *error = e.str();
  return error->empty();
}

std::vector<uint8_t> HoldOutTrainMask(int nx, int ny, bool hold_out, const HoldOutPattern& pattern) {
  std::vector<uint8_t> train(static_cast<size_t>(nx) * ny, 1);
  if (!hold_out) return train;
  // The generator's raw output (std::mt19937_64 is fully specified, the standard distributions
  // are not): the same pattern on every platform.
  std::mt19937_64 rng(pattern.seed);
  for (int y = 0; y < ny; ++y) {
    for (int x = 0; x < nx; ++x) {
      bool fitted = true;
      if (pattern.kind == "checkerboard") {
        fitted = (x + y) % 2 == 0;
      } else if (pattern.kind == "blocks") {
        fitted = (x / pattern.block + y / pattern.block) % 2 == 0;
      } else {
        fitted = static_cast<double>(rng() >> 11) * 0x1.0p-53 >= pattern.fraction;
      }
      train[static_cast<size_t>(y) * nx + x] = fitted;
    }
  }
  return train;
}

bool DmfMapFitOptions::Check(std::string* error) const {
  if (!point.Check(error)) return false;
  if (cluster && !clustering.Check(error)) return false;
  if (num_threads < 1 || num_threads > kMaxThreads) {
    *error = "num_threads = " + std::to_string(num_threads) + " must be in 1.." + std::to_string(kMaxThreads);
    return false;
  }
  return true;
}

void PoolSplitHalfSigmas(int width, int height, int num_threads, std::vector<DmfPointFit>* fits, int min_samples,
                         int max_radius) {
  ParallelFor(height, num_threads, [&](int y) {
    for (int x = 0; x < width; ++x) {
      DmfPointFit& f = (*fits)[y * width + x];
      if (!f.HasNdf()) continue;
      double sum_alpha = 0, sum_roughness = 0;
      int n = 0;
      for (int r = 0; r <= max_radius && n < min_samples; ++r) {
        // The ring of Chebyshev radius r around (x, y).
        for (int yy = y - r; yy <= y + r; ++yy) {
          if (yy < 0 || yy >= height) continue;
          const bool full_row = yy == y - r || yy == y + r;
          for (int xx = x - r; xx <= x + r; xx += full_row || r == 0 ? 1 : 2 * r) {
            if (xx < 0 || xx >= width) continue;
            const DmfPointFit& g = (*fits)[yy * width + xx];
            if (!g.split_fitted) continue;
            sum_alpha += g.split_alpha_difference * g.split_alpha_difference;
            sum_roughness += g.split_roughness_difference * g.split_roughness_difference;
            ++n;
          }
        }
      }
      if (n == 0) continue;
      f.sigma_alpha = std::sqrt(sum_alpha / (4.0 * n));
      // Plus the model-form term: the roughness depends on the family assumed; half the GGX and
      // Beckmann fits' difference (both fit the same table).
      f.sigma_roughness = std::sqrt(sum_roughness / (4.0 * n) + Sqr(0.5 * (f.roughness.ggx_alpha - f.roughness.beckmann_alpha)));
    }
  });
}

std::vector<uint8_t> SplitTrainingHalf(const std::vector<uint8_t>& train, int nx, int half) {
  std::vector<uint8_t> out(train.size(), 0);
  int rank = 0;
  for (size_t q = 0; q < train.size(); ++q) {
    if (nx > 0 && q % nx == 0) rank = 0;
    if (!train[q]) continue;
    out[q] = (rank++ % 2) == half;
  }
  return out;
}

Image DmfMaps::ToImage(const EquivalentRoughnessOptions& roughness_options) const {
  Image image(width, height, {"top_face_weight", "smith_alpha", "k_s", "rho_d", "log_rms_residual", "status", "measured_ndf_fraction",
                              "transmittance", "equivalent_roughness", "ndf_family", "rough_face",
                              "sigma_top_face_weight", "sigma_equivalent_roughness"});
  for (int p = 0; p < width * height; ++p) {
    const DmfPointFit& f = fits[p];
    const int x = p % width, y = p / width;
    image.at(x, y, 0) = static_cast<float>(f.alpha);
    image.at(x, y, 1) = static_cast<float>(f.smith_alpha);
    image.at(x, y, 2) = static_cast<float>(f.k_s);
    image.at(x, y, 3) = static_cast<float>(f.rho_d);
    image.at(x, y, 4) = static_cast<float>(f.log_rms_residual);
    image.at(x, y, 5) = static_cast<float>(static_cast<int>(f.status));
    image.at(x, y, 6) = static_cast<float>(f.measured_ndf_fraction);
    image.at(x, y, 7) = static_cast<float>(f.transmittance);
    image.at(x, y, 8) = static_cast<float>(f.roughness.roughness);
    image.at(x, y, 9) = static_cast<float>(static_cast<int>(f.roughness.family));
    image.at(x, y, 10) = static_cast<float>(static_cast<int>(RoughFaceOf(f.alpha, roughness_options)));
    image.at(x, y, 11) = static_cast<float>(f.sigma_alpha);
    image.at(x, y, 12) = static_cast<float>(f.sigma_roughness);
  }
  return image;
}

namespace {

// Eq. 20 for the NDF: D_i = sum_j w_ij D_j over point p's neighbouring representatives with a
// fitted NDF and k_s > 0, normalised by the weights used; ln of it (floored at 1e-6) into
// *log_ndf. Returns the weight sum (0: no usable neighbour, *log_ndf untouched).
// `linear_ndf`: DmfMaps::representative_ndf, or empty (each D_j exponentiated here).
double InterpolateLogNdf(const std::vector<DmfPointFit>& fits, const DmfClustering& c,
                         const std::vector<double>& linear_ndf, int p, int num_cells, std::vector<double>* log_ndf) {
  std::vector<double> d(num_cells, 0.0);
  double weight_sum = 0;
  for (int k = 0; k < c.num_neighbors; ++k) {
    const int j = c.neighbors[static_cast<size_t>(p) * c.num_neighbors + k];
    const double w = c.weights[static_cast<size_t>(p) * c.num_neighbors + k];
    if (j < 0 || w <= 0) continue;
    const DmfPointFit& rep = fits[c.representatives[j]];
    if (rep.log_ndf.empty() || !(rep.k_s > 0)) continue;
    if (linear_ndf.empty()) {
      for (int cell = 0; cell < num_cells; ++cell) d[cell] += w * std::exp(rep.log_ndf[cell]);
    } else {
      const double* linear = linear_ndf.data() + static_cast<size_t>(j) * num_cells;
      for (int cell = 0; cell < num_cells; ++cell) d[cell] += w * linear[cell];
    }
    weight_sum += w;
  }
  if (!(weight_sum > 0)) return 0;
  log_ndf->resize(num_cells);
  for (int cell = 0; cell < num_cells; ++cell) (*log_ndf)[cell] = std::log(std::max(d[cell] / weight_sum, 1e-6));
  return weight_sum;
}

}  // namespace

DmfPointFit DmfMaps::FitWithNdf(int p) const {
  DmfPointFit f = fits[p];
  if (f.log_ndf.empty() && f.ndf_interpolated) {
    InterpolateLogNdf(fits, clustering, representative_ndf, p, ndf_resolution * ndf_resolution, &f.log_ndf);
  }
  return f;
}

void DmfMaps::CacheRepresentativeNdfs(int num_threads) {
  const int num_cells = ndf_resolution * ndf_resolution;
  const int nr = static_cast<int>(clustering.representatives.size());
  representative_ndf.assign(static_cast<size_t>(nr) * num_cells, 0.0);
  ParallelFor(nr, num_threads, [&](int j) {
    const DmfPointFit& rep = fits[clustering.representatives[j]];
    if (rep.log_ndf.empty() || !(rep.k_s > 0)) return;  // Not an Eq. 20 term (InterpolateLogNdf).
    double* linear = representative_ndf.data() + static_cast<size_t>(j) * num_cells;
    for (int cell = 0; cell < num_cells; ++cell) linear[cell] = std::exp(rep.log_ndf[cell]);
  });
}

Status FitDualMicrofacetMaps(const DmfSliceSet& slices, const DmfMapFitOptions& options, DmfMaps* maps) {
  std::string error;
  if (!options.Check(&error)) return Status::Error("dmf fit options: " + error);
  THINSLAB_RETURN_IF_ERROR(slices.Check());
  const auto start = std::chrono::steady_clock::now();
  const DmfNdfGrid grid(options.point.ndf_resolution);
  const int np = slices.num_points();
  // Streamed (issue #29): every stage below visits the points band by band (ForEachPointBand);
  // the shapes go to a spill file of their own, and interpolated NDFs are not kept.
  const bool streamed = slices.spill != nullptr;
  // Under mpirun every process runs this function on the same slices; the per-point loops are
  // shared out (DistributedFor) and every process ends with the same maps. The clustering runs
  // whole on each (it is deterministic, and its inputs are the same).
  ProcessGroup& group = ProcessGroup::World();
  maps->width = slices.width;
  maps->height = slices.height;
  maps->ndf_resolution = grid.n();
  maps->eta = options.point.eta;
  maps->fits.assign(np, DmfPointFit());
  maps->num_fitted = 0;
  maps->clustering = DmfClustering();
  maps->representative_ndf.clear();

  // Diffuse separation (Eq. 14) and the slice shapes the clustering compares.
  auto t = std::chrono::steady_clock::now();
  std::vector<double> rho_d(np, 0);
  std::vector<uint8_t> fit_me(np, 0);
  Eigen::MatrixXf shapes;  // In memory only: every point's shape.
  // Shapes on one grid of u = i_xy + o_xy for every point (fit/dmf_slice_shape.h), as fine as
  // the dot grid, spanning what the sample's central point sees.
  SliceShapeGrid shape_grid;
  if (options.cluster) {
    const int centre = (slices.height / 2) * slices.width + slices.width / 2;
    THINSLAB_RETURN_IF_ERROR(LoadPoint(slices, centre));
    shape_grid = MakeSliceShapeGrid(slices.Slice(centre), std::max(slices.dots_nx, slices.dots_ny));
    if (!streamed) shapes.setZero(np, shape_grid.num_nodes());
  }
  // Streamed: the shapes go to a file of their own (point-major), read back for the PCA
  // subsample and the projection without computing any slice again.
  std::unique_ptr<SpillFile> shape_file;
  const int nodes = options.cluster ? shape_grid.num_nodes() : 0;
  if (options.cluster && streamed) {
    THINSLAB_RETURN_IF_ERROR(
        SpillFile::Create(slices.spill->dir(), static_cast<size_t>(np) * nodes, "slice shape spill", &shape_file));
  }
  std::vector<float> band_shapes;  // Streamed: a band's shapes, row-major.
  // Point p's shape (in memory: a row of `shapes`; streamed: of the band starting at `first`).
  auto shape_of = [&](int first, int p) -> float* {
    return shape_file ? band_shapes.data() + static_cast<size_t>(p - first) * nodes : nullptr;
  };
  ProgressTracker separation_progress(options.progress, "fit dmf: diffuse separation (Dai Eq. 14)", np);
  THINSLAB_RETURN_IF_ERROR(ForEachPointBand(slices, [&](int first, int count) {
    if (shape_file) band_shapes.assign(static_cast<size_t>(count) * nodes, 0.0f);
    auto separate = [&](int p) {
      maps->fits[p].status = static_cast<DmfStatus>(slices.point_status[p]);
      if (slices.point_status[p] != static_cast<uint8_t>(DmfStatus::kOk)) return;
      const DmfSlice slice = slices.Slice(p);
      rho_d[p] = slice.rho_d;
      maps->fits[p].rho_d = slice.rho_d;
      const DmfStatus precheck = PrecheckSlice(slice, options.point);
      if (precheck != DmfStatus::kOk) {
        maps->fits[p].status = precheck;
        return;
      }
      fit_me[p] = 1;
      if (options.cluster) {
        Eigen::VectorXf shape(nodes);
        AlignedSliceShape(slice, shape_grid, shape.data());
        if (shape_file) {
          std::copy(shape.data(), shape.data() + nodes, shape_of(first, p));
        } else {
          shapes.row(p) = shape.transpose();
        }
      }
    };
    DistributedLoop loop;
    SetReportedCompute(
        group, options.num_threads, &separation_progress, first, [&](int k) { separate(first + k); }, &loop);
    loop.pack = [&](int k, ByteWriter* out) {
      const int p = first + k;
      out->Put(maps->fits[p].status);
      out->Put(rho_d[p]);
      out->Put(fit_me[p]);
      if (!options.cluster || !fit_me[p]) return;
      std::vector<float> shape(nodes);
      if (shape_file) {
        std::copy(shape_of(first, p), shape_of(first, p) + nodes, shape.begin());
      } else {
        for (int n = 0; n < nodes; ++n) shape[n] = shapes(p, n);
      }
      out->PutVector(shape);
    };
    loop.unpack = [&](int k, ByteReader* in) {
      const int p = first + k;
      if (!in->Get(&maps->fits[p].status) || !in->Get(&rho_d[p]) || !in->Get(&fit_me[p])) return false;
      maps->fits[p].rho_d = rho_d[p];
      if (!options.cluster || !fit_me[p]) return true;
      std::vector<float> shape;
      if (!in->GetVector(&shape) || static_cast<int>(shape.size()) != nodes) return false;
      if (shape_file) {
        std::copy(shape.begin(), shape.end(), shape_of(first, p));
      } else {
        for (int n = 0; n < nodes; ++n) shapes(p, n) = shape[n];
      }
      return true;
    };
    THINSLAB_RETURN_IF_ERROR(
        DistributedFor(group, count, PointChunk(group, count), "fit dmf: diffuse separation (Eq. 14)", loop));
    if (shape_file) {
      return shape_file->Write(static_cast<size_t>(first) * nodes, band_shapes.size(), band_shapes.data());
    }
    return Status::Ok();
  }));
  std::vector<float>().swap(band_shapes);
  maps->timings.diffuse_s = Seconds(t);

  // Which points are fitted directly.
  std::vector<int> direct;
  t = std::chrono::steady_clock::now();
  if (options.cluster) {
    DmfClusteringOptions clustering = options.clustering;
    clustering.num_threads = options.num_threads;
    DmfShapeClusterer clusterer(fit_me, clustering);
    ProgressTracker clustering_progress(options.progress, "fit dmf: clustering (PCA, k-means, Dai Eq. 20)",
                                        clusterer.num_steps());
    clustering_progress.Report(0);
    const std::vector<int>& sample = clusterer.pca_sample();
    Eigen::MatrixXf sample_shapes(sample.size(), nodes);
    // Every point's shape projected onto the principal components: a stage of its own (reading
    // the shapes back from the shape file takes seconds at the paper's size).
    ProgressTracker projection_progress(options.progress, "fit dmf: clustering, projections", np);
    if (!streamed) {
      for (size_t s = 0; s < sample.size(); ++s) sample_shapes.row(s) = shapes.row(sample[s]);
      clusterer.FitProjection(sample_shapes);
      clustering_progress.Report(1);
      constexpr int kProjectionChunk = 65536;
      for (int first = 0; first < np; first += kProjectionChunk) {
        const int count = std::min(kProjectionChunk, np - first);
        ParallelFor(count, options.num_threads, [&](int k) {
          if (fit_me[first + k]) clusterer.Project(first + k, shapes, first + k);
        });
        if (!projection_progress.Report(first + count)) return Status::Error("FitDualMicrofacetMaps: cancelled");
      }
      shapes = Eigen::MatrixXf();
    } else {
      // The subsample's shapes, then every point's projection, one band at a time, from the
      // shape file.
      Eigen::VectorXf shape(nodes);
      for (size_t s = 0; s < sample.size(); ++s) {
        THINSLAB_RETURN_IF_ERROR(shape_file->Read(static_cast<size_t>(sample[s]) * nodes, nodes, shape.data()));
        sample_shapes.row(s) = shape.transpose();
      }
      clusterer.FitProjection(sample_shapes);
      clustering_progress.Report(1);  // The principal components; their projections next.
      sample_shapes = Eigen::MatrixXf();
      // Half a band at a time: the rows as read and as a matrix take a band's shapes' memory.
      const int band = std::max(1, slices.spill->band_points() / 2);
      std::vector<float> rows;
      Eigen::MatrixXf band_matrix;  // The same type as the in-memory `shapes` (Project's arithmetic).
      for (int first = 0; first < np; first += band) {
        const int count = std::min(band, np - first);
        rows.resize(static_cast<size_t>(count) * nodes);
        THINSLAB_RETURN_IF_ERROR(shape_file->Read(static_cast<size_t>(first) * nodes, rows.size(), rows.data()));
        band_matrix = Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
            rows.data(), count, nodes);
        ParallelFor(count, options.num_threads, [&](int k) {
          if (fit_me[first + k]) clusterer.Project(first + k, band_matrix, k);
        });
        if (!projection_progress.Report(first + count)) return Status::Error("FitDualMicrofacetMaps: cancelled");
      }
    }
    if (!clustering_progress.Report(DmfShapeClusterer::kProjectionSteps)) {
      return Status::Error("FitDualMicrofacetMaps: cancelled");
    }
    maps->clustering = clusterer.Cluster(&clustering_progress);
    if (clustering_progress.cancelled()) return Status::Error("FitDualMicrofacetMaps: cancelled");
    direct = maps->clustering.representatives;
  } else {
    for (int p = 0; p < np; ++p) {
      if (fit_me[p]) direct.push_back(p);
    }
  }
  maps->timings.clustering_s = Seconds(t);

  t = std::chrono::steady_clock::now();
  ProgressTracker progress(options.progress, "fit dmf: point fits (Dai Eqs. 14-19)",
                           static_cast<int64_t>(direct.size()));
  // The split halves give the sigmas of alpha and the roughness only, which the NDF's tail does
  // not change (both are judged before it): no tail there (a tenth of the point fits' time).
  DmfPointFitOptions half_options = options.point;
  half_options.ndf_tail = "smooth";
  auto fit_direct = [&](int p) {
    const DmfSlice slice = slices.Slice(p);
    DmfPointFit& fit = maps->fits[p];
    fit = FitDualMicrofacetPoint(slice, grid, options.point);
    if (!options.split_half || fit.log_ndf.empty()) return;
    DmfPointFit halves[2];
    for (int h = 0; h < 2; ++h) {
      DmfSlice half = slice;
      half.train = SplitTrainingHalf(slice.train, slices.dots_nx, h);
      halves[h] = FitDualMicrofacetPoint(half, grid, half_options);
      if (halves[h].log_ndf.empty()) return;
    }
    fit.split_fitted = true;
    fit.split_alpha_difference = halves[0].alpha - halves[1].alpha;
    fit.split_roughness_difference = halves[0].roughness.roughness - halves[1].roughness.roughness;
  };
  int64_t fitted = 0;
  THINSLAB_RETURN_IF_ERROR(ForEachPointBand(slices, [&](int first, int count) {
    std::vector<int> in_band;
    for (int p : direct) {
      if (p >= first && p < first + count) in_band.push_back(p);
    }
    const int n = static_cast<int>(in_band.size());
    DistributedLoop loop;
    SetReportedCompute(
        group, options.num_threads, &progress, fitted, [&](int k) { fit_direct(in_band[k]); }, &loop);
    loop.pack = [&](int k, ByteWriter* out) { PackDmfPointFit(maps->fits[in_band[k]], out); };
    loop.unpack = [&](int k, ByteReader* in) { return UnpackDmfPointFit(in, &maps->fits[in_band[k]]); };
    THINSLAB_RETURN_IF_ERROR(DistributedFor(group, n, PointChunk(group, n), "fit dmf: point fits (Eqs. 14-19)", loop));
    fitted += n;
    return Status::Ok();
  }));
  maps->num_fitted = static_cast<int>(direct.size());
  maps->timings.representative_fit_s = Seconds(t);

  // Eq. 20: <alpha, D>_i = sum_j w_ij <alpha, D>_j (D linear, normalised), then k_s per point.
  t = std::chrono::steady_clock::now();
  if (options.cluster) {
    const DmfClustering& c = maps->clustering;
    std::vector<uint8_t> is_rep(np, 0);
    for (int p : c.representatives) is_rep[p] = 1;
    maps->CacheRepresentativeNdfs(options.num_threads);
    ProgressTracker interpolation_progress(options.progress, "fit dmf: interpolation (Dai Eqs. 20-22)", np);
    THINSLAB_RETURN_IF_ERROR(ForEachPointBand(slices, [&](int first, int count) {
      auto interpolate = [&](int p) {
        if (!fit_me[p] || is_rep[p]) return;
        DmfPointFit f;
        f.rho_d = rho_d[p];
        f.alpha = 0;
        f.smith_alpha = 0;
        double weight_sum = 0, transmittance_per_k_s = 0;
        for (int k = 0; k < c.num_neighbors; ++k) {
          const int j = c.neighbors[static_cast<size_t>(p) * c.num_neighbors + k];
          const double w = c.weights[static_cast<size_t>(p) * c.num_neighbors + k];
          if (j < 0 || w <= 0) continue;
          const DmfPointFit& rep = maps->fits[c.representatives[j]];
          if (rep.log_ndf.empty() || !(rep.k_s > 0)) continue;
          f.alpha += w * rep.alpha;
          f.smith_alpha += w * rep.smith_alpha;
          f.measured_ndf_fraction += w * rep.measured_ndf_fraction;
          f.roughness.ggx_alpha += w * rep.roughness.ggx_alpha;
          f.roughness.beckmann_alpha += w * rep.roughness.beckmann_alpha;
          f.roughness.ggx_misfit += w * rep.roughness.ggx_misfit;
          f.roughness.beckmann_misfit += w * rep.roughness.beckmann_misfit;
          // The refracted part of the transmittance is linear in k_s for a fixed normalised NDF:
          // each representative's, rescaled to this point's k_s and rho_d below (the integral is
          // not evaluated per interpolated point: it would cost about as much as the
          // interpolation). pi rho_d is the diffuse term's share.
          transmittance_per_k_s += w * (rep.transmittance - kPi * rep.rho_d) / rep.k_s;
          weight_sum += w;
        }
        if (!(weight_sum > 0)) {
          f.status = DmfStatus::kNoLobe;
          f.alpha = 0.5;
          f.smith_alpha = options.point.initial_smith_alpha;
          maps->fits[p] = f;
          return;
        }
        f.alpha /= weight_sum;
        f.smith_alpha /= weight_sum;
        f.measured_ndf_fraction /= weight_sum;
        f.roughness.ggx_alpha /= weight_sum;
        f.roughness.beckmann_alpha /= weight_sum;
        f.roughness.ggx_misfit /= weight_sum;
        f.roughness.beckmann_misfit /= weight_sum;
        DecideFamily(options.point.roughness, &f.roughness);
        InterpolateLogNdf(maps->fits, c, maps->representative_ndf, p, grid.num_cells(), &f.log_ndf);
        f.ndf_interpolated = true;
        const DmfSlice slice = slices.Slice(p);
        const int used = ScaleShapeToSlice(slice, grid, options.point, &f);
        f.num_used = used;
        f.transmittance = kPi * f.rho_d + f.k_s * transmittance_per_k_s / weight_sum;
        // An interpolated NDF is as measured as its representatives' (weighted).
        if (used == 0) {
          f.status = DmfStatus::kNoLobe;
        } else if (options.point.Undersampled(f.measured_ndf_fraction, slice)) {
          f.status = DmfStatus::kUndersampled;
        } else if (options.point.Unphysical(f.transmittance, f.k_s)) {
          f.status = DmfStatus::kUnphysical;
        } else {
          f.status = DmfStatus::kInterpolated;
        }
        if (streamed) std::vector<double>().swap(f.log_ndf);  // FitWithNdf rebuilds it.
        maps->fits[p] = f;
      };
      DistributedLoop loop;
      SetReportedCompute(
          group, options.num_threads, &interpolation_progress, first, [&](int k) { interpolate(first + k); }, &loop);
      // Only the interpolated points: every process already has the others' fits.
      loop.pack = [&](int k, ByteWriter* out) {
        const int p = first + k;
        const uint8_t interpolated = fit_me[p] && !is_rep[p];
        out->Put(interpolated);
        if (interpolated) PackDmfPointFit(maps->fits[p], out);
      };
      loop.unpack = [&](int k, ByteReader* in) {
        uint8_t interpolated = 0;
        if (!in->Get(&interpolated)) return false;
        return !interpolated || UnpackDmfPointFit(in, &maps->fits[first + k]);
      };
      return DistributedFor(group, count, PointChunk(group, count), "fit dmf: interpolation (Eqs. 20-22)", loop);
    }));
  }
  maps->timings.interpolation_s = Seconds(t);
  if (options.split_half) PoolSplitHalfSigmas(maps->width, maps->height, options.num_threads, &maps->fits);
  if (options.trace.enabled()) {
    // The traced point fitted once more, alone, with its trace (the same fit as in the maps
    // when it was fitted directly; the maps' values are printed after).
    THINSLAB_RETURN_IF_ERROR(CheckPixelTraceInside(options.trace, slices.width, slices.height, "--pixel"));
    const int p = options.trace.y * slices.width + options.trace.x;
    std::ostream& out = *options.trace.out;
    const bool direct_fit = std::find(direct.begin(), direct.end(), p) != direct.end();
    out << "point (" << options.trace.x << ", " << options.trace.y << ")"
        << (direct_fit ? ": fitted directly (Dai Eqs. 14-19)\n"
                       : ": not fitted directly in the maps (clustered run: interpolated, Eqs. 20-22; or no lobe); its own fit:\n");
    DmfPointFitOptions traced = options.point;
    traced.trace = &out;
    THINSLAB_RETURN_IF_ERROR(LoadPoint(slices, p));
    const DmfPointFit alone = FitDualMicrofacetPoint(slices.Slice(p), grid, traced);
    const DmfPointFit& in_maps = maps->fits[p];
    out << "  alone: status " << DmfStatusName(alone.status) << "; in the maps: status " << DmfStatusName(in_maps.status)
        << ", top_face_weight " << in_maps.alpha << ", smith_alpha " << in_maps.smith_alpha << ", k_s " << in_maps.k_s
        << "\n";
  }
  maps->timings.total_s = Seconds(start);
  return Status::Ok();
}

double DmfHeldOutError(const DmfSliceSet& slices, const DmfMaps& maps, int p, double lobe_fraction) {
  if (!maps.fits[p].HasNdf()) return -1;
  const DmfPointFit fit = maps.FitWithNdf(p);
  const DmfNdfGrid grid(maps.ndf_resolution);
  const DmfSlice slice = slices.Slice(p);
  return HeldOutRelativeRms(slice, lobe_fraction, [&](const Eigen::Vector3d& i, const Eigen::Vector3d& o) {
    return PredictDualMicrofacet(fit, grid, maps.eta, i, o);
  });
}

}  // namespace thinslab
