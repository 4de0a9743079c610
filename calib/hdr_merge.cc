// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/hdr_merge.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>
#include <set>

#include "thinslab/core/parallel.h"
#include "thinslab/core/session_io.h"

namespace thinslab {

bool HdrMergeOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(saturation_dn > 0)) {
    msg << "HdrMergeOptions::saturation_dn = " << saturation_dn << ". Violated constraint: > 0";
  } else if (!(gain_e_per_dn >= 0)) {
    msg << "HdrMergeOptions::gain_e_per_dn = " << gain_e_per_dn << ". Violated constraint: >= 0";
  } else if (!(read_noise_dn > 0)) {
    msg << "HdrMergeOptions::read_noise_dn = " << read_noise_dn << ". Violated constraint: > 0";
  } else if (log_domain && weighting != HdrWeighting::kHat) {
    msg << "HdrMergeOptions::log_domain = true needs weighting = kHat (Debevec & Malik Eq. 6)";
  } else if (!(black_level_dn >= 0)) {
    msg << "HdrMergeOptions::black_level_dn = " << black_level_dn << ". Violated constraint: >= 0";
  } else if (num_threads < 1 || num_threads > kMaxThreads) {
    msg << "HdrMergeOptions::num_threads = " << num_threads << ". Violated constraint: 1.." << kMaxThreads;
  } else {
    for (size_t i = 0; i < weight_table.size(); ++i) {
      if (!(weight_table[i] >= 0) || !std::isfinite(weight_table[i])) {
        msg << "HdrMergeOptions::weight_table[" << i << "] = " << weight_table[i] << ". Violated constraint: >= 0";
        *error = msg.str();
        return false;
      }
    }
    return true;
  }
  *error = msg.str();
  return false;
}

double HatWeight(double z_dn, double saturation_dn) {
  const double half = 0.5 * saturation_dn;
  return std::clamp(std::min(z_dn, saturation_dn - z_dn) / half, 0.0, 1.0);
}

namespace {

// The merge sums, over frames k, weight w_k, w_k * value_k and w_k^2 var(value_k). Each of them
// factorises into a per-level part that depends only on the sample z (and the dark) and a
// per-frame scale that depends only on the exposure t_k:
//   w_k = sa_k * a(z),   w_k value_k = sb_k * b(z) + soff_k * a(z),   w_k^2 var_k = sc_k * c(z).
// With v(z) the variance of L(z) and x = L(z) - dark:
//   inverse variance: a = 1/v,  b = x/v,     c = 1/v;             sa = t^2, sb = t,  soff = 0,     sc = t^2
//   hat, linear:      a = h,    b = h x,     c = h^2 v;           sa = 1,   sb = 1/t, soff = 0,    sc = 1/t^2
//   hat, log domain:  a = h,    b = h ln x,  c = h^2 v / x^2;     sa = 1,   sb = 1,  soff = -ln t, sc = 1
// (value_k = x / t_k, or ln(x / t_k) = ln x - ln t_k). So one table over the raw values serves
// every exposure: 2^16 levels x 12 bytes = 768 KiB, which stays in a core's L2 cache, where one
// table per exposure (5 x 1 MiB) did not and made the 16-bit merge 3x slower than the 8-bit one.
struct Level {
  float a = 0, b = 0, c = 0;  // All 0 for saturated samples and samples of zero weight.
};
struct Scale {
  double sa = 1, sb = 1, soff = 0, sc = 1;
};

// Everything that turns a black-subtracted sample z into its contribution. The one function
// LevelOf fills the table and serves the samples that cannot use it (dark-corrected frames,
// non-integer values), so both paths compute the same thing.
class SampleModel {
 public:
  SampleModel(const HdrMergeOptions& options)
      : options_(options),
        gain_(options.gain_e_per_dn > 0 ? options.gain_e_per_dn : 1.0),
        read_var_(options.read_noise_dn * options.read_noise_dn),
        nonlinear_(options.response != nullptr && !options.response->IsIdentity()) {}

  double Linearize(double z) const { return options_.response ? options_.response->Linearize(z) : z; }
  bool Saturated(double z) const { return z >= options_.saturation_dn - 0.5; }

