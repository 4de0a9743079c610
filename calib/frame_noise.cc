// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/frame_noise.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <sstream>
#include <tuple>

#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"

namespace thinslab {

namespace {

constexpr double kMadToSigma = 1.4826;        // sigma of a Gaussian / its median absolute deviation.
constexpr int64_t kMinSamples = 200;
constexpr int64_t kSamplesPerFrame = 250000;  // Enough for 64 levels of ~4000 samples.
constexpr size_t kMaxFrames = 8;
constexpr int64_t kMaxLevels = 64;

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

void NoiseSamples::AddSingleFrame(const Image& frame, double saturation, int stride) {
  const int w = frame.width(), h = frame.height();
  static constexpr float kMask[3][3] = {{1, -2, 1}, {-2, 4, -2}, {1, -2, 1}};
  for (int y = 1; y + 1 < h; y += stride) {
    for (int x = 1; x + 1 < w; x += stride) {
      float r = 0, sum = 0;
      bool clipped = false;
      for (int j = -1; j <= 1; ++j) {
        for (int i = -1; i <= 1; ++i) {
          const float v = frame.at(x + i, y + j);
          clipped |= v >= saturation - 0.5;
          r += kMask[j + 1][i + 1] * v;
          sum += v;
        }
      }
      if (clipped) continue;
      level.push_back(sum / 9);
      residual.push_back(r / 6);  // The mask's squared coefficients sum to 36.
    }
  }
}

Status FitNoiseModel(const NoiseSamples& samples, const std::string& method, bool integer_frames,
                     FrameNoiseModel* model) {
  const int64_t n = static_cast<int64_t>(samples.level.size());
  if (n < kMinSamples) {
    return Status::Error("noise estimate (" + method + "): only " + std::to_string(n) +
                         " unsaturated pixels to estimate from (at least " + std::to_string(kMinSamples) + ")");
  }
  std::vector<int64_t> order(n);
  for (int64_t i = 0; i < n; ++i) order[i] = i;
  std::sort(order.begin(), order.end(), [&](int64_t a, int64_t b) { return samples.level[a] < samples.level[b]; });
  // Narrow bins: a bin's median |r| of a mixture of variances falls below the mixture's mean
  // variance, so a bin spanning 0..2x its level would bias the floor low.
  const int bins = static_cast<int>(std::clamp<int64_t>(n / 1000, 1, kMaxLevels));
  std::vector<double> bin_level, bin_var, bin_count;
  std::vector<float> abs_residual;
  double max_abs_level = 0;
  for (int b = 0; b < bins; ++b) {
    const int64_t i0 = n * b / bins, i1 = n * (b + 1) / bins;
    abs_residual.clear();
    for (int64_t i = i0; i < i1; ++i) abs_residual.push_back(std::abs(samples.residual[order[i]]));
    // The bin's median level: the top bin may reach far into a bright spike, whose mean would
    // give that bin a lever that tilts the whole line.
    const double level = samples.level[order[(i0 + i1) / 2]];
    max_abs_level = std::max<double>({max_abs_level, std::abs(samples.level[order[i0]]), std::abs(samples.level[order[i1 - 1]])});
    bin_level.push_back(level);
    bin_var.push_back(std::pow(kMadToSigma * MedianOf(&abs_residual), 2));
    bin_count.push_back(static_cast<double>(i1 - i0));
  }
  // Weighted least squares of var = a + b * max(level, 0) with weights count / var^2: each bin's
  // variance estimate has a relative error ~ sqrt(2 / count), whatever the scale.
  double positive_var = 0;
  for (double v : bin_var) positive_var = std::max(positive_var, v);
  const double tiny = positive_var * 1e-12;
  double sw = 0, sx = 0, sy = 0, sxx = 0, sxy = 0;
  std::vector<double> weight(bins);
  for (int b = 0; b < bins; ++b) {
    weight[b] = bin_count[b] / std::pow(std::max(bin_var[b], tiny), 2);
    const double x = std::max(bin_level[b], 0.0);
    sw += weight[b];
    sx += weight[b] * x;
    sy += weight[b] * bin_var[b];
    sxx += weight[b] * x * x;
    sxy += weight[b] * x * bin_var[b];
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
  if (integer_frames) floor = std::max(floor, 1.0 / 12);  // Quantisation of integer values.
  if (floor <= 0) {
    // Noise-free frames (a renderer's converged output): a floor 1e-6 of the largest level keeps
    // the variances positive without making the data look noisy; scale-equivariant.
    floor = max_abs_level > 0 ? std::pow(1e-6 * max_abs_level, 2) : 1.0;
  }
  model->variance_floor = floor;
  model->variance_per_value = slope;
  model->method = method;
  model->samples = n;
  model->levels = bins;
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
