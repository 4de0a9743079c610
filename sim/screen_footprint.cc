// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/screen_footprint.h"

#include <algorithm>
#include <cmath>

namespace thinslab {
namespace {

constexpr int kMaxVertices = 12;  // A quadrilateral clipped by four half-planes has at most 8.

// Sutherland-Hodgman against one half-plane sign * (p[axis] - bound) >= 0.
int ClipAgainst(const Eigen::Vector2d* in, int n, int axis, double bound, double sign, Eigen::Vector2d* out) {
  int m = 0;
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector2d& a = in[k];
    const Eigen::Vector2d& b = in[(k + 1) % n];
    const double da = sign * (a[axis] - bound), db = sign * (b[axis] - bound);
    if (da >= 0) out[m++] = a;
    if ((da >= 0) != (db >= 0)) out[m++] = a + (b - a) * (da / (da - db));
  }
  return m;
}

}  // namespace

double ConvexPolygonAreaInBox(const Eigen::Vector2d* poly, int n, double x0, double y0, double x1, double y1) {
  Eigen::Vector2d a[kMaxVertices], b[kMaxVertices];
  std::copy(poly, poly + n, a);
  n = ClipAgainst(a, n, 0, x0, 1, b);
  n = ClipAgainst(b, n, 0, x1, -1, a);
  n = ClipAgainst(a, n, 1, y0, 1, b);
  n = ClipAgainst(b, n, 1, y1, -1, a);
  double twice_area = 0;
  for (int k = 0; k < n; ++k) {
    const Eigen::Vector2d& p = a[k];
    const Eigen::Vector2d& q = a[(k + 1) % n];
    twice_area += p.x() * q.y() - q.x() * p.y();
  }
  return 0.5 * std::abs(twice_area);
}

ScreenFootprintMean MeanOverFootprint(const Image& levels, const Eigen::Vector2d& centre, const Eigen::Vector2d& eu,
                                      const Eigen::Vector2d& ev) {
  ScreenFootprintMean mean;
  const int w = levels.width(), h = levels.height();
  const double area = std::abs(eu.x() * ev.y() - eu.y() * ev.x());
  if (!(area > 1e-12)) {
    if (centre.x() >= 0 && centre.y() >= 0 && centre.x() < w && centre.y() < h) {
      mean.level = levels.at(static_cast<int>(centre.x()), static_cast<int>(centre.y()));
      mean.inside = 1;
    }
    return mean;
  }
  const Eigen::Vector2d poly[4] = {centre - 0.5 * eu - 0.5 * ev, centre + 0.5 * eu - 0.5 * ev,
                                   centre + 0.5 * eu + 0.5 * ev, centre - 0.5 * eu + 0.5 * ev};
  const double half_x = 0.5 * (std::abs(eu.x()) + std::abs(ev.x())), half_y = 0.5 * (std::abs(eu.y()) + std::abs(ev.y()));
  const int x_begin = std::max(0, static_cast<int>(std::floor(centre.x() - half_x)));
  const int x_end = std::min(w - 1, static_cast<int>(std::floor(centre.x() + half_x)));
  const int y_begin = std::max(0, static_cast<int>(std::floor(centre.y() - half_y)));
  const int y_end = std::min(h - 1, static_cast<int>(std::floor(centre.y() + half_y)));
  if (x_begin > x_end || y_begin > y_end) return mean;  // Wholly on the bezel.
  mean.inside = ConvexPolygonAreaInBox(poly, 4, 0, 0, w, h) / area;
  double sum = 0;
  for (int y = y_begin; y <= y_end; ++y) {
    for (int x = x_begin; x <= x_end; ++x) {
      const float l = levels.at(x, y);
      if (l != 0) sum += l * ConvexPolygonAreaInBox(poly, 4, x, y, x + 1, y + 1);
    }
  }
  mean.level = sum / area;
  return mean;
}

}  // namespace thinslab