  // x = L(z) - dark (linear DN) and its variance v: shot and read noise in the linear domain,
  // the dark's own variance, and for a nonlinear response the quantisation step L'(z).
  // own_var >= 0: the frame's declared variance of z, replacing shot and read noise.
  void Linear(double z, double dark, double dark_var, double own_var, double* x, double* v) const {
    const double l = Linearize(z);
    *v = (own_var >= 0 ? own_var : std::max(l, 0.0) / gain_ + read_var_) + dark_var;
    if (nonlinear_) {
      const double s = options_.response->Slope(z);
      *v += s * s / 12.0;
    }
    *x = l - dark;
  }

  // Radiance estimate x / t and its variance, whatever the weighting (used by the fallback).
  void Estimate(double z, double t, double dark, double dark_var, double own_var, double* x, double* var) const {
    double v;
    Linear(z, dark, dark_var, own_var, x, &v);
    *x /= t;
    *var = v / (t * t);
  }

  double HatOrTable(double z) const {
    if (!options_.weight_table.empty()) {
      // Table indexed by raw DN; interpolated for non-integer samples.
      const double raw = std::clamp(z + options_.black_level_dn, 0.0, static_cast<double>(options_.weight_table.size() - 1));
      const size_t i0 = static_cast<size_t>(raw);
      const size_t i1 = std::min(i0 + 1, options_.weight_table.size() - 1);
      const double f = raw - i0;
      return (1 - f) * options_.weight_table[i0] + f * options_.weight_table[i1];
    }
    return HatWeight(z, options_.saturation_dn);
  }

  Level LevelOf(double z, double dark, double dark_var, double own_var = -1) const {
    Level level;
    if (Saturated(z)) return level;
    double x, v;
    Linear(z, dark, dark_var, own_var, &x, &v);
    if (!(v > 0)) v = std::numeric_limits<double>::min();  // A declared variance of 0: exact.
    if (options_.weighting == HdrWeighting::kInverseVariance) {
      level.a = static_cast<float>(1.0 / v);
      level.b = static_cast<float>(x / v);
      level.c = level.a;
      return level;
    }
    const double h = HatOrTable(z);
    if (options_.log_domain) {
      if (!(x > 0)) return level;  // ln undefined: no weight (the fallback may still use it).
      level.a = static_cast<float>(h);
      level.b = static_cast<float>(h * std::log(x));
      level.c = static_cast<float>(h * h * v / (x * x));  // Delta method: var(ln x) = v / x^2.
      return level;
    }
    level.a = static_cast<float>(h);
    level.b = static_cast<float>(h * x);
    level.c = static_cast<float>(h * h * v);
    return level;
  }

  Scale ScaleOf(double t) const {
    Scale s;
    if (options_.weighting == HdrWeighting::kInverseVariance) {
      s.sa = s.sc = t * t;
      s.sb = t;
    } else if (options_.log_domain) {
      s.soff = -std::log(t);
    } else {
      s.sb = 1.0 / t;
      s.sc = 1.0 / (t * t);
    }
    return s;
  }

  double read_var() const { return read_var_; }
  double gain() const { return gain_; }

