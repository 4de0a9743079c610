// SPDX-License-Identifier: Apache-2.0
#include "thinslab/synth/placement.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <sstream>

#include "thinslab/core/math.h"

namespace thinslab {

bool PlacementOptions::Check(std::string* error) const {
  std::ostringstream e;
  if (!(density >= 0 && density <= 100))
    e << "PlacementOptions::density = " << density << ". Violated constraint: in [0, 100]";
  else if (!(scale_min > 0 && scale_min <= scale_max && scale_max <= 16))
    e << "PlacementOptions::scale = [" << scale_min << ", " << scale_max
      << "]. Violated constraint: 0 < scale_min <= scale_max <= 16";
  else if (!(rotation_min_deg >= -360 && rotation_min_deg <= rotation_max_deg && rotation_max_deg <= 360))
    e << "PlacementOptions::rotation_deg = [" << rotation_min_deg << ", " << rotation_max_deg
      << "]. Violated constraint: -360 <= min <= max <= 360";
  else if (!(x_min >= 0 && x_min <= x_max && x_max <= 1))
    e << "PlacementOptions::x = [" << x_min << ", " << x_max << "]. Violated constraint: 0 <= x_min <= x_max <= 1";
  else if (!(y_min >= 0 && y_min <= y_max && y_max <= 1))
    e << "PlacementOptions::y = [" << y_min << ", " << y_max << "]. Violated constraint: 0 <= y_min <= y_max <= 1";
  else if (!(top_bias >= 1 && top_bias <= 10))
    e << "PlacementOptions::top_bias = " << top_bias << ". Violated constraint: in [1, 10]";
  else if (!(pitch_ratio > 0 && pitch_ratio <= 64))
    e << "PlacementOptions::pitch_ratio = " << pitch_ratio << ". Violated constraint: in (0, 64]";
  if (e.str().empty()) return true;
  *error = e.str();
  return false;
}

PlacementOptions DefaultPlacementForCategory(const std::string& category) {
  PlacementOptions o;
  if (category == "dirt") {
    // Gu et al. 2007, Sec. 5.3: limited rotation and translation, water stripes on the top.
    o.density = 0.15;
    o.scale_min = 0.8;
    o.scale_max = 1.2;
    o.rotation_min_deg = -10;
    o.rotation_max_deg = 10;
    o.y_min = 0;
    o.y_max = 0.5;
    o.top_bias = 2;
  }
  return o;
}

Status PlaceCopies(const Image& prototype, int width, int height, const PlacementOptions& o, uint64_t seed,
                   Image* canvas, std::vector<PlacedCopy>* copies) {
  std::string error;
  if (!o.Check(&error)) return Status::Error(error);
  if (width < 1 || height < 1 || width > 65536 || height > 65536) {
    return Status::Error("placement canvas " + std::to_string(width) + "x" + std::to_string(height) +
                         " is impossible: each side must be in [1, 65536] px");
  }
  const int pw = prototype.width(), ph = prototype.height();
  if (pw < 1 || ph < 1 || prototype.num_channels() < 1) return Status::Error("placement prototype is empty");
  if (canvas->empty()) *canvas = Image(width, height, {"tau"});
  if (canvas->width() != width || canvas->height() != height)
    return Status::Error("placement canvas has the wrong size");
  if (copies) copies->clear();

  // E[s^2] for s uniform in [a, b] is (a^2 + ab + b^2) / 3.
  const double mean_s2 = (Sqr(o.scale_min) + o.scale_min * o.scale_max + Sqr(o.scale_max)) / 3.0;
  const double copy_area = static_cast<double>(pw) * ph * Sqr(o.pitch_ratio) * mean_s2;
  const int64_t count = std::llround(o.density * static_cast<double>(width) * height / copy_area);
  if (count > 1000000)
    return Status::Error("PlacementOptions::density asks for " + std::to_string(count) + " copies (> 10^6)");

  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const double pcx = 0.5 * pw, pcy = 0.5 * ph;
  for (int64_t n = 0; n < count; ++n) {
    // Draw order fixed (x, y, scale, rotation): part of the seed contract.
    PlacedCopy c;
    const double ux = uni(rng), uy = uni(rng), us = uni(rng), ur = uni(rng);
    c.centre_x_px = (o.x_min + (o.x_max - o.x_min) * ux) * width;
    c.centre_y_px = (o.y_min + (o.y_max - o.y_min) * std::pow(uy, o.top_bias)) * height;
    c.scale = o.scale_min + (o.scale_max - o.scale_min) * us;
    c.rotation_deg = o.rotation_min_deg + (o.rotation_max_deg - o.rotation_min_deg) * ur;
    if (copies) copies->push_back(c);

    // canvas = centre + s R (p - prototype centre); inverse-map each canvas pixel centre.
    const double s = c.scale * o.pitch_ratio, a = c.rotation_deg * kPi / 180.0;
    const double ca = std::cos(a), sa = std::sin(a);
    const double half = 0.5 * s * std::sqrt(Sqr(static_cast<double>(pw)) + Sqr(static_cast<double>(ph)));
    const int x0 = std::max(0, static_cast<int>(std::floor(c.centre_x_px - half)));
    const int x1 = std::min(width - 1, static_cast<int>(std::ceil(c.centre_x_px + half)));
    const int y0 = std::max(0, static_cast<int>(std::floor(c.centre_y_px - half)));
    const int y1 = std::min(height - 1, static_cast<int>(std::ceil(c.centre_y_px + half)));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double dx = x + 0.5 - c.centre_x_px, dy = y + 0.5 - c.centre_y_px;
        // R^T d / s, then to prototype pixel coordinates (centres at +0.5).
        const double u = (ca * dx + sa * dy) / s + pcx - 0.5, v = (-sa * dx + ca * dy) / s + pcy - 0.5;
        if (u <= -1 || v <= -1 || u >= pw || v >= ph) continue;
        const int iu = static_cast<int>(std::floor(u)), iv = static_cast<int>(std::floor(v));
        const double fu = u - iu, fv = v - iv;
        auto tap = [&](int xx, int yy) -> double {
          return (xx < 0 || yy < 0 || xx >= pw || yy >= ph) ? 0.0 : prototype.at(xx, yy, 0);
        };
        const double value = (1 - fv) * ((1 - fu) * tap(iu, iv) + fu * tap(iu + 1, iv)) +
                             fv * ((1 - fu) * tap(iu, iv + 1) + fu * tap(iu + 1, iv + 1));
        if (value > 0) canvas->at(x, y, 0) += static_cast<float>(value);
      }
    }
  }
  return Status::Ok();
}

}  // namespace thinslab
