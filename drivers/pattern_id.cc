// SPDX-License-Identifier: Apache-2.0
#include "thinslab/drivers/pattern_id.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <utility>

namespace thinslab {
namespace {

std::vector<std::string> SplitCommas(const std::string& s) {
  std::vector<std::string> parts;
  size_t start = 0;
  while (true) {
    const size_t comma = s.find(',', start);
    parts.push_back(s.substr(start, comma == std::string::npos ? std::string::npos : comma - start));
    if (comma == std::string::npos) break;
    start = comma + 1;
  }
  return parts;
}

bool ParseFiniteDouble(const std::string& s, double* value) {
  if (s.empty() || std::isspace(static_cast<unsigned char>(s[0]))) return false;
  char* end = nullptr;
  errno = 0;
  const double v = std::strtod(s.c_str(), &end);
  if (errno != 0 || end != s.c_str() + s.size() || !std::isfinite(v)) return false;
  *value = v;
  return true;
}

Status PatternError(const std::string& id, const std::string& what) {
  return Status::Error("pattern id \"" + id + "\": " + what);
}

std::string ShortestDouble(double v) {
  char buf[64];
  for (int precision = 1; precision <= 17; ++precision) {
    std::snprintf(buf, sizeof(buf), "%.*g", precision, v);
    if (std::strtod(buf, nullptr) == v) break;
  }
  return buf;
}

// Integral of the unit tent max(0, 1 - |t|) from -inf to t.
double TentCdf(double t) {
  if (t <= -1) return 0;
  if (t >= 1) return 1;
  return t <= 0 ? 0.5 * (t + 1) * (t + 1) : 1 - 0.5 * (1 - t) * (1 - t);
}

// Value of pixel (px, py): the disc of radius r around (cx, cy) integrated against the separable
// tent (bilinear) kernel centred on the pixel centre. Why a tent and not the pixel box: sampling
// at pixel centres preserves the total and the first moments of f exactly iff f's spectrum and
// its gradient vanish at every non-zero integer frequency. The box kernel's sinc has only simple
// zeros there, which leaves a centroid bias of up to 0.02 px for a 1 px dot; the tent's sinc^2
// has double zeros, so the intensity centroid of the rasterised dot is its centre (up to the
// quadrature below, < 1e-4 px) and its sum is the disc area. The cost is one pixel of extra blur.
double PixelValue(int px, int py, double cx, double cy, double r) {
  const double ux = px + 0.5, uy = py + 0.5;
  // Support [u-1, u+1]^2: entirely outside or inside the disc are the common cases.
  const double nx = std::clamp(cx, ux - 1, ux + 1) - cx;
  const double ny = std::clamp(cy, uy - 1, uy + 1) - cy;
  if (nx * nx + ny * ny >= r * r) return 0;
  const double fx = std::abs(ux - cx) + 1, fy = std::abs(uy - cy) + 1;
  if (fx * fx + fy * fy <= r * r) return 1;
  // Midpoint rule over the chords y - cy = r sin(theta) inside the support: the substitution
  // removes the square-root singularity of the chord length at the disc's top and bottom, so
  // the error is O(1/n^2) from the kernel's kinks only; the x integral of each chord is exact.
  const double lo = std::max(uy - 1 - cy, -r) / r, hi = std::min(uy + 1 - cy, r) / r;
  if (hi <= lo) return 0;
  const double theta0 = std::asin(std::clamp(lo, -1.0, 1.0));
  const double theta1 = std::asin(std::clamp(hi, -1.0, 1.0));
  // Split at the kernel's kink in y (t = 0) so each panel's integrand is smooth there.
  const double kink = std::clamp((uy - cy) / r, lo, hi);
  const double theta_kink = std::asin(std::clamp(kink, -1.0, 1.0));
  constexpr int kRows = 128;  // Per panel.
  double value = 0;
  for (const auto& [a, b] : {std::pair<double, double>{theta0, theta_kink}, {theta_kink, theta1}}) {
    const double dtheta = (b - a) / kRows;
    for (int k = 0; k < kRows; ++k) {
      const double theta = a + (k + 0.5) * dtheta;
      const double t = cy + r * std::sin(theta) - uy;  // Offset from the pixel centre in y.
      const double h = r * std::cos(theta);
      const double wx = TentCdf(cx + h - ux) - TentCdf(cx - h - ux);
      value += std::max(0.0, 1 - std::abs(t)) * wx * h * dtheta;
    }
  }
  return value;
}

}  // namespace

Status ParsePatternId(const std::string& id, PatternSpec* spec) {
  PatternSpec out;
  if (id.empty()) {
    out.kind = PatternSpec::Kind::kBlack;
    *spec = out;
    return Status::Ok();
  }
  const size_t colon = id.find(':');
  const std::string head = id.substr(0, colon);
  const std::string args = colon == std::string::npos ? std::string() : id.substr(colon + 1);
  const bool has_args = colon != std::string::npos;
  if (head == "flat") {
    out.kind = PatternSpec::Kind::kFlat;
    out.level = 1;
    if (has_args) {
      if (!ParseFiniteDouble(args, &out.level) || out.level < 0 || out.level > 1) {
        return PatternError(id, "flat level \"" + args + "\" is not a number in [0, 1]");
      }
    }
  } else if (head == "dot" || head == "dots") {
    if (!has_args) return PatternError(id, head + " needs coordinates after ':'");
    const std::vector<std::string> fields = SplitCommas(args);
    const size_t expected = head == "dot" ? 2 : 6;
    if (fields.size() != expected) {
      return PatternError(id, head + " expects " + std::to_string(expected) +
                                  " comma-separated numbers, got " + std::to_string(fields.size()));
    }
    std::vector<double> v(fields.size());
    for (size_t i = 0; i < fields.size(); ++i) {
      if (!ParseFiniteDouble(fields[i], &v[i])) {
        return PatternError(id, "field " + std::to_string(i + 1) + " \"" + fields[i] +
                                    "\" is not a finite number");
      }
    }
    out.kind = PatternSpec::Kind::kDots;
    out.level = 1;
    if (head == "dot") {
      out.dots.push_back({v[0], v[1]});
    } else {
      const double nx = v[4], ny = v[5];
      if (nx != std::floor(nx) || ny != std::floor(ny) || nx < 1 || ny < 1) {
        return PatternError(id, "dots grid counts nx, ny must be whole numbers >= 1");
      }
      // A grid larger than any display is a typo, and would allocate without bound.
      if (nx * ny > 1e6) return PatternError(id, "dots grid has more than 1e6 dots");
      for (int j = 0; j < static_cast<int>(ny); ++j) {
        for (int i = 0; i < static_cast<int>(nx); ++i) {
          out.dots.push_back({v[0] + i * v[2], v[1] + j * v[3]});
        }
      }
    }
  } else {
    return PatternError(id, "unknown pattern \"" + head +
                                "\" (expected \"\", flat, flat:<level>, dot:<x>,<y> or "
                                "dots:<x0>,<y0>,<dx>,<dy>,<nx>,<ny>)");
  }
  *spec = out;
  return Status::Ok();
}

std::string DotPatternId(double x_px, double y_px) {
  return "dot:" + ShortestDouble(x_px) + "," + ShortestDouble(y_px);
}

std::string FlatPatternId(double level) { return "flat:" + ShortestDouble(level); }

Status RasterizePattern(const PatternSpec& spec, int width, int height, double dot_radius_px,
                        Image* image) {
  if (width <= 0 || height <= 0) {
    return Status::Error("RasterizePattern: size " + std::to_string(width) + "x" +
                         std::to_string(height) + " is not positive");
  }
  // Dots are spots, not discs covering the screen; the bound keeps the stamp size sane.
  if (!(dot_radius_px > 0) || !(dot_radius_px <= 1000)) {
    return Status::Error("RasterizePattern: dot radius " + std::to_string(dot_radius_px) +
                         " px is not in (0, 1000]");
  }
  Image out(width, height, 0.0f);
  switch (spec.kind) {
    case PatternSpec::Kind::kBlack:
      break;
    case PatternSpec::Kind::kFlat:
      std::fill(out.data().begin(), out.data().end(), static_cast<float>(spec.level));
      break;
    case PatternSpec::Kind::kDots: {
      // One stamp per distinct sub-pixel phase: a grid with whole-pixel spacing rasterises a
      // single dot, however many it has. A stamp covers the pixels the tent-blurred disc reaches.
      const int half = static_cast<int>(std::ceil(dot_radius_px)) + 2;
      const int side = 2 * half + 1;
      std::map<std::pair<double, double>, std::vector<float>> stamps;
      for (const PatternSpec::Dot& dot : spec.dots) {
        // Dots wholly off-screen draw nothing (and must not reach the int conversions below).
        if (dot.x_px + half < 0 || dot.y_px + half < 0 || dot.x_px - half > width ||
            dot.y_px - half > height) {
          continue;
        }
        const int ix = static_cast<int>(std::floor(dot.x_px));
        const int iy = static_cast<int>(std::floor(dot.y_px));
        const std::pair<double, double> phase(dot.x_px - ix, dot.y_px - iy);
        std::vector<float>& stamp = stamps[phase];
        if (stamp.empty()) {
          stamp.resize(static_cast<size_t>(side) * side);
          for (int j = 0; j < side; ++j) {
            for (int i = 0; i < side; ++i) {
              stamp[j * side + i] = static_cast<float>(
                  PixelValue(i - half, j - half, phase.first, phase.second, dot_radius_px));
            }
          }
        }
        for (int j = 0; j < side; ++j) {
          const int y = iy + j - half;
          if (y < 0 || y >= height) continue;
          for (int i = 0; i < side; ++i) {
            const int x = ix + i - half;
            if (x < 0 || x >= width) continue;
            float& v = out.at(x, y);
            v = static_cast<float>(std::min(1.0, v + spec.level * stamp[j * side + i]));
          }
        }
      }
      break;
    }
      break;
  }
  *image = std::move(out);
  return Status::Ok();
}

}  // namespace thinslab