 private:
  const HdrMergeOptions& options_;
  double gain_;
  double read_var_;
  bool nonlinear_;
};

std::string FrameName(const std::vector<HdrFrame>& frames, size_t k) {
  return frames[k].name.empty() ? "frame " + std::to_string(k) : "frame '" + frames[k].name + "'";
}

Status CheckFrames(const std::vector<HdrFrame>& frames, int* bit_depth) {
  if (frames.empty()) return Status::Error("MergeExposureBracket: no frames");
  *bit_depth = 0;
  size_t depth_frame = 0;
  for (size_t k = 0; k < frames.size(); ++k) {
    if (frames[k].dn == nullptr || frames[k].dn->empty()) {
      return Status::Error("MergeExposureBracket: " + FrameName(frames, k) + ": image missing");
    }
  }
  const int w = frames[0].dn->width(), h = frames[0].dn->height();
  for (size_t k = 0; k < frames.size(); ++k) {
    const HdrFrame& f = frames[k];
    if (f.dn->width() != w || f.dn->height() != h) {
      return Status::Error("MergeExposureBracket: " + FrameName(frames, k) + " is " + std::to_string(f.dn->width()) +
                           "x" + std::to_string(f.dn->height()) + ", frame 0 is " + std::to_string(w) + "x" +
                           std::to_string(h));
    }
    if (f.dn->num_channels() != 1) {
      return Status::Error("MergeExposureBracket: " + FrameName(frames, k) + " has " +
                           std::to_string(f.dn->num_channels()) + " channels, expected 1");
    }
    if (!(f.exposure_time_us > 0) || !std::isfinite(f.exposure_time_us)) {
      return Status::Error("MergeExposureBracket: " + FrameName(frames, k) + " has exposure_time_us <= 0");
    }
    if (f.variance_dn2 != nullptr && (f.variance_dn2->width() != w || f.variance_dn2->height() != h)) {
      return Status::Error("MergeExposureBracket: " + FrameName(frames, k) + ": variance image size differs from the frame's");
    }
    if (f.dark_linear_dn != nullptr &&
        (f.dark_linear_dn->width() != w || f.dark_linear_dn->height() != h || f.dark_count < 1)) {
      return Status::Error("MergeExposureBracket: " + FrameName(frames, k) +
                           ": dark frame size differs from the bracket's or dark_count < 1");
    }
    if (f.bit_depth != 0) {
      if (*bit_depth == 0) {
        *bit_depth = f.bit_depth;
        depth_frame = k;
      } else if (f.bit_depth != *bit_depth) {
        return Status::Error("MergeExposureBracket: mixed bit depths: " + FrameName(frames, k) + " has bit_depth " +
                             std::to_string(f.bit_depth) + ", " + FrameName(frames, depth_frame) + " has " +
                             std::to_string(*bit_depth));
      }
    }
  }
  return Status::Ok();
}

// fn(y0, y1) on num_threads contiguous blocks of rows (core/parallel.h's ParallelFor).
template <typename Fn>
void ParallelRows(int height, int num_threads, const Fn& fn) {
  const int blocks = std::max(1, std::min(num_threads, height));
  ParallelFor(blocks, blocks, [&](int t) {
    fn(static_cast<int>(static_cast<int64_t>(height) * t / blocks),
       static_cast<int>(static_cast<int64_t>(height) * (t + 1) / blocks));
  });
}

}  // namespace

