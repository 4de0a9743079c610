// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/slab_sample.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <sstream>

#include "thinslab/core/parallel.h"
#include "thinslab/optics/fresnel.h"
#include "thinslab/optics/microfacet.h"

namespace thinslab {
namespace {

std::string RegionLabel(size_t idx, const SlabRegion& r) {
  return "SlabSampleOptions::regions[" + std::to_string(idx) + "] ('" + r.name + "')";
}

Status CheckFace(const std::string& where, const SlabFace& f) {
  for (double a : {f.alpha_x, f.alpha_y}) {
    if (!(a >= kMinMicrofacetAlpha && a <= kMaxMicrofacetAlpha)) {
      std::ostringstream msg;
      msg << where << ": alpha_x, alpha_y = " << f.alpha_x << ", " << f.alpha_y << ". Violated constraint: in ["
          << kMinMicrofacetAlpha << ", " << kMaxMicrofacetAlpha << "]";
      return Status::Error(msg.str());
    }
  }
  return Status::Ok();
}

SlabRegion MakeRegion(const std::string& name, SlabFace top, SlabFace bottom, double rho_d = 0, double k_s = 1) {
  SlabRegion r;
  r.name = name;
  r.material.top = top;
  r.material.bottom = bottom;
  r.material.rho_d = rho_d;
  r.material.k_s = k_s;
  return r;
}

}  // namespace

Status SlabSampleOptions::Check() const {
  auto err = [](const std::string& field, const std::string& what) {
    return Status::Error("SlabSampleOptions::" + field + ": " + what);
  };
  if (!(max_m.x() > min_m.x() && max_m.y() > min_m.y())) return err("min_m/max_m", "need max_m > min_m in x and y");
  if (photons_per_region < 1000) return err("photons_per_region", "must be >= 1000");
  if (table_bins < 4 || table_bins > 1024) return err("table_bins", "must be in [4, 1024]");
  if (max_interactions < 2) return err("max_interactions", "must be >= 2");
  if (!(thickness_m >= 0 && thickness_m <= 0.05)) return err("thickness_m", "must be in [0, 0.05] m");
  if (num_threads < 1 || num_threads > kMaxThreads) {
    return err("num_threads", "must be in 1.." + std::to_string(kMaxThreads) + ", got " + std::to_string(num_threads));
  }
  if (regions.empty()) return err("regions", "must not be empty (DefaultSlabRegions gives the preset)");
  const double eps = 1e-9;
  double area = 0;
  for (size_t k = 0; k < regions.size(); ++k) {
    const SlabRegion& r = regions[k];
    const std::string where = RegionLabel(k, r);
    if (!(r.max_m.x() > r.min_m.x() && r.max_m.y() > r.min_m.y())) {
      return Status::Error(where + ": need max_m > min_m in x and y");
    }
    if (r.min_m.x() < min_m.x() - eps || r.min_m.y() < min_m.y() - eps || r.max_m.x() > max_m.x() + eps ||
        r.max_m.y() > max_m.y() + eps) {
      return Status::Error(where + ": rectangle leaves the sample rectangle");
    }
    THINSLAB_RETURN_IF_ERROR(CheckFace(where + ".material.top", r.material.top));
    THINSLAB_RETURN_IF_ERROR(CheckFace(where + ".material.bottom", r.material.bottom));
    if (!(r.material.eta > 1 && r.material.eta < 4)) return Status::Error(where + ".material.eta: must be in (1, 4)");
    if (!(r.material.rho_d >= 0 && std::isfinite(r.material.rho_d))) {
      return Status::Error(where + ".material.rho_d: must be >= 0 [1/sr]");
    }
    if (!(r.material.k_s >= 0 && std::isfinite(r.material.k_s))) {
      return Status::Error(where + ".material.k_s: must be >= 0");
    }
    area += (r.max_m - r.min_m).prod();
    for (size_t j = 0; j < k; ++j) {
      const SlabRegion& q = regions[j];
      const double ox = std::min(r.max_m.x(), q.max_m.x()) - std::max(r.min_m.x(), q.min_m.x());
      const double oy = std::min(r.max_m.y(), q.max_m.y()) - std::max(r.min_m.y(), q.min_m.y());
      if (ox > eps && oy > eps) return Status::Error(where + ": overlaps " + RegionLabel(j, q));
    }
  }
  const double total = (max_m - min_m).prod();
  if (std::abs(area - total) > 1e-6 * total) {
    return err("regions", "do not tile the sample rectangle (region areas sum to " + std::to_string(area) +
                              " m^2, the sample is " + std::to_string(total) + " m^2)");
  }
  return Status::Ok();
}

std::vector<SlabRegion> DefaultSlabRegions(const Eigen::Vector2d& min_m, const Eigen::Vector2d& max_m) {
  const SlabFace flat;
  auto ggx = [](double ax, double ay) { return SlabFace{RoughSlabNdf::kGgx, ax, ay}; };
  auto beckmann = [](double a) { return SlabFace{RoughSlabNdf::kBeckmann, a, a}; };
  std::vector<SlabRegion> regions = {
      MakeRegion("ggx_top", ggx(0.3, 0.3), flat),
      MakeRegion("ggx_bottom", flat, ggx(0.3, 0.3)),
      MakeRegion("ggx_both", ggx(0.2, 0.2), ggx(0.2, 0.2)),
      MakeRegion("beckmann_top", beckmann(0.3), flat),
      MakeRegion("beckmann_both", beckmann(0.2), beckmann(0.2)),
      MakeRegion("ggx_aniso_top", ggx(0.15, 0.4), flat),
      MakeRegion("smooth", flat, flat),
      MakeRegion("diffuse", ggx(0.25, 0.25), flat, 0.05, 0.8),
      MakeRegion("ggx_mixed", ggx(0.1, 0.1), ggx(0.3, 0.3)),
  };
  const Eigen::Vector2d step = (max_m - min_m) / 3.0;
  for (int k = 0; k < 9; ++k) {
    const int i = k % 3, j = k / 3;
    regions[k].min_m = min_m + Eigen::Vector2d(i * step.x(), j * step.y());
    // The last row/column ends exactly at max_m (no round-off gap).
    regions[k].max_m = Eigen::Vector2d(i == 2 ? max_m.x() : min_m.x() + (i + 1) * step.x(),
                                       j == 2 ? max_m.y() : min_m.y() + (j + 1) * step.y());
  }
  return regions;
}

double SlabBtdfTable::Eval(const Eigen::Vector3d& i) const {
  if (!(i.z() < 0) || bins == 0) return 0;
  const double inv_h = bins / 2.0;
  const double u = (i.x() + 1) * inv_h - 0.5, v = (i.y() + 1) * inv_h - 0.5;
  const double fu = std::floor(u), fv = std::floor(v);
  const double tu = u - fu, tv = v - fv;
  const int c0 = std::clamp(static_cast<int>(fu), 0, bins - 1), c1 = std::clamp(static_cast<int>(fu) + 1, 0, bins - 1);
  const int r0 = std::clamp(static_cast<int>(fv), 0, bins - 1), r1 = std::clamp(static_cast<int>(fv) + 1, 0, bins - 1);
  const float* t = rho.data();
  return (1 - tv) * ((1 - tu) * t[r0 * bins + c0] + tu * t[r0 * bins + c1]) +
         tv * ((1 - tu) * t[r1 * bins + c0] + tu * t[r1 * bins + c1]);
}

Status SlabSample::Create(const SlabSampleOptions& options_in, const Eigen::Vector3d& camera_centre_in_sample,
                          std::unique_ptr<SlabSample>* out) {
  SlabSampleOptions options = options_in;
  if (options.regions.empty()) options.regions = DefaultSlabRegions(options.min_m, options.max_m);
  THINSLAB_RETURN_IF_ERROR(options.Check());
  if (!(camera_centre_in_sample.z() > 0)) {
    return Status::Error("SlabSample: the camera must be on the +z side of the sample (camera centre z = " +
                         std::to_string(camera_centre_in_sample.z()) + " m)");
  }
  std::unique_ptr<SlabSample> sample(new SlabSample());
  sample->options_ = options;
  const int n = sample->num_regions();
  sample->tables_.resize(n);
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector2d c = options.regions[k].Centre();
    sample->view_directions_.push_back((camera_centre_in_sample - Eigen::Vector3d(c.x(), c.y(), 0)).normalized());
  }
  const auto start = std::chrono::steady_clock::now();
  // The adjoint trace (slab_sample.h): entry through the region's bottom (camera-side) face
  // from the view direction, in the sample frame; the tracer's top face is the region's bottom.
  auto trace = [&](int k) {
    const SlabMaterial& m = options.regions[k].material;
    if (m.IsSmooth()) return;
    RoughSlabPhotonTracerOptions t;
    t.eta = m.eta;
    t.ndf_top = m.bottom.ndf;
    t.alpha_top = m.bottom.alpha_x;
    t.alpha_top_y = m.bottom.alpha_y;
    t.ndf_bottom = m.top.ndf;
    t.alpha_bottom = m.top.alpha_x;
    t.alpha_bottom_y = m.top.alpha_y;
    t.wi = sample->view_directions_[k];
    t.num_photons = options.photons_per_region;
    t.max_interactions = options.max_interactions;
    t.num_bins = options.table_bins;
    t.seed = options.seed * 1000003ULL + static_cast<uint64_t>(k) * 7919ULL + 17;
    const RoughSlabPhotonTracerResult r = TraceRoughSlab(t);
    auto table = std::make_unique<SlabBtdfTable>();
    table->view_direction = t.wi;
    table->bins = r.num_bins;
    table->rho.resize(static_cast<size_t>(r.num_bins) * r.num_bins);
    table->std_error.resize(table->rho.size());
    for (int row = 0; row < r.num_bins; ++row) {
      for (int col = 0; col < r.num_bins; ++col) {
        table->rho[row * r.num_bins + col] = static_cast<float>(r.Btdf(row, col));
        table->std_error[row * r.num_bins + col] = static_cast<float>(r.BtdfStdError(row, col));
      }
    }
    // Offsets per unit thickness (slab_sample.h).
    const size_t cells = r.transmitted_counts.size();
    Eigen::Vector2d sum_once = Eigen::Vector2d::Zero();
    int64_t n_once = 0;
    for (size_t c = 0; c < cells; ++c) {
      sum_once += Eigen::Vector2d(r.once_offset_x[c], r.once_offset_y[c]);
      n_once += r.transmitted_once_counts[c];
    }
    const int64_t n_multiple = static_cast<int64_t>(r.multiple_offsets.size());
    const Eigen::Vector2f mean_once =
        n_once > 0 ? Eigen::Vector2f((sum_once / static_cast<double>(n_once)).cast<float>()) : Eigen::Vector2f::Zero();
    table->offset_once.assign(cells, mean_once);
    table->share_once.assign(cells, n_once + n_multiple > 0 ? static_cast<float>(n_once) / (n_once + n_multiple) : 1);
    for (size_t c = 0; c < cells; ++c) {
      const int64_t once = r.transmitted_once_counts[c], multiple = r.transmitted_counts[c] - once;
      if (once > 0) {
        table->offset_once[c] = Eigen::Vector2f(static_cast<float>(r.once_offset_x[c] / once),
                                                static_cast<float>(r.once_offset_y[c] / once));
      }
      if (once + multiple > 0) table->share_once[c] = static_cast<float>(once) / (once + multiple);
    }
    std::vector<Eigen::Vector2f> multiple = r.multiple_offsets;
    std::sort(multiple.begin(), multiple.end(),
              [](const Eigen::Vector2f& a, const Eigen::Vector2f& b) { return a.squaredNorm() < b.squaredNorm(); });
    for (int part = 0; part < SlabBtdfTable::kMultipleParts; ++part) {
      const size_t lo = multiple.size() * part / SlabBtdfTable::kMultipleParts;
      const size_t hi = multiple.size() * (part + 1) / SlabBtdfTable::kMultipleParts;
      Eigen::Vector2f sum = Eigen::Vector2f::Zero();
      for (size_t j = lo; j < hi; ++j) sum += multiple[j];
      table->offset_multiple[part] = hi > lo ? Eigen::Vector2f(sum / static_cast<float>(hi - lo)) : 3 * mean_once;
    }
    table->transmitted = r.transmitted;
    table->reflected = r.reflected;
    table->masked = r.masked;
    table->capped = r.capped;
    table->photons = r.num_photons;
    table->seed = t.seed;
    sample->tables_[k] = std::move(table);
  };
  ParallelFor(n, options.num_threads, trace);  // Each region has its own seed: deterministic.
  sample->tracing_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  *out = std::move(sample);
  return Status::Ok();
}

