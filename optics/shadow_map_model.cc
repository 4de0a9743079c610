// SPDX-License-Identifier: Apache-2.0
#include "thinslab/optics/shadow_map_model.h"

#include <glog/logging.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <utility>

#include "thinslab/core/math.h"

namespace thinslab {

int BoardKernelRadiusPx(const BoardGeometry& geometry) {
  CHECK_GT(geometry.distance_m, 0);
  CHECK_GT(geometry.pixel_pitch_m, 0);
  const double d_px = geometry.distance_m / geometry.pixel_pitch_m;
  // Capped before the conversion: a far board or a fine pitch (a memory estimate of an absurd
  // option, fit/tau_memory.h) must not overflow the int.
  double radius = std::ceil(d_px * std::tan(geometry.max_angle_deg * kPi / 180.0));
  if (geometry.max_radius_px > 0) radius = std::min(radius, static_cast<double>(geometry.max_radius_px));
  return static_cast<int>(std::clamp(radius, 1.0, static_cast<double>(std::numeric_limits<int>::max() / 4)));
}

Image BuildBoardKernel(const std::function<double(double mu)>& radiance, const BoardGeometry& geometry) {
  const double d_px = geometry.distance_m / geometry.pixel_pitch_m;
  const int radius = BoardKernelRadiusPx(geometry);
  const int size = 2 * radius + 1;
  Image kernel(size, size);
  const double mu_min = std::cos(geometry.max_angle_deg * kPi / 180.0);
  // Source and board pixels are both boxes: average over n x n sub-positions of each where the
  // lobe changes within a pixel (near the centre), a single sample further out.
  const double near_radius_px = std::max(6.0, 0.5 * d_px);
  auto lobe = [&](double dx_px, double dy_px) {
    const double r2 = Sqr(dx_px) + Sqr(dy_px);
    const double mu = d_px / std::sqrt(Sqr(d_px) + r2);
    if (mu < mu_min) return 0.0;
    // Irradiance per unit incident irradiance: A_px L mu^4 / D^2 with A_px / D^2 = 1 / d_px^2.
    return radiance(mu) * Sqr(Sqr(mu)) / Sqr(d_px);
  };
  // Box times box: the offset between two of the n uniform sub-positions of a source and a board
  // pixel is k / n with multiplicity n - |k|, k = -(n-1) .. n-1; weights of the n^2 pairs.
  constexpr int n = 4;
  std::array<double, 2 * n - 1> pair_weight{};
  for (int k = -(n - 1); k <= n - 1; ++k) pair_weight[k + n - 1] = static_cast<double>(n - std::abs(k)) / (n * n);
  // The lobe depends on the offset's length only, so the kernel has the square's eight
  // symmetries: each value is computed once, for 0 <= j <= i, and mirrored (exactly symmetric).
  for (int i = 0; i <= radius; ++i) {
    for (int j = 0; j <= i; ++j) {
      double value = 0;
      if (std::hypot(i, j) < near_radius_px) {
        for (int kx = -(n - 1); kx <= n - 1; ++kx) {
          for (int ky = -(n - 1); ky <= n - 1; ++ky) {
            value += pair_weight[kx + n - 1] * pair_weight[ky + n - 1] *
                     lobe(i + kx / static_cast<double>(n), j + ky / static_cast<double>(n));
          }
        }
      } else {
        value = lobe(i, j);
      }
      for (const auto& [x, y] : {std::pair{i, j}, std::pair{j, i}}) {
        for (const int sx : {-1, 1}) {
          for (const int sy : {-1, 1}) kernel.at(radius + sx * x, radius + sy * y) = static_cast<float>(value);
        }
      }
    }
  }
  return kernel;
}

Image ConvolveZeroPadded(const Image& source, const Image& kernel) {
  cv::Mat src(source.height(), source.width(), CV_32F, const_cast<float*>(source.data().data()));
  cv::Mat k(kernel.height(), kernel.width(), CV_32F, const_cast<float*>(kernel.data().data()));
  Image result(source.width(), source.height());
  // Written into the result's own buffer (filter2D keeps a destination of the right size and
  // type), so no second map-sized buffer is held.
  cv::Mat out(result.height(), result.width(), CV_32F, result.data().data());
  // The kernel is point-symmetric, so correlation (filter2D) equals convolution.
  cv::filter2D(src, out, CV_32F, k, cv::Point(-1, -1), 0, cv::BORDER_CONSTANT);
  CHECK_EQ(static_cast<const void*>(out.ptr<float>()), static_cast<const void*>(result.data().data()));
  return result;
}

ScatterKernelBank::ScatterKernelBank(const std::vector<double>& tau_nodes,
                                     const std::function<double(double tau, double mu)>& radiance_per_tau,
                                     const BoardGeometry& geometry)
    : nodes_(tau_nodes) {
  CHECK_GE(nodes_.size(), 2u);
  CHECK(std::is_sorted(nodes_.begin(), nodes_.end()));
  for (double t : nodes_) {
    kernels_.push_back(BuildBoardKernel([&](double mu) { return radiance_per_tau(t, mu); }, geometry));
  }
}

std::vector<double> ScatterKernelBank::DefaultNodes(double spacing_scale) {
  std::vector<double> nodes;
  const double fine = 0.1 * spacing_scale, coarse = 0.25 * spacing_scale;
  for (double t = 0; t < 1.5 - 1e-9; t += fine) nodes.push_back(t);
  for (double t = 1.5; t < 3.0 - 1e-9; t += coarse) nodes.push_back(t);
  nodes.push_back(3.0);
  nodes.push_back(4.0);
  nodes.push_back(6.0);
  return nodes;
}

Image ScatterKernelBank::Scattered(const Image& e0, const Image& tau) const {
  CHECK_EQ(e0.width(), tau.width());
  CHECK_EQ(e0.height(), tau.height());
  const int w = tau.width(), h = tau.height();
  Image total(w, h);
  const int n = static_cast<int>(nodes_.size());
  for (int j = 0; j < n; ++j) {
    // Source strength for node j: E0 tau w_j(tau), hat weights on the node grid; tau beyond
    // the last node uses the last kernel.
    Image source(w, h);
    bool any = false;
    for (size_t i = 0; i < source.num_pixels(); ++i) {
      const double t = std::max(0.0, static_cast<double>(tau.data()[i]));
      double weight = 0;
      if (j == n - 1 && t >= nodes_[j]) {
        weight = 1;
      } else if (j > 0 && t >= nodes_[j - 1] && t < nodes_[j]) {
        weight = (t - nodes_[j - 1]) / (nodes_[j] - nodes_[j - 1]);
      } else if (j < n - 1 && t >= nodes_[j] && t < nodes_[j + 1]) {
        weight = (nodes_[j + 1] - t) / (nodes_[j + 1] - nodes_[j]);
      }
      if (weight > 0) {
        source.data()[i] = static_cast<float>(e0.data()[i] * t * weight);
        any = true;
      }
    }
    if (!any) continue;
    const Image scattered = ConvolveZeroPadded(source, kernels_[j]);
    for (size_t i = 0; i < total.num_pixels(); ++i) total.data()[i] += scattered.data()[i];
  }
  return total;
}

}  // namespace thinslab
