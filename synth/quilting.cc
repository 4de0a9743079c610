// SPDX-License-Identifier: Apache-2.0
#include "thinslab/synth/quilting.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <random>
#include <sstream>
#include <vector>

#include "thinslab/core/math.h"

namespace thinslab {

bool QuiltingOptions::Check(std::string* error) const {
  std::ostringstream e;
  if (patch_px < 4 || patch_px > 1024)
    e << "QuiltingOptions::patch_px = " << patch_px << ". Violated constraint: in [4, 1024]";
  else if (overlap_px < 1 || overlap_px > patch_px / 2)
    e << "QuiltingOptions::overlap_px = " << overlap_px << ". Violated constraint: in [1, patch_px / 2]";
  else if (!(tolerance >= 0 && tolerance <= 10))
    e << "QuiltingOptions::tolerance = " << tolerance << ". Violated constraint: in [0, 10]";
  else if (!(variance_tolerance >= 0 && variance_tolerance <= 10))
    e << "QuiltingOptions::variance_tolerance = " << variance_tolerance << ". Violated constraint: in [0, 10]";
  else if (max_candidates < 0)
    e << "QuiltingOptions::max_candidates = " << max_candidates << ". Violated constraint: >= 0";
  else if (!(max_tilt > 0 && max_tilt <= 20))
    e << "QuiltingOptions::max_tilt = " << max_tilt << ". Violated constraint: in (0, 20]";
  else if (!(mass_feedback >= 0 && mass_feedback <= 10))
    e << "QuiltingOptions::mass_feedback = " << mass_feedback << ". Violated constraint: in [0, 10]";
  if (e.str().empty()) return true;
  *error = e.str();
  return false;
}

namespace {

// Minimum-error boundary cut (Efros and Freeman 2001, Sec. 2.1): the path of least cumulative
// squared difference through an overlap strip, one position per line, moving at most one
// position sideways per line. `err` is lines x width, row-major; returns the cut position per
// line. Pixels before the cut keep the old patch, pixels at or after it take the new one.
std::vector<int> MinErrorCut(const std::vector<double>& err, int lines, int width) {
  std::vector<double> cum(err.size());
  std::copy(err.begin(), err.begin() + width, cum.begin());
  for (int l = 1; l < lines; ++l) {
    for (int x = 0; x < width; ++x) {
      double best = cum[(l - 1) * width + x];
      if (x > 0) best = std::min(best, cum[(l - 1) * width + x - 1]);
      if (x + 1 < width) best = std::min(best, cum[(l - 1) * width + x + 1]);
      cum[l * width + x] = err[l * width + x] + best;
    }
  }
  std::vector<int> cut(lines);
  int x = 0;
  for (int k = 1; k < width; ++k) {
    if (cum[(lines - 1) * width + k] < cum[(lines - 1) * width + x]) x = k;
  }
  cut[lines - 1] = x;
  for (int l = lines - 1; l > 0; --l) {
    // Ties go to the straight move, then left, then right: deterministic.
    int next = x;
    double best = cum[(l - 1) * width + x];
    if (x > 0 && cum[(l - 1) * width + x - 1] < best) {
      best = cum[(l - 1) * width + x - 1];
      next = x - 1;
    }
    if (x + 1 < width && cum[(l - 1) * width + x + 1] < best) next = x + 1;
    x = next;
    cut[l - 1] = x;
  }
  return cut;
}

// Whether patch pixel (x, y) takes the new patch, given the cuts through its left and top
// overlap strips.
bool TakesNew(int x, int y, int overlap, bool left, bool top, const std::vector<int>& cut_left,
              const std::vector<int>& cut_top) {
  const bool take_left = !left || x >= overlap || x >= cut_left[y];
  const bool take_top = !top || y >= overlap || y >= cut_top[x];
  return take_left && take_top;
}

// Not in Efros-Freeman: exponential tilting of a uniform draw. Returns the weights
// w_q = e^{lambda u_q} / sum_r e^{lambda u_r} with sum_q w_q u_q = 0, the distribution closest
// to uniform in Kullback-Leibler divergence whose mean of u is 0 (the I-projection; Csiszar
// 1975). lambda is limited to [-max_lambda, max_lambda]; *capped says whether the limit was
// reached (then the weighted mean of u is the closest to 0 the limit allows).
void SolveTilt(const std::vector<double>& u, double max_lambda, std::vector<double>* weights, bool* capped) {
  auto mean_at = [&](double lambda) {
    double top = -std::numeric_limits<double>::infinity();
    for (double v : u) top = std::max(top, lambda * v);
    double z = 0, m = 0;
    weights->resize(u.size());
    for (size_t q = 0; q < u.size(); ++q) {
      (*weights)[q] = std::exp(lambda * u[q] - top);
      z += (*weights)[q];
      m += (*weights)[q] * u[q];
    }
    for (double& w : *weights) w /= z;
    return m / z;
  };
  // The weighted mean of u increases with lambda (its derivative is the weighted variance).
  double lo = -max_lambda, hi = max_lambda;
  *capped = false;
  if (mean_at(0) == 0) return;  // Uniform already (also when every u is 0).
  *capped = true;
  if (mean_at(lo) >= 0 || mean_at(hi) <= 0) return;  // mean_at(hi) left the weights at the cap.
  *capped = false;
  for (int it = 0; it < 60; ++it) {
    const double mid = 0.5 * (lo + hi);
    (mean_at(mid) < 0 ? lo : hi) = mid;
  }
  mean_at(0.5 * (lo + hi));
}

}  // namespace

void SpecifyHistogram(const std::vector<float>& source, std::vector<float>* values) {
  if (source.empty() || values->empty()) return;
  std::vector<float> sorted_source = source;
  std::sort(sorted_source.begin(), sorted_source.end());
  std::vector<std::pair<float, size_t>> order(values->size());
  for (size_t i = 0; i < values->size(); ++i) order[i] = {(*values)[i], i};
  std::sort(order.begin(), order.end());
  const double n_out = static_cast<double>(order.size()), n_src = static_cast<double>(sorted_source.size());
  for (size_t a = 0; a < order.size();) {
    size_t b = a;
    while (b < order.size() && order[b].first == order[a].first) ++b;
    float target = 0.0f;
    // Clean glass stays clean: the group of exact zeros keeps 0, even when the output has
    // more zeros than the source (its mid-rank quantile would then be a positive source value,
    // a haze over every clean pixel). Every other group takes the source value at its mid-rank
    // quantile over the whole output, so the positive values keep their place in the source
    // distribution and, when the output has fewer zeros than the source, its faintest values
    // become 0 until the source's zero fraction is reached.
    if (order[a].first != 0.0f) {
      const double mid_rank = 0.5 * (static_cast<double>(a) + static_cast<double>(b - 1));
      const size_t k = n_out > 1 ? static_cast<size_t>(std::llround(mid_rank * (n_src - 1) / (n_out - 1))) : 0;
      target = sorted_source[std::min(k, sorted_source.size() - 1)];
    }
    for (size_t i = a; i < b; ++i) (*values)[order[i].second] = target;
    a = b;
  }
}

Status QuiltTexture(const Image& source, int width, int height, const QuiltingOptions& options, Image* output,
                    Image* patch_index, QuiltingSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  if (width < 1 || height < 1 || width > 65536 || height > 65536) {
    return Status::Error("quilting output size " + std::to_string(width) + "x" + std::to_string(height) +
                         " is impossible: each side must be in [1, 65536] px");
  }
  const int P = options.patch_px, O = options.overlap_px, S = P - O;
  const int sw = source.width(), sh = source.height();
  if (source.num_channels() < 1 || sw < P || sh < P) {
    return Status::Error("quilting source is " + std::to_string(sw) + "x" + std::to_string(sh) +
                         " px, smaller than one " + std::to_string(P) + " px patch (QuiltingOptions::patch_px)");
  }
  std::vector<float> src(static_cast<size_t>(sw) * sh);
  for (int y = 0; y < sh; ++y) {
    for (int x = 0; x < sw; ++x) {
      const float v = source.at(x, y, 0);
      if (!std::isfinite(v)) {
        return Status::Error("quilting source pixel (" + std::to_string(x) + ", " + std::to_string(y) +
                             ") is not finite");
      }
      src[static_cast<size_t>(y) * sw + x] = v;
    }
  }
  double mean = 0, var = 0;
  for (float v : src) mean += v;
  mean /= src.size();
  for (float v : src) var += (v - mean) * (v - mean);
  var /= src.size();
  const double source_mean = mean;
  // Canvas of whole patches covering the output; cropped at the end.
  const int nx = width <= P ? 1 : (width - O + S - 1) / S;
  const int ny = height <= P ? 1 : (height - O + S - 1) / S;
  const int cw = nx * S + O, ch = ny * S + O;
  std::vector<float> canvas(static_cast<size_t>(cw) * ch, 0.0f);
  std::vector<int32_t> ids(static_cast<size_t>(cw) * ch, -1);

  const int cand_x = sw - P + 1, cand_y = sh - P + 1;
  const int64_t num_positions = static_cast<int64_t>(cand_x) * cand_y;
  const bool exhaustive = options.max_candidates == 0 || num_positions <= options.max_candidates;
  const int64_t num_candidates = exhaustive ? num_positions : options.max_candidates;
  std::mt19937_64 rng(options.seed);
  std::vector<int64_t> candidates(num_candidates);
  std::vector<double> errors(num_candidates);
  std::vector<int64_t> qualifying;
  std::vector<double> masses, weights;
  std::vector<double> strip;
  QuiltingSummary local;
  double canvas_mass = 0;
  int64_t written_pixels = 0;
  std::vector<int> cut_left, cut_top;
  // Boundary cuts of the patch from source (sx, sy) at canvas (px, py) through the left
  // strip (one column per row) and the top strip (one row per column).
  auto BoundaryCuts = [&](int sx, int sy, bool left, bool top, int px, int py, std::vector<int>* cl,
                          std::vector<int>* ct) {
    auto diff2 = [&](int x, int y) {
      return std::pow(src[static_cast<size_t>(sy + y) * sw + sx + x] - canvas[static_cast<size_t>(py + y) * cw + px + x],
                      2);
    };
    cl->clear();
    ct->clear();
    if (left) {
      strip.assign(static_cast<size_t>(P) * O, 0.0);
      for (int y = 0; y < P; ++y) {
        for (int x = 0; x < O; ++x) strip[y * O + x] = diff2(x, y);
      }
      *cl = MinErrorCut(strip, P, O);
    }
    if (top) {
      strip.assign(static_cast<size_t>(P) * O, 0.0);
      for (int x = 0; x < P; ++x) {
        for (int y = 0; y < O; ++y) strip[x * O + y] = diff2(x, y);
      }
      *ct = MinErrorCut(strip, P, O);
    }
  };

  for (int j = 0; j < ny; ++j) {
    for (int i = 0; i < nx; ++i) {
      const int px = i * S, py = j * S;
      const bool left = i > 0, top = j > 0;
      const int32_t id = j * nx + i;
      if (exhaustive) {
        for (int64_t k = 0; k < num_candidates; ++k) candidates[k] = k;
      } else {
        std::uniform_int_distribution<int64_t> pick(0, num_positions - 1);
        for (int64_t k = 0; k < num_candidates; ++k) candidates[k] = pick(rng);
      }
      int64_t chosen = 0;
      if (!left && !top) {
        std::uniform_int_distribution<int64_t> pick(0, num_positions - 1);
        chosen = pick(rng);
      } else {
        const int overlap_pixels = (left ? P * O : 0) + (top ? P * O : 0) - (left && top ? O * O : 0);
        const double error_floor = options.variance_tolerance * var * overlap_pixels;
        // Overlap SSD (Efros and Freeman 2001, Sec. 2.1). A candidate whose partial sum
        // already exceeds (1 + tolerance) * best-so-far can never qualify: stop early.
        double best = std::numeric_limits<double>::infinity();
        for (int64_t k = 0; k < num_candidates; ++k) {
          const int sx = static_cast<int>(candidates[k] % cand_x), sy = static_cast<int>(candidates[k] / cand_x);
          const double bound = best * (1.0 + options.tolerance) + error_floor;
          double e = 0;
          for (int y = 0; y < P && e <= bound; ++y) {
            const float* s_row = &src[static_cast<size_t>(sy + y) * sw + sx];
            const float* c_row = &canvas[static_cast<size_t>(py + y) * cw + px];
            // Left strip: columns [0, O) on every row; top strip: the rest of rows [0, O).
            const int x_end = (top && y < O) ? P : (left ? O : 0);
            double row = 0;
            for (int x = 0; x < x_end; ++x) {
              const double d = static_cast<double>(s_row[x]) - c_row[x];
              row += d * d;
            }
            e += row;
          }
          errors[k] = e;
          best = std::min(best, e);
          ++local.candidates_evaluated;
        }
        const double threshold = best * (1.0 + options.tolerance) + error_floor;
        qualifying.clear();
        for (int64_t k = 0; k < num_candidates; ++k) {
          if (errors[k] <= threshold) qualifying.push_back(candidates[k]);
        }
        if (options.selection == QuiltingSelection::kSsd) {
          std::uniform_int_distribution<size_t> pick(0, qualifying.size() - 1);
          chosen = qualifying[pick(rng)];
        } else {
          // Not in Efros-Freeman: mass-matched selection (docs/models/contamination_synthesis.md,
          // Sec. 2). delta_q, the tau mass candidate q adds to the canvas once joined along its
          // own boundary cut, is on average below the source's for the pixels it adds (SSD
          // favours low-dust overlaps). The draw among the qualifying candidates is tilted so
          // that the expected delta is the source mean times the new pixels, plus
          // mass_feedback times the canvas's running deficit.
          const int new_pixels = P * P - overlap_pixels;
          const double target =
              source_mean * new_pixels + options.mass_feedback * (source_mean * written_pixels - canvas_mass);
          masses.resize(qualifying.size());
          double sum = 0, sum_sq = 0;
          for (size_t q = 0; q < qualifying.size(); ++q) {
            const int sx = static_cast<int>(qualifying[q] % cand_x), sy = static_cast<int>(qualifying[q] / cand_x);
            BoundaryCuts(sx, sy, left, top, px, py, &cut_left, &cut_top);
            double delta = 0;
            for (int y = 0; y < P; ++y) {
              for (int x = 0; x < P; ++x) {
                if (!TakesNew(x, y, O, left, top, cut_left, cut_top)) continue;
                delta += src[static_cast<size_t>(sy + y) * sw + sx + x] - canvas[static_cast<size_t>(py + y) * cw + px + x];
              }
            }
            masses[q] = delta - target;
            sum += masses[q];
            sum_sq += masses[q] * masses[q];
          }
          // u_q in units of the spread of delta over the qualifying set, so that max_tilt
          // bounds the largest weight ratio per unit of spread whatever the texture's scale.
          const double n_q = static_cast<double>(qualifying.size());
          const double spread = std::sqrt(std::max(0.0, sum_sq / n_q - Sqr(sum / n_q)));
          for (double& m : masses) m = spread > 0 ? m / spread : 0.0;
          bool capped = false;
          SolveTilt(masses, options.max_tilt, &weights, &capped);
          local.tilt_capped_patches += capped;
          // Inverse-CDF draw from 53 random bits (the same on every standard library).
          const double u = static_cast<double>(rng() >> 11) * 0x1.0p-53;
          double acc = 0;
          size_t q = 0;
          for (; q + 1 < qualifying.size(); ++q) {
            acc += weights[q];
            if (u < acc) break;
          }
          chosen = qualifying[q];
        }
      }
      const int sx = static_cast<int>(chosen % cand_x), sy = static_cast<int>(chosen / cand_x);
      BoundaryCuts(sx, sy, left, top, px, py, &cut_left, &cut_top);
      for (int y = 0; y < P; ++y) {
        for (int x = 0; x < P; ++x) {
          if (!TakesNew(x, y, O, left, top, cut_left, cut_top)) continue;
          const size_t at = static_cast<size_t>(py + y) * cw + px + x;
          if (ids[at] < 0) ++written_pixels;
          canvas_mass += src[static_cast<size_t>(sy + y) * sw + sx + x] - canvas[at];
          canvas[at] = src[static_cast<size_t>(sy + y) * sw + sx + x];
          ids[at] = id;
        }
      }
      ++local.patches;
    }
  }

  *output = Image(width, height, {"tau"});
  if (patch_index) *patch_index = Image(width, height, {"patch_index"});
  for (int y = 0; y < height; ++y) {
    for (int x = 0; x < width; ++x) {
      output->at(x, y) = canvas[static_cast<size_t>(y) * cw + x];
      if (patch_index) patch_index->at(x, y) = static_cast<float>(ids[static_cast<size_t>(y) * cw + x]);
    }
  }
  local.source_zero_fraction =
      static_cast<double>(std::count(src.begin(), src.end(), 0.0f)) / static_cast<double>(src.size());
  local.quilted_zero_fraction = static_cast<double>(std::count(output->data().begin(), output->data().end(), 0.0f)) /
                                static_cast<double>(output->data().size());
  if (options.match_histogram) SpecifyHistogram(src, &output->data());
  local.total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (summary) *summary = local;
  return Status::Ok();
}

}  // namespace thinslab