bool SlabSample::Contains(const Eigen::Vector2d& x) const {
  return x.x() >= options_.min_m.x() && x.x() < options_.max_m.x() && x.y() >= options_.min_m.y() &&
         x.y() < options_.max_m.y();
}

int SlabSample::RegionIndexAt(const Eigen::Vector2d& x) const {
  if (!Contains(x)) return -1;
  for (int k = 0; k < num_regions(); ++k) {
    const SlabRegion& r = options_.regions[k];
    if (x.x() >= r.min_m.x() && x.x() < r.max_m.x() && x.y() >= r.min_m.y() && x.y() < r.max_m.y()) return k;
  }
  // Round-off at a shared edge: the nearest region.
  int best = 0;
  double best_d = 1e30;
  for (int k = 0; k < num_regions(); ++k) {
    const SlabRegion& r = options_.regions[k];
    const double dx = std::max({r.min_m.x() - x.x(), 0.0, x.x() - r.max_m.x()});
    const double dy = std::max({r.min_m.y() - x.y(), 0.0, x.y() - r.max_m.y()});
    if (dx + dy < best_d) {
      best_d = dx + dy;
      best = k;
    }
  }
  return best;
}

const SlabMaterial* SlabSample::MaterialAt(const Eigen::Vector2d& x) const {
  const int k = RegionIndexAt(x);
  return k < 0 ? nullptr : &options_.regions[k].material;
}