Status MergeExposureBracket(const std::vector<HdrFrame>& frames, const HdrMergeOptions& options, HdrImage* hdr) {
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  if (options.response != nullptr) THINSLAB_RETURN_IF_ERROR(options.response->Validate().WithContext("HdrMergeOptions::response"));
  int bit_depth = 0;
  THINSLAB_RETURN_IF_ERROR(CheckFrames(frames, &bit_depth));
  if (!options.weight_table.empty() && (bit_depth == 0 || bit_depth > 16 ||
                                        options.weight_table.size() != (size_t{1} << bit_depth))) {
    return Status::Error("HdrMergeOptions::weight_table has " + std::to_string(options.weight_table.size()) +
                         " entries; needs 2^bit_depth with the frames' bit_depth declared (" +
                         std::to_string(bit_depth) + ")");
  }
  const int w = frames[0].dn->width(), h = frames[0].dn->height();
  const size_t num_frames = frames.size();
  const SampleModel model(options);

  size_t shortest = 0;
  std::vector<size_t> longest_first(num_frames);
  for (size_t k = 0; k < num_frames; ++k) {
    longest_first[k] = k;
    if (frames[k].exposure_time_us < frames[shortest].exposure_time_us) shortest = k;
  }
  std::stable_sort(longest_first.begin(), longest_first.end(),
                   [&](size_t a, size_t b) { return frames[a].exposure_time_us > frames[b].exposure_time_us; });

  // One table over every raw value, shared by all frames without a dark frame.
  const bool tables = options.use_lookup_tables && bit_depth >= 8 && bit_depth <= 16;
  const size_t table_size = tables ? (size_t{1} << bit_depth) : 0;
  std::vector<Level> table(table_size);
  for (size_t raw = 0; raw < table_size; ++raw) {
    table[raw] = model.LevelOf(static_cast<double>(raw) - options.black_level_dn, 0.0, 0.0);
  }

  // Output buffers are reused when the caller merges brackets of one size repeatedly (no
  // page faults, no fill of 3 x 64 MB at 16 Mpx); every element of radiance and variance is
  // written below.
  auto reuse = [&](Image* image) {
    if (image->width() != w || image->height() != h || image->channel_names() != std::vector<std::string>{"Y"}) {
      *image = Image(w, h);
    }
  };
  reuse(&hdr->radiance);
  reuse(&hdr->variance);
  reuse(&hdr->all_saturated);
  std::fill(hdr->all_saturated.data().begin(), hdr->all_saturated.data().end(), 0.0f);
  hdr->radiance.attributes().clear();
  hdr->variance.attributes().clear();
  hdr->all_saturated.attributes().clear();
  hdr->used_lookup_tables = tables;
  const float black = static_cast<float>(options.black_level_dn);
  const float max_raw = static_cast<float>(table_size) - 1.0f;

  // Hot loop state as plain arrays (the compiler cannot hoist Image/vector accessors past the
  // output stores).
  std::vector<const float*> src(num_frames), dark_src(num_frames), own_var_src(num_frames);
  std::vector<Scale> scale(num_frames);
  std::vector<char> frame_uses_table(num_frames);
  for (size_t k = 0; k < num_frames; ++k) {
    src[k] = frames[k].dn->data().data();
    dark_src[k] = frames[k].dark_linear_dn != nullptr ? frames[k].dark_linear_dn->data().data() : nullptr;
    own_var_src[k] = frames[k].variance_dn2 != nullptr ? frames[k].variance_dn2->data().data() : nullptr;
    scale[k] = model.ScaleOf(frames[k].exposure_time_us);
    frame_uses_table[k] = tables && dark_src[k] == nullptr && own_var_src[k] == nullptr;
  }
  auto own_var_of = [&](size_t k, size_t i) { return own_var_src[k] != nullptr ? own_var_src[k][i] : -1.0; };
  auto dark_of = [&](size_t k, size_t i, double* dark, double* dark_var) {
    *dark = *dark_var = 0;
    if (dark_src[k] == nullptr) return;
    *dark = dark_src[k][i];
    *dark_var = (std::max(*dark, 0.0) / model.gain() + model.read_var()) / frames[k].dark_count;
  };

  std::vector<int64_t> all_saturated_rows(h, 0), fallback_rows(h, 0);
  float* const out_radiance = hdr->radiance.data().data();
  float* const out_variance = hdr->variance.data().data();
  ParallelRows(h, options.num_threads, [&](int y0, int y1) {
    const Level* levels = table.data();
    // Row accumulators. The loop runs frame by frame over a row, not pixel by pixel over the
    // frames: the table look-ups of neighbouring pixels are then independent and many are in
    // flight at once, which hides the cache misses that bound the pixel-major loop.
    // Float accumulators: a bracket has few frames, and float halves the memory traffic and
    // saves conversions; the per-pixel mean and variance are formed in double below.
    std::vector<float> acc_w(w), acc_wx(w), acc_w2var(w);
    for (int y = y0; y < y1; ++y) {
      const size_t row = static_cast<size_t>(y) * w;
      std::fill(acc_w.begin(), acc_w.end(), 0.0f);
      std::fill(acc_wx.begin(), acc_wx.end(), 0.0f);
      std::fill(acc_w2var.begin(), acc_w2var.end(), 0.0f);
      for (size_t k = 0; k < num_frames; ++k) {
        const float* row_src = src[k] + row;
        const float sa = static_cast<float>(scale[k].sa), sb = static_cast<float>(scale[k].sb);
        const float soff = static_cast<float>(scale[k].soff), sc = static_cast<float>(scale[k].sc);
        const bool use_table = frame_uses_table[k];
        for (int x = 0; x < w; ++x) {
          const float raw = row_src[x] + black;
          Level level;
          int index;
          if (use_table && raw >= 0.0f && raw <= max_raw && static_cast<float>(index = static_cast<int>(raw)) == raw) {
            level = levels[index];
          } else {
            double dark, dark_var;
            dark_of(k, row + x, &dark, &dark_var);
            level = model.LevelOf(row_src[x], dark, dark_var, own_var_of(k, row + x));
          }
          acc_w[x] += sa * level.a;
          acc_wx[x] += sb * level.b + soff * level.a;
          acc_w2var[x] += sc * level.c;
        }
      }
      for (int x = 0; x < w; ++x) {
        const size_t i = row + x;
        const double sum_w = acc_w[x], sum_wx = acc_wx[x], sum_w2var = acc_w2var[x];
        float radiance, variance;
        if (sum_w > 0) {
          const double mean = sum_wx / sum_w;
          const double var = sum_w2var / (sum_w * sum_w);
          if (options.log_domain) {
            const float e = std::exp(static_cast<float>(mean));
            radiance = e;
            variance = static_cast<float>(static_cast<double>(e) * e * var);
          } else {
            radiance = static_cast<float>(mean);
            variance = static_cast<float>(var);
          }
        } else {
          // No sample had weight: either every frame saturated, or the unsaturated samples all
          // had zero weight (hat weights at z <= 0, or x <= 0 in the log domain), and then the
          // longest unsaturated exposure has the best signal-to-noise ratio.
          bool found = false;
          radiance = variance = 0;
          for (size_t k : longest_first) {
            const float z = src[k][i];
            if (model.Saturated(z)) continue;
            double dark, dark_var, estimate, var;
            dark_of(k, i, &dark, &dark_var);
            model.Estimate(z, frames[k].exposure_time_us, dark, dark_var, own_var_of(k, i), &estimate, &var);
            radiance = static_cast<float>(estimate);
            variance = static_cast<float>(var);
            found = true;
            break;
          }
          if (found) {
            ++fallback_rows[y];
          } else {
            const double t = frames[shortest].exposure_time_us;
            const double lower = model.Linearize(options.saturation_dn) / t;
            radiance = static_cast<float>(lower);
            variance = static_cast<float>(lower * lower);
            hdr->all_saturated.data()[i] = 1;
            ++all_saturated_rows[y];
          }
        }
        out_radiance[i] = radiance;
        out_variance[i] = variance;
      }
    }
  });
  hdr->pixels_all_saturated = 0;
  hdr->pixels_fallback = 0;
  for (int y = 0; y < h; ++y) {
    hdr->pixels_all_saturated += all_saturated_rows[y];
    hdr->pixels_fallback += fallback_rows[y];
  }
  return Status::Ok();
}

