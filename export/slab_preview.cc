// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/slab_preview.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "thinslab/core/parallel.h"
#include "thinslab/fit/dmf_map_fit.h"
#include "thinslab/optics/fresnel.h"

namespace thinslab {

namespace {

Status Range(const std::string& field, const std::string& option, double value, double lo, double hi) {
  if (value >= lo && value <= hi) return Status::Ok();
  return Status::Error("SlabPreviewOptions::" + field + " (--" + option + "): must be in [" + std::to_string(lo) +
                       ", " + std::to_string(hi) + "], got " + std::to_string(value));
}

// One cell of the projected unit disk: the direction towards the light (i.z < 0) and the cell's
// area, which is |i_z| d omega.
struct DiskCell {
  Eigen::Vector3d i;
  double area;
};

std::vector<DiskCell> DiskCells(int n) {
  std::vector<DiskCell> cells;
  const double step = 2.0 / n;
  for (int row = 0; row < n; ++row) {
    for (int col = 0; col < n; ++col) {
      const double u = -1 + (col + 0.5) * step, v = -1 + (row + 0.5) * step, r2 = u * u + v * v;
      if (r2 >= 1) continue;
      cells.push_back({Eigen::Vector3d(u, v, -std::sqrt(1 - r2)), step * step});
    }
  }
  return cells;
}

}  // namespace

Status SlabPreviewOptions::Check() const {
  THINSLAB_RETURN_IF_ERROR(Range("checker_m", "checker-mm", checker_m * 1e3, 0.01, 1000));
  THINSLAB_RETURN_IF_ERROR(
      Range("backlight_distance_m", "backlight-distance-mm", backlight_distance_m * 1e3, 0.01, 10000));
  THINSLAB_RETURN_IF_ERROR(Range("dark_square", "dark-square", dark_square, 0, 1));
  THINSLAB_RETURN_IF_ERROR(Range("max_size_px", "max-size-px", max_size_px, 8, 4096));
  THINSLAB_RETURN_IF_ERROR(Range("directions", "directions", directions, 8, 512));
  return Range("threads", "threads", threads, 0, kMaxThreads);
}

Status RenderSlabPreview(const DmfFitOnDisk& fit, const SlabPreviewOptions& options, Image* view) {
  THINSLAB_RETURN_IF_ERROR(options.Check());
  const DmfMaps& maps = fit.maps;
  if (maps.width <= 0 || maps.height <= 0 || maps.fits.size() != static_cast<size_t>(maps.width) * maps.height) {
    return Status::Error("slab preview: the fit has no map points");
  }
  const int stride = std::max(1, (std::max(maps.width, maps.height) + options.max_size_px - 1) / options.max_size_px);
  const int w = (maps.width + stride - 1) / stride, h = (maps.height + stride - 1) / stride;
  *view = Image(w, h, {"fitted", "clean", "has_model"});
  const DmfNdfGrid grid(maps.ndf_resolution);
  const std::vector<DiskCell> cells = DiskCells(options.directions);
  const auto checker = [&](const Eigen::Vector3d& x, const Eigen::Vector3d& i) {
    const Eigen::Vector3d p = x + i * (options.backlight_distance_m / std::abs(i.z()));
    const long cx = static_cast<long>(std::floor(p.x() / options.checker_m));
    const long cy = static_cast<long>(std::floor(p.y() / options.checker_m));
    return ((cx + cy) & 1) ? 1.0 : options.dark_square;
  };
  // Clean glass at normal incidence: two faces, each transmitting 1 - F (the multiple reflections
  // inside add F^2 (1 - F)^2 / (1 - F^2), under 0.2 %: left out).
  const double face = 1 - FresnelDielectric(1.0, maps.eta);
  const Eigen::Vector3d o_optical = SampleToOptical(Eigen::Vector3d(0, 0, 1));
  const int threads = options.threads > 0 ? options.threads : DefaultThreadCount();
  ParallelFor(h, threads, [&](int py) {
    for (int px = 0; px < w; ++px) {
      const int col = std::min(maps.width - 1, px * stride + stride / 2);
      const int row = std::min(maps.height - 1, py * stride + stride / 2);
      const Eigen::Vector3d x(fit.grid_min_m.x() + (col + 0.5) * fit.pitch_m,
                              fit.grid_min_m.y() + (row + 0.5) * fit.pitch_m, 0);
      const double clean = face * face * checker(x, Eigen::Vector3d(0, 0, -1));
      const DmfPointFit& f = maps.fits[static_cast<size_t>(row) * maps.width + col];
      double radiance = clean;
      if (!f.log_ndf.empty()) {
        radiance = 0;
        for (const DiskCell& cell : cells) {
          radiance += PredictDualMicrofacet(f, grid, maps.eta, SampleToOptical(cell.i), o_optical) *
                      checker(x, cell.i) * cell.area;
        }
      }
      view->at(px, py, 0) = static_cast<float>(radiance);
      view->at(px, py, 1) = static_cast<float>(clean);
      view->at(px, py, 2) = f.log_ndf.empty() ? 0.0f : 1.0f;
    }
  });
  return Status::Ok();
}

}  // namespace thinslab
