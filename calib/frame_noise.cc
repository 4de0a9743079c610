// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/frame_noise.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <numeric>
#include <random>
#include <sstream>
#include <tuple>

#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/session_io.h"

namespace thinslab {

namespace {

constexpr double kMadToSigma = 1.4826;        // sigma of a Gaussian / its median absolute deviation.
constexpr int64_t kMinSamples = 200;
constexpr int64_t kSamplesPerFrame = 250000;  // Enough for 64 levels of ~4000 samples.
constexpr size_t kMaxFrames = 8;
constexpr int64_t kMaxLevels = 64;
// Weak-texture selection of single-frame samples (after Liu, Tanaka and Okutomi 2013, who select
// patches by their gradients; here the mean squared residual of the 5 x 5 residuals around a
// sample, which ignores the linear structure the residual cancels).
constexpr double kWeakTextureQuantile = 0.99;
constexpr int kWeakTextureIterations = 4;

int StrideFor(const Image& frame) {
  const double pixels = static_cast<double>(frame.width()) * frame.height();
  return std::max(1, static_cast<int>(std::ceil(std::sqrt(pixels / kSamplesPerFrame))));
}

double MedianOf(std::vector<float>* v) {
  if (v->empty()) return 0;
  const size_t mid = v->size() / 2;
  std::nth_element(v->begin(), v->begin() + mid, v->end());
  return (*v)[mid];
}

}  // namespace

double FrameNoiseModel::gain_e_per_dn() const {
  return variance_per_value > 0 ? 1.0 / variance_per_value : std::numeric_limits<double>::max();
}

double FrameNoiseModel::read_noise_dn(double fallback) const {
  return variance_floor.has_value() ? std::sqrt(*variance_floor) : fallback;
}

std::string FrameNoiseModel::Describe() const {
  std::ostringstream out;
  out.precision(4);
  out << "noise " << method << ": var(v) = ";
  if (variance_floor.has_value()) {
    out << *variance_floor;
  } else {
    out << "read^2 (dark frames or default)";
  }
  out << " + " << variance_per_value << " * v";
  if (estimated()) out << " (" << samples << " samples, " << levels << " levels)";
  return out.str();
}

nlohmann::ordered_json FrameNoiseModel::ToJson() const {
  nlohmann::ordered_json j;
  j["method"] = method;
  j["variance_floor"] = variance_floor.has_value() ? nlohmann::ordered_json(*variance_floor) : nullptr;
  j["variance_per_value"] = variance_per_value;
  j["samples"] = samples;
  j["levels"] = levels;
  return j;
}

void NoiseSamples::AddRepeatedPair(const Image& a, const Image& b, double saturation, int stride) {
  const float inv_sqrt2 = static_cast<float>(1 / std::sqrt(2.0));
  for (int y = 0; y < a.height(); y += stride) {
    for (int x = 0; x < a.width(); x += stride) {
      const float va = a.at(x, y), vb = b.at(x, y);
      if (va >= saturation - 0.5 || vb >= saturation - 0.5) continue;
      level.push_back(0.5f * (va + vb));
      residual.push_back((va - vb) * inv_sqrt2);
    }
  }
}

namespace {

// Immerkaer's residual at (x, y) (interior pixels) and whether its 3 x 3 window touches a clipped
// pixel; `sum` gets the window's sum.
float ImmerkaerResidual(const Image& frame, int x, int y, double saturation, bool* clipped, float* sum) {
  static constexpr float kMask[3][3] = {{1, -2, 1}, {-2, 4, -2}, {1, -2, 1}};
  float r = 0, s = 0;
  bool c = false;
  for (int j = -1; j <= 1; ++j) {
    for (int i = -1; i <= 1; ++i) {
      const float v = frame.at(x + i, y + j);
      c |= v >= saturation - 0.5;
      r += kMask[j + 1][i + 1] * v;
      s += v;
    }
  }
  *clipped = c;
  *sum = s;
  return r / 6;  // The mask's squared coefficients sum to 36.
}

}  // namespace

void NoiseSamples::AddSingleFrame(const Image& frame, double saturation, int stride) {
  const int w = frame.width(), h = frame.height();
  // The residual and the 3 x 3 mean at every interior pixel, once: each sample's texture measure
  // reads the residuals of its whole neighbourhood.
  Image residual_image(w, h, 0.0f), mean_image(w, h, 0.0f);
  std::vector<uint8_t> clipped_at(static_cast<size_t>(w) * h, 1);
  for (int y = 1; y + 1 < h; ++y) {
    for (int x = 1; x + 1 < w; ++x) {
      bool clipped = false;
      float sum = 0;
      residual_image.at(x, y) = ImmerkaerResidual(frame, x, y, saturation, &clipped, &sum);
      mean_image.at(x, y) = sum / 9;
      clipped_at[static_cast<size_t>(y) * w + x] = clipped;
    }
  }
  const int r = kTextureRadius;
  for (int y = 1 + r; y + 1 + r < h; y += stride) {
    for (int x = 1 + r; x + 1 + r < w; x += stride) {
      bool clipped = false;
      double energy = 0;
      for (int j = -r; j <= r && !clipped; ++j) {
        for (int i = -r; i <= r; ++i) {
          clipped |= clipped_at[static_cast<size_t>(y + j) * w + x + i] != 0;
          energy += Sqr(residual_image.at(x + i, y + j));
        }
      }
      if (clipped) continue;
      level.push_back(mean_image.at(x, y));
      residual.push_back(residual_image.at(x, y));
      texture.push_back(static_cast<float>(energy / Sqr(2 * r + 1)));
    }
  }
}

namespace {

struct NoiseLine {
  double floor = 0, slope = 0, max_abs_level = 0;
  int bins = 0;
};

// The Poisson-Gaussian line through the samples `use` (indices into `samples`), each bin's
// robust variance multiplied by `variance_scale`.
NoiseLine FitLine(const NoiseSamples& samples, std::vector<int64_t> use, double variance_scale) {
  NoiseLine line;
  const int64_t n = static_cast<int64_t>(use.size());
  std::sort(use.begin(), use.end(), [&](int64_t a, int64_t b) {
    return samples.level[a] < samples.level[b] || (samples.level[a] == samples.level[b] && a < b);
  });
  // Narrow bins: a bin's median |r| of a mixture of variances falls below the mixture's mean
  // variance, so a bin spanning 0..2x its level would bias the floor low.
  const int bins = static_cast<int>(std::clamp<int64_t>(n / 1000, 1, kMaxLevels));
  std::vector<double> bin_level, bin_var, bin_count;
  std::vector<float> abs_residual;
  for (int b = 0; b < bins; ++b) {
    const int64_t i0 = n * b / bins, i1 = n * (b + 1) / bins;
    abs_residual.clear();
    for (int64_t i = i0; i < i1; ++i) abs_residual.push_back(std::abs(samples.residual[use[i]]));
    // The bin's median level: the top bin may reach far into a bright spike, whose mean would
    // give that bin a lever that tilts the whole line.
    const double level = samples.level[use[(i0 + i1) / 2]];
    line.max_abs_level =
        std::max<double>({line.max_abs_level, std::abs(samples.level[use[i0]]), std::abs(samples.level[use[i1 - 1]])});
    bin_level.push_back(level);
    bin_var.push_back(variance_scale * std::pow(kMadToSigma * MedianOf(&abs_residual), 2));
    bin_count.push_back(static_cast<double>(i1 - i0));
  }
  // Weighted least squares of var = a + b * max(level, 0) with weights count / var^2: each bin's
  // variance estimate has a relative error ~ sqrt(2 / count), whatever the scale.
  double positive_var = 0;
  for (double v : bin_var) positive_var = std::max(positive_var, v);
  const double tiny = positive_var * 1e-12;
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (int b = 0; b < bins; ++b) {
    const double weight = bin_count[b] / std::pow(std::max(bin_var[b], tiny), 2);
    const double x = std::max(bin_level[b], 0.0);
    sw += weight;
    sx += weight * x;
    sy += weight * bin_var[b];
    sxx += weight * x * x;
    sxy += weight * x * bin_var[b];
  }
  const double det = sw * sxx - sx * sx;
  double floor = positive_var > 0 ? sy / sw : 0, slope = 0;
  if (positive_var > 0 && bins >= 2 && det > 1e-12 * sw * sxx) {
    slope = (sw * sxy - sx * sy) / det;
    floor = (sy - slope * sx) / sw;
  }
  if (positive_var > 0 && slope < 0) {  // Noise that falls with the signal: no shot-noise term.
    slope = 0;
    floor = sy / sw;
  }
  if (positive_var > 0 && floor < 0) {  // Pure shot noise through the origin.
    floor = 0;
    slope = sxx > 0 ? sxy / sxx : 0;
  }
  line.floor = floor;
  line.slope = slope;
  line.bins = bins;
  return line;
}

// What the texture measure of a single-frame sample does on pure noise (unit variance,
// independent pixels; by simulation, once): the quantile below which a sample counts as weak
// texture, and the factor by which keeping only those lowers the residual's robust variance (the
// measure includes the sample's own residual).
struct PureNoiseTexture {
  double threshold = 0;        // kWeakTextureQuantile of texture / variance.
  double variance_factor = 1;  // (MAD of the kept residuals / MAD of all)^2.
};

const PureNoiseTexture& PureNoise() {
  static const PureNoiseTexture constants = [] {
    constexpr int kSize = 384;
    std::mt19937_64 rng(20261206);
    std::normal_distribution<double> normal(0, 1);
    Image frame(kSize, kSize);
    for (float& v : frame.data()) v = static_cast<float>(normal(rng));
    NoiseSamples samples;
    samples.AddSingleFrame(frame, std::numeric_limits<double>::infinity(), 1);
    PureNoiseTexture c;
    std::vector<float> texture = samples.texture;
    const size_t q = static_cast<size_t>(kWeakTextureQuantile * (texture.size() - 1));
    std::nth_element(texture.begin(), texture.begin() + q, texture.end());
    c.threshold = texture[q];
    std::vector<float> all, kept;
    for (size_t i = 0; i < samples.residual.size(); ++i) {
      all.push_back(std::abs(samples.residual[i]));
      if (samples.texture[i] <= c.threshold) kept.push_back(std::abs(samples.residual[i]));
    }
    c.variance_factor = std::pow(MedianOf(&kept) / MedianOf(&all), 2);
    return c;
  }();
  return constants;
}

}  // namespace

Status FitNoiseModel(const NoiseSamples& samples, const std::string& method, bool integer_frames,
                     FrameNoiseModel* model) {
  const int64_t n = static_cast<int64_t>(samples.level.size());
  if (n < kMinSamples) {
    return Status::Error("noise estimate (" + method + "): only " + std::to_string(n) +
                         " unsaturated pixels to estimate from (at least " + std::to_string(kMinSamples) + ")");
  }
  std::vector<int64_t> all(n);
  std::iota(all.begin(), all.end(), 0);
  NoiseLine line = FitLine(samples, all, 1.0);
  int64_t used = n;
  // Single frames: keep the samples whose neighbourhood looks like noise at the current line (its
  // mean squared residual below the pure-noise quantile), refit, and repeat while the kept set
  // changes. Structure at the scale of a pixel (a sharp dot image, an edge) inflates the residual
  // where it is; texture everywhere cannot be told from noise in one frame.
  if (samples.texture.size() == samples.level.size()) {
    const PureNoiseTexture& pure = PureNoise();
    for (int iteration = 0; iteration < kWeakTextureIterations; ++iteration) {
      std::vector<int64_t> weak;
      for (int64_t i = 0; i < n; ++i) {
        const double variance = line.floor + line.slope * std::max(0.0f, samples.level[i]);
        if (samples.texture[i] <= pure.threshold * variance) weak.push_back(i);
      }
      if (static_cast<int64_t>(weak.size()) < kMinSamples || static_cast<int64_t>(weak.size()) == used) break;
      used = static_cast<int64_t>(weak.size());
      line = FitLine(samples, std::move(weak), 1.0 / pure.variance_factor);
    }
  }
  double floor = line.floor;
  if (integer_frames) floor = std::max(floor, 1.0 / 12);  // Quantisation of integer values.
  if (floor <= 0) {
    // Noise-free frames (a renderer's converged output): a floor 1e-6 of the largest level keeps
    // the variances positive without making the data look noisy; scale-equivariant.
    floor = line.max_abs_level > 0 ? std::pow(1e-6 * line.max_abs_level, 2) : 1.0;
  }
  model->variance_floor = floor;
  model->variance_per_value = line.slope;
  model->method = method;
  model->samples = used;
  model->levels = line.bins;
  return Status::Ok();
}

Status ResolveFrameNoise(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                         FrameNoiseModel* model) {
  *model = FrameNoiseModel();
  if (camera.gain_e_per_dn > 0) {
    model->variance_per_value = 1.0 / camera.gain_e_per_dn;
    if (camera.read_noise_dn.has_value()) {
      model->variance_floor = std::max(*camera.read_noise_dn * *camera.read_noise_dn,
                                       camera.linear_frames() ? std::numeric_limits<double>::min() : 1.0 / 12);
      model->method = "declared";
    } else {
      model->method = "declared_gain";
    }
    return Status::Ok();
  }
  // Frames of one light state and exposure, in manifest order.
  using Key = std::tuple<std::string, std::string, std::string, bool, double, double, double, double>;
  std::map<Key, std::vector<const FrameRecord*>> states;
  std::vector<const FrameRecord*> usable;
  for (const FrameRecord& f : session.frames) {
    if (f.camera_id != camera.id || f.status == FrameStatus::kFailed) continue;
    usable.push_back(&f);
    const Eigen::Vector2d dot = f.light.dot_px.value_or(Eigen::Vector2d(-1, -1));
    states[Key(f.kind, f.sample_state, f.light.projector_pattern, f.light.laser_on, dot.x(), dot.y(),
               f.exposure_time_us, f.gain_db)]
        .push_back(&f);
  }
  const double saturation = camera.saturation_dn - camera.black_level_dn;
  const bool integer = !camera.linear_frames() && camera.bit_depth <= 16;
  NoiseSamples samples;
  size_t pairs = 0;
  // Repeated dark frames alone span no signal: they give the floor but not the shot-noise slope
  // (which came out 0: a single float exposure per light state with two darks had a sigma_tau 20x
  // too small). Without a repeated light state the single-frame estimate is used instead.
  bool light_pair = false;
  for (const auto& [key, frames] : states) {
    if (frames.size() >= 2 && std::get<0>(key) != "dark") light_pair = true;
  }
  for (const auto& [key, frames] : states) {
    if (frames.size() < 2 || pairs >= kMaxFrames || !light_pair) continue;
    Image a, b;
    THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *frames[0], &a));
    THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *frames[1], &b));
    samples.AddRepeatedPair(a, b, saturation, StrideFor(a));
    ++pairs;
  }
  std::string method = "repeated_frames";
  if (samples.level.size() < static_cast<size_t>(kMinSamples)) {
    samples = NoiseSamples();
    method = "single_frame_residual";
    const size_t count = std::min(usable.size(), kMaxFrames);
    for (size_t k = 0; k < count; ++k) {
      Image frame;
      THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *usable[k * usable.size() / count], &frame));
      samples.AddSingleFrame(frame, saturation, StrideFor(frame));
    }
  }
  if (samples.level.size() < static_cast<size_t>(kMinSamples)) {
    // Integer frames keep the old default (gain 1, read noise from the dark frames or 1 DN): a DN
    // is a physical unit of the camera. Linear frames have no such unit, so any default would make
    // every sigma depend on the scale their writer chose (issue #23); unless each frame brings its
    // own variance file, refuse and say what to declare.
    const bool every_frame_has_variance =
        std::all_of(usable.begin(), usable.end(), [](const FrameRecord* f) { return !f->variance_file.empty(); });
    if (camera.linear_frames() && !every_frame_has_variance) {
      return Status::Error(JoinPath(session_dir, kSessionManifestName) + ": camera '" + camera.id +
                           "': linear frames with no declared noise, and only " + std::to_string(samples.level.size()) +
                           " unsaturated pixels to estimate it from (at least " + std::to_string(kMinSamples) +
                           "); declare cameras[].gain_e_per_dn and read_noise_dn in the frames' value units, or give "
                           "each frame a variance_file");
    }
    return Status::Ok();  // "default".
  }
  return FitNoiseModel(samples, method, integer, model)
      .WithContext(JoinPath(session_dir, kSessionManifestName) + ": camera '" + camera.id + "'");
}

}  // namespace thinslab