double DarkFrameReadNoise(const std::vector<Image>& darks, const CameraResponse* response) {
  if (darks.empty()) return 0.5;
  auto linear = [&](float v) { return response != nullptr ? response->Linearize(v) : static_cast<double>(v); };
  const size_t n = darks[0].data().size();
  double sum = 0, sum_sq = 0;
  for (size_t i = 0; i < n; ++i) {
    const double d = darks.size() >= 2 ? linear(darks[0].data()[i]) - linear(darks[1].data()[i]) : linear(darks[0].data()[i]);
    sum += d;
    sum_sq += d * d;
  }
  const double var = sum_sq / n - (sum / n) * (sum / n);
  return std::sqrt(std::max(darks.size() >= 2 ? 0.5 * var : var, 0.25));
}

Status MergeSessionBracket(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                           const std::vector<const FrameRecord*>& frames, const std::vector<const FrameRecord*>& darks,
                           const CameraResponse* response, HdrMergeOptions options, double fallback_read_noise_dn,
                           const FrameNoiseModel& noise, HdrImage* hdr, SessionMergeInfo* info,
                           ExposureCheckMode exposure_check) {
  if (frames.empty()) return Status::Error(session_dir + ": no frames to merge");  // Before reading the darks.
  SessionDarks dark_frames;
  THINSLAB_RETURN_IF_ERROR(LoadSessionDarks(session_dir, session, darks, response, &dark_frames));
  return MergeSessionBracket(session_dir, session, camera, frames, dark_frames, response, options,
                             fallback_read_noise_dn, noise, hdr, info, exposure_check);
}

Status LoadSessionDarks(const std::string& session_dir, const Session& session,
                        const std::vector<const FrameRecord*>& darks, const CameraResponse* response,
                        SessionDarks* out) {
  *out = SessionDarks();
  // Darks: linearised, grouped by exposure.
  std::map<double, std::vector<Image>> dark_by_exposure;
  for (const FrameRecord* d : darks) {
    Image dark;
    THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *d, &dark));
    dark_by_exposure[d->exposure_time_us].push_back(std::move(dark));
  }
  out->num_frames = static_cast<int>(darks.size());
  if (!dark_by_exposure.empty()) out->read_noise_dn = DarkFrameReadNoise(dark_by_exposure.begin()->second, response);
  auto linear = [&](float v) { return response != nullptr ? response->Linearize(v) : static_cast<double>(v); };
  for (const auto& [t, group] : dark_by_exposure) {
    Image mean(group[0].width(), group[0].height());
    for (const Image& d : group) {
      for (size_t i = 0; i < mean.data().size(); ++i) {
        mean.data()[i] += static_cast<float>(linear(d.data()[i]) / group.size());
      }
    }
    out->linear.emplace(t, std::move(mean));
    out->count[t] = static_cast<int>(group.size());
  }
  return Status::Ok();
}