double SlabSample::Btdf(int idx, const Eigen::Vector3d& i_sample) const {
  return Btdf(idx, i_sample, view_directions_[idx]);
}

double SlabSample::Transmission(int idx, const Eigen::Vector3d& i_sample) const {
  return Transmission(idx, i_sample, view_directions_[idx]);
}

double SlabSample::Btdf(int idx, const Eigen::Vector3d& i_sample, const Eigen::Vector3d& o_sample) const {
  const SlabBtdfTable* t = tables_[idx].get();
  if (!t) return 0.0;
  const Eigen::Vector3d& o_c = view_directions_[idx];
  return t->Eval(Eigen::Vector3d(i_sample.x() + o_sample.x() - o_c.x(), i_sample.y() + o_sample.y() - o_c.y(), i_sample.z()));
}

Eigen::Vector3d SlabSample::LightEntryPoint(int idx, const Eigen::Vector3d& x, const Eigen::Vector3d& i_sample,
                                            const Eigen::Vector3d& o_sample, int part, double* share) const {
  const double t = options_.thickness_m;
  const SlabBtdfTable* table = tables_[idx].get();
  if (!(t > 0) || !table) {
    *share = part == 0 ? 1 : 0;
    return x;
  }
  // The cell the BTDF lookup reads (the same view shift as Btdf), nearest, not interpolated: a
  // lobe's edge cells must not mix with the empty ones.
  const Eigen::Vector3d& o_c = view_directions_[idx];
  const double h = 2.0 / table->bins;
  const int col = std::clamp(static_cast<int>((i_sample.x() + o_sample.x() - o_c.x() + 1) / h), 0, table->bins - 1);
  const int row = std::clamp(static_cast<int>((i_sample.y() + o_sample.y() - o_c.y() + 1) / h), 0, table->bins - 1);
  const size_t cell = static_cast<size_t>(row) * table->bins + col;
  const double once = table->share_once[cell];
  *share = part == 0 ? once : (1 - once) / SlabBtdfTable::kMultipleParts;
  const Eigen::Vector2f offset = part == 0 ? table->offset_once[cell] : table->offset_multiple[part - 1];
  return Eigen::Vector3d(x.x() + t * offset.x(), x.y() + t * offset.y(), x.z() - t);
}

double SlabSample::Transmission(int idx, const Eigen::Vector3d& i_sample, const Eigen::Vector3d& o_sample) const {
  const SlabMaterial& m = options_.regions[idx].material;
  return m.rho_d + m.k_s * Btdf(idx, i_sample, o_sample);
}

double SlabSample::FlatSlabTransmittance(double cos_theta, double eta) {
  const double f = FresnelDielectric(std::abs(cos_theta), eta);
  return (1 - f) / (1 + f);
}

}  // namespace thinslab
