// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/contamination_pattern.h"

#include <cmath>
#include <random>

#include "thinslab/core/math.h"

namespace thinslab {

Image GenerateContaminationPattern(const ContaminationPatternOptions& options) {
  const int w = options.width_px, h = options.height_px;
  Image tau(w, h, {"tau"});
  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const double s = std::min(w, h);

  // Fingerprint: elliptical whorl of sinusoidal ridges in the left half, smooth envelope.
  const double fx = 0.32 * w, fy = 0.45 * h, ax = 0.2 * s, ay = 0.28 * s;
  const double ridge_period_px = std::max(5.0, 0.045 * s);
  // Streak: a vertical water streak on the right, thickest at the top (dirt runs down).
  const double sx = 0.78 * w, streak_halfwidth_px = std::max(3.0, 0.03 * s);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double px = x + 0.5, py = y + 0.5;
      double t = 0;
      const double ex = (px - fx) / ax, ey = (py - fy) / ay;
      const double e2 = ex * ex + ey * ey;
      if (e2 < 1.0) {
        const double r = std::sqrt(Sqr(px - fx) + Sqr((py - fy) * ax / ay));
        const double ridge = 0.5 + 0.5 * std::cos(2 * kPi * r / ridge_period_px);
        const double envelope = Sqr(1.0 - e2);
        t += 0.6 * envelope * ridge;
      }
      const double wobble = 0.02 * s * std::sin(py / h * 2 * kPi * 1.5);
      const double dx = (px - sx - wobble) / streak_halfwidth_px;
      if (std::abs(dx) < 3 && py < 0.85 * h) {
        const double along = 1.0 - py / (0.85 * h);
        t += 0.35 * std::exp(-0.5 * dx * dx) * (0.3 + 0.7 * along);
      }
      tau.at(x, y) = static_cast<float>(t);
    }
  }
  // Dust specks: Gaussian blobs, sigma 1.2-3.5 px, peak tau up to max_tau, in the middle band.
  for (int i = 0; i < options.num_dust_specks; ++i) {
    const double cx = (0.45 + 0.25 * uni(rng)) * w, cy = (0.1 + 0.8 * uni(rng)) * h;
    const double sigma = 1.2 + 2.3 * uni(rng);
    const double peak = options.max_tau * (0.2 + 0.8 * uni(rng));
    const int r = static_cast<int>(std::ceil(4 * sigma));
    for (int y = std::max(0, static_cast<int>(cy) - r); y < std::min(h, static_cast<int>(cy) + r + 1); ++y) {
      for (int x = std::max(0, static_cast<int>(cx) - r); x < std::min(w, static_cast<int>(cx) + r + 1); ++x) {
        const double d2 = Sqr(x + 0.5 - cx) + Sqr(y + 0.5 - cy);
        tau.at(x, y) += static_cast<float>(peak * std::exp(-0.5 * d2 / Sqr(sigma)));
      }
    }
  }
  for (auto& v : tau.data()) v = std::min(v, static_cast<float>(options.max_tau));
  return tau;
}

}  // namespace thinslab