Status MergeSessionBracket(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                           const std::vector<const FrameRecord*>& frames, const SessionDarks& darks,
                           const CameraResponse* response, HdrMergeOptions options, double fallback_read_noise_dn,
                           const FrameNoiseModel& noise, HdrImage* hdr, SessionMergeInfo* info,
                           ExposureCheckMode exposure_check) {
  *info = SessionMergeInfo();
  if (frames.empty()) return Status::Error(session_dir + ": no frames to merge");
  if (!(fallback_read_noise_dn > 0)) {
    return Status::Error("MergeSessionBracket: fallback_read_noise_dn = " + std::to_string(fallback_read_noise_dn) +
                         ". Violated constraint: > 0");
  }
  std::vector<Image> images(frames.size()), variances(frames.size());
  std::vector<HdrFrame> bracket(frames.size());
  std::set<double> exposures;
  for (size_t k = 0; k < frames.size(); ++k) {
    THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *frames[k], &images[k]));
    THINSLAB_RETURN_IF_ERROR(LoadFrameVariance(session_dir, session, *frames[k], &variances[k]));
    if (!variances[k].empty()) {
      bracket[k].variance_dn2 = &variances[k];
      ++info->num_variance_files;
    }
    bracket[k].dn = &images[k];
    bracket[k].exposure_time_us = frames[k]->exposure_time_us;
    bracket[k].bit_depth = camera.bit_depth <= 16 ? camera.bit_depth : 0;
    bracket[k].name = frames[k]->file;
    exposures.insert(frames[k]->exposure_time_us);
  }
  if (noise.variance_floor.has_value()) {
    info->read_noise_dn = std::sqrt(*noise.variance_floor);
  } else if (!darks.linear.empty()) {
    info->read_noise_dn = darks.read_noise_dn;
  } else {
    info->read_noise_dn = std::max(fallback_read_noise_dn, 0.5);
  }
  const std::map<double, Image>& dark_linear = darks.linear;
  for (size_t k = 0; k < frames.size() && !dark_linear.empty(); ++k) {
    const double t = frames[k]->exposure_time_us;
    auto best = dark_linear.begin();
    for (auto it = dark_linear.begin(); it != dark_linear.end(); ++it) {
      if (std::abs(it->first - t) < std::abs(best->first - t)) best = it;
    }
    if (std::abs(best->first - t) > 1e-3 * t) ++info->dark_exposure_mismatches;
    bracket[k].dark_linear_dn = &best->second;
    bracket[k].dark_count = darks.count.at(best->first);
  }
  options.saturation_dn = camera.saturation_dn - camera.black_level_dn;
  options.black_level_dn = camera.black_level_dn;
  options.gain_e_per_dn = noise.method == "default" ? camera.gain_e_per_dn : noise.gain_e_per_dn();
  options.read_noise_dn = info->read_noise_dn;
  options.response = response;
  info->noise = noise;
  // Linear frames (already radiance) have no exposure of their own to check.
  if (camera.linear_frames()) exposure_check = ExposureCheckMode::kNone;
  if (exposure_check != ExposureCheckMode::kNone) {
    THINSLAB_RETURN_IF_ERROR(CheckBracketExposures(bracket, options, &info->exposure_check).WithContext(session_dir));
  }
  if (exposure_check == ExposureCheckMode::kUseMeasured) {
    const ExposureCheck& check = info->exposure_check;
    for (HdrFrame& f : bracket) {
      for (size_t e = 0; e < check.reported_us.size(); ++e) {
        if (f.exposure_time_us == check.reported_us[e] && check.measured_over_reported[e] > 0) {
          f.exposure_time_us *= check.measured_over_reported[e];
          break;
        }
      }
    }
    info->merged_with_measured_exposures = true;
  }
  THINSLAB_RETURN_IF_ERROR(MergeExposureBracket(bracket, options, hdr).WithContext(session_dir));
  info->num_frames = static_cast<int>(frames.size());
  info->num_exposures = static_cast<int>(exposures.size());
  info->num_darks = darks.num_frames;
  info->exposures_us.assign(exposures.begin(), exposures.end());
  return Status::Ok();
}

}  // namespace thinslab
