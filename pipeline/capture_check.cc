// SPDX-License-Identifier: Apache-2.0
#include "thinslab/pipeline/capture_check.h"

#include <algorithm>
#include <cmath>
#include <iomanip>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <tuple>

#include "thinslab/calib/dot_geometry.h"
#include "thinslab/calib/exposure_check.h"
#include "thinslab/calib/frame_noise.h"
#include "thinslab/calib/hdr_merge.h"
#include "thinslab/calib/session_calibration.h"
#include "thinslab/core/camera_model.h"
#include "thinslab/core/duration_text.h"
#include "thinslab/core/file.h"
#include "thinslab/core/frame_io.h"
#include "thinslab/core/math.h"
#include "thinslab/core/session_recovery.h"
#include "thinslab/core/statistics.h"
#include "thinslab/fit/dmf_processing.h"

namespace thinslab {

const char* CheckSeverityName(CheckSeverity severity) {
  switch (severity) {
    case CheckSeverity::kNote:
      return "note";
    case CheckSeverity::kWarning:
      return "warning";
    case CheckSeverity::kRetake:
      return "retake";
  }
  return "unknown";
}

bool CaptureCheckOptions::Check(std::string* error) const {
  std::ostringstream msg;
  auto fraction = [&](const char* name, double v, bool allow_zero) {
    if (msg.tellp() > 0) return;
    if (!std::isfinite(v) || v < 0 || v > 1 || (!allow_zero && v == 0)) {
      msg << "CaptureCheckOptions::" << name << " = " << v << ": expected a fraction in " << (allow_zero ? "[0" : "(0")
          << ", 1]";
    }
  };
  fraction("max_saturated_fraction", max_saturated_fraction, true);
  fraction("min_range_fraction", min_range_fraction, true);
  fraction("max_dark_fraction", max_dark_fraction, false);
  fraction("max_moved_fraction", max_moved_fraction, true);
  fraction("max_brightness_change", max_brightness_change, false);
  fraction("min_dots_found_fraction", min_dots_found_fraction, true);
  fraction("min_lit_fraction", min_lit_fraction, true);
  if (msg.tellp() == 0) {
    if (!(min_peak_sigmas > 0) || !std::isfinite(min_peak_sigmas)) {
      msg << "CaptureCheckOptions::min_peak_sigmas = " << min_peak_sigmas << ": expected > 0";
    } else if (!(max_spot_offset_mm > 0) || !std::isfinite(max_spot_offset_mm)) {
      msg << "CaptureCheckOptions::max_spot_offset_mm = " << max_spot_offset_mm << ": expected > 0";
    } else if (max_examples < 1) {
      msg << "CaptureCheckOptions::max_examples = " << max_examples << ": expected >= 1";
    } else if (std::string pair_error; !pair.Check(&pair_error)) {
      msg << pair_error;
    }
  }
  *error = msg.str();
  return error->empty();
}

std::string CaptureCheck::verdict() const {
  bool warned = false;
  for (const CheckFinding& f : findings) {
    if (f.severity == CheckSeverity::kRetake) return "retake";
    warned = warned || f.severity == CheckSeverity::kWarning;
  }
  return warned ? "usable" : "good";
}

namespace {

std::string Fixed(double v, int digits) {
  std::ostringstream s;
  s << std::fixed << std::setprecision(digits) << v;
  return s.str();
}

std::string Percent(double fraction) { return Fixed(100 * fraction, fraction < 0.01 ? 3 : 1) + " %"; }

std::string FrameList(const std::vector<int>& frames) {
  std::string s;
  for (size_t i = 0; i < frames.size(); ++i) s += (i ? ", " : "") + std::to_string(frames[i]);
  return s;
}

}  // namespace

std::string CaptureCheck::Describe() const {
  std::ostringstream out;
  out << "check: " << capture << " (" << session_kind << ", " << frames << " frames)\n";
  out << "  noise: " << noise << "; response: " << (response.empty() ? "linear" : response) << "\n";
  for (const CheckedKind& k : kinds) {
    out << "  " << k.label << ": " << k.states << " state(s), " << k.frames << " frames, " << k.exposures
        << " exposure(s) " << DurationText(k.shortest_us)
        << (k.exposures > 1 ? " .. " + DurationText(k.longest_us) : "");
    if (k.lit > 0) {
      out << "; saturated at the shortest: " << k.saturated_states << " (worst " << Percent(k.worst_saturated_fraction)
          << " of a frame); peak at the longest: median " << Fixed(k.median_peak_sigmas, 0) << " sigma, "
          << k.underexposed_states << " below threshold, brightest " << Percent(k.max_range_fraction)
          << " of the range";
    }
    if (k.frame_pairs > 0) {
      out << "; " << k.frame_pairs << " frame pair(s): worst " << Percent(k.worst_moved_fraction)
          << " pixels differing, worst brightness change " << Percent(k.worst_brightness_change);
    }
    out << "\n";
  }
  for (const std::string& line : geometry) out << "  geometry: " << line << "\n";
  for (const CheckFinding& f : findings) {
    out << "  " << CheckSeverityName(f.severity) << " [" << f.topic << "]: " << f.message << "\n";
  }
  int retake = 0, warnings = 0;
  for (const CheckFinding& f : findings) {
    retake += f.severity == CheckSeverity::kRetake;
    warnings += f.severity == CheckSeverity::kWarning;
  }
  out << "verdict: " << verdict();
  if (retake > 0)
    out << " (" << retake << " reason(s) to re-take before the sample leaves the rig)";
  else if (warnings > 0)
    out << " (" << warnings << " warning(s); the fits will run)";
  out << "\n";
  return out.str();
}

nlohmann::ordered_json CaptureCheck::ToJson() const {
  nlohmann::ordered_json j;
  j["format"] = "thinslab-capture-check";
  j["capture"] = capture;
  j["session_kind"] = session_kind;
  j["frames"] = frames;
  j["verdict"] = verdict();
  j["noise"] = noise;
  j["response"] = response;
  j["kinds"] = nlohmann::ordered_json::array();
  for (const CheckedKind& k : kinds) {
    j["kinds"].push_back({{"label", k.label},
                          {"states", k.states},
                          {"frames", k.frames},
                          {"exposures", k.exposures},
                          {"shortest_us", k.shortest_us},
                          {"longest_us", k.longest_us},
                          {"lit_states", k.lit},
                          {"saturated_states", k.saturated_states},
                          {"worst_saturated_fraction", k.worst_saturated_fraction},
                          {"underexposed_states", k.underexposed_states},
                          {"median_peak_sigmas", k.median_peak_sigmas},
                          {"max_range_fraction", k.max_range_fraction},
                          {"frame_pairs", k.frame_pairs},
                          {"worst_moved_fraction", k.worst_moved_fraction},
                          {"worst_brightness_change", k.worst_brightness_change}});
  }
  j["geometry"] = geometry;
  j["findings"] = nlohmann::ordered_json::array();
  for (const CheckFinding& f : findings) {
    j["findings"].push_back({{"severity", CheckSeverityName(f.severity)},
                             {"topic", f.topic},
                             {"message", f.message},
                             {"frames", f.frames}});
  }
  return j;
}

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// What makes frames show the same light: everything but the exposure (and the repeat).
using StateKey = std::tuple<std::string, std::string, std::string, std::string, bool, double, double, bool>;

StateKey KeyOf(const FrameRecord& f) {
  const Eigen::Vector2d dot = f.light.dot_px.value_or(Eigen::Vector2d(-1, -1));
  return {f.camera_id,      f.kind,  f.sample_state, f.light.projector_pattern,
          f.light.laser_on, dot.x(), dot.y(),        f.validation};
}

std::string KindLabel(const FrameRecord& f) {
  return f.kind + ", " + f.sample_state + (f.validation ? ", validation" : "");
}

std::string StateLabel(const FrameRecord& f) {
  std::string label = "'" + f.kind + "' (" + f.sample_state;
  if (f.light.dot_px) {
    label += ", dot (" + Fixed(f.light.dot_px->x(), 1) + ", " + Fixed(f.light.dot_px->y(), 1) + ")";
  } else if (!f.light.projector_pattern.empty()) {
    label += ", pattern " + f.light.projector_pattern;
  }
  if (f.light.laser_on && f.kind != "laser") label += ", laser on";
  if (f.validation) label += ", validation";
  return label + ")";
}

// Everything about one camera that every state of it uses.
struct CameraContext {
  CameraInfo camera;  // With rig.json applied.
  SessionCalibration calibration;
  FrameNoiseModel noise;
  double saturation = kInf;          // Black-subtracted raw level at which a value clips.
  std::map<double, Image> dark_raw;  // Mean dark frame per exposure, raw black-subtracted.
  std::map<double, Image> dark_linear;
  std::map<double, int> dark_count;
};

// The (2 radius + 1)^2 box mean's largest value and where.
double BoxMax(const Image& image, int radius, Eigen::Vector2i* where) {
  double best = -kInf;
  for (int y = radius; y < image.height() - radius; ++y) {
    for (int x = radius; x < image.width() - radius; ++x) {
      double sum = 0;
      for (int dy = -radius; dy <= radius; ++dy) {
        for (int dx = -radius; dx <= radius; ++dx) sum += image.at(x + dx, y + dy);
      }
      if (sum > best) {
        best = sum;
        *where = Eigen::Vector2i(x, y);
      }
    }
  }
  return best / Sqr(2 * radius + 1);
}

double BoxMean(const Image& image, int x, int y, int radius) {
  double sum = 0;
  int n = 0;
  for (int yy = std::max(0, y - radius); yy <= std::min(image.height() - 1, y + radius); ++yy) {
    for (int xx = std::max(0, x - radius); xx <= std::min(image.width() - 1, x + radius); ++xx) {
      sum += image.at(xx, yy);
      ++n;
    }
  }
  return n > 0 ? sum / n : 0;
}

// One state's frames loaded: raw (black-subtracted) and linear dark-subtracted, ascending exposure.
struct LoadedFrame {
  const FrameRecord* record;
  Image raw, signal;
  Image variance;  // Of `signal`: the noise model at the raw level (glow included) plus the dark's.
};

// Per pixel the longest unsaturated exposure's signal / exposure (an HDR merge without weights):
// where the laser spot is, whatever the bracket.
Image RadianceOf(const std::vector<LoadedFrame>& frames, double saturation) {
  Image radiance(frames.front().raw.width(), frames.front().raw.height(), 0.0f);
  std::vector<bool> set(radiance.data().size(), false);
  for (auto it = frames.rbegin(); it != frames.rend(); ++it) {
    for (size_t i = 0; i < radiance.data().size(); ++i) {
      if (set[i] || (it->raw.data()[i] >= saturation - 0.5 && it != std::prev(frames.rend()))) continue;
      radiance.data()[i] = static_cast<float>(it->signal.data()[i] / it->record->exposure_time_us);
      set[i] = true;
    }
  }
  return radiance;
}

struct PairRecord {
  std::string kind, state;
  double t_a = 0, t_b = 0;
  int frame_a = 0, frame_b = 0;
  FramePairComparison comparison;
  double normalized() const { return comparison.ratio / (t_b / t_a); }
};

struct StateRecord {
  std::string kind, state;
  int first_frame = 0;
  double saturated_fraction = 0;
  bool lit = false;
  double peak_sigmas = 0, range_fraction = 0;
};

class CaptureChecker {
 public:
  CaptureChecker(const std::string& session_dir, const Session& session, const CaptureCheckOptions& options,
                 CaptureCheck* check)
      : dir_(session_dir), session_(session), options_(options), check_(check) {}

  Status Run(int journaled) {
    CheckCompleteness(journaled);
    for (const CameraInfo& camera : session_.rig.cameras) {
      CameraContext context;
      THINSLAB_RETURN_IF_ERROR(PrepareCamera(camera, &context));
      if (check_->noise.empty()) {
        check_->noise = context.noise.Describe();
        check_->response = context.calibration.response_file;
      }
      THINSLAB_RETURN_IF_ERROR(CheckStates(context));
      THINSLAB_RETURN_IF_ERROR(CheckDots(context));
    }
    Summarise();
    return Status::Ok();
  }

 private:
  void Add(CheckSeverity severity, const std::string& topic, const std::string& message, std::vector<int> frames = {}) {
    if (static_cast<int>(frames.size()) > options_.max_examples) frames.resize(options_.max_examples);
    check_->findings.push_back({severity, topic, message, std::move(frames)});
  }

  void CheckCompleteness(int journaled) {
    const CaptureCompleteness completeness = AssessCapture(session_, journaled);
    if (!completeness.complete()) {
      Add(CheckSeverity::kRetake, "incomplete",
          "the acquisition did not finish: " + completeness.Describe() +
              "; resume it (`thinslab acquire <same options> --resume`) before the sample leaves the rig");
    }
    std::vector<int> failed, retried;
    for (const FrameRecord& f : session_.frames) {
      if (f.status == FrameStatus::kFailed) failed.push_back(f.index);
      if (f.status == FrameStatus::kRetried) retried.push_back(f.index);
    }
    if (!failed.empty()) {
      Add(CheckSeverity::kWarning, "failed_frames",
          std::to_string(failed.size()) + " frame(s) failed (e.g. " +
              FrameList({failed.begin(), failed.begin() + std::min<size_t>(failed.size(), options_.max_examples)}) +
              "); the fits use the others",
          failed);
    }
    if (!retried.empty()) {
      Add(CheckSeverity::kNote, "failed_frames",
          std::to_string(retried.size()) + " frame(s) needed a retry; all were captured", retried);
    }
  }

  Status PrepareCamera(const CameraInfo& manifest_camera, CameraContext* context) {
    context->camera = manifest_camera;
    SessionCalibrationOptions calibration_options;
    calibration_options.response_path = options_.response_path;
    THINSLAB_RETURN_IF_ERROR(
        LoadSessionCalibration(dir_, calibration_options, &context->camera, &context->calibration));
    THINSLAB_RETURN_IF_ERROR(ResolveFrameNoise(dir_, session_, context->camera, &context->noise));
    if (context->noise.method == "default") {
      Add(CheckSeverity::kNote, "noise",
          "camera '" + manifest_camera.id +
              "': the noise could not be estimated (no repeated frames, too few pixels) "
              "and the manifest declares no gain: sigma thresholds assume gain 1 and 1 DN read noise");
    }
    const CameraInfo& camera = context->camera;
    if (std::isfinite(camera.saturation_dn) && camera.saturation_dn > 0) {
      context->saturation = camera.saturation_dn - camera.black_level_dn;
    }
    std::map<double, std::vector<const FrameRecord*>> darks;
    for (const FrameRecord* f : session_.UsableFrames("dark")) {
      if (f->camera_id == camera.id) darks[f->exposure_time_us].push_back(f);
    }
    for (const auto& [exposure, frames] : darks) {
      Image sum;
      std::vector<Image> raws;
      for (const FrameRecord* f : frames) {
        Image raw;
        THINSLAB_RETURN_IF_ERROR(LoadFrame(dir_, session_, *f, &raw));
        if (sum.empty()) sum = Image(raw.width(), raw.height(), 0.0f);
        for (size_t i = 0; i < raw.data().size(); ++i) sum.data()[i] += raw.data()[i] / frames.size();
        if (raws.size() < 2) raws.push_back(std::move(raw));
      }
      // The read noise, where the manifest and the data leave it open, from the shortest
      // exposure's darks as the HDR merge takes it.
      if (!context->noise.variance_floor.has_value()) {
        if (raws.size() >= 2) {
          context->noise.variance_floor = Sqr(DarkFrameReadNoise(raws, context->calibration.response_or_null()));
        } else {
          // One dark: its fine-scale noise (Immerkaer's residual, calib/frame_noise.h), not its
          // spread, which a display's glow or a fixed pattern would inflate.
          NoiseSamples samples;
          samples.AddSingleFrame(raws.front(), context->saturation, 1);
          if (samples.residual.size() >= 200) {
            const double sigma = RobustSigma(samples.residual, 0.0);
            context->noise.variance_floor = std::max(Sqr(sigma), 0.25 * 0.25);
          }
        }
      }
      Image linear = sum;
      LinearizeFrame(context->calibration.response_or_null(), &linear);
      context->dark_raw[exposure] = sum;
      context->dark_linear[exposure] = linear;
      context->dark_count[exposure] = static_cast<int>(frames.size());
    }
    if (!context->noise.variance_floor.has_value()) {
      context->noise.variance_floor = Sqr(context->noise.read_noise_dn(1.0));
      Add(CheckSeverity::kNote, "noise",
          "camera '" + manifest_camera.id + "': no dark frames and no declared read noise: sigma thresholds assume " +
              Fixed(*context->noise.variance_floor, 2) + " (frame units squared) at zero signal");
    }
    CheckDarkLevel(*context, darks);
    return Status::Ok();
  }

  void CheckDarkLevel(const CameraContext& context, const std::map<double, std::vector<const FrameRecord*>>& darks) {
    if (!std::isfinite(context.saturation) || context.dark_raw.empty()) return;
    const auto& [exposure, dark] = *context.dark_raw.rbegin();
    const double level = Quantile(dark.data(), 0.99) / context.saturation;
    if (level > options_.max_dark_fraction) {
      Add(CheckSeverity::kWarning, "dark",
          "the dark frame at " + DurationText(exposure) + " fills " + Percent(level) +
              " of the range (99th percentile): a display's black glow or stray light takes the range and adds "
              "its shot noise to every lit frame; darken the room or the display (a shorter longest exposure "
              "loses more signal than glow: docs/acquisition.md, \"Exposure planning\")",
          {darks.at(exposure).front()->index});
    }
  }

  Status LoadState(const CameraContext& context, std::vector<const FrameRecord*> records,
                   std::vector<LoadedFrame>* frames) {
    std::sort(records.begin(), records.end(), [](const FrameRecord* a, const FrameRecord* b) {
      return std::tie(a->exposure_time_us, a->index) < std::tie(b->exposure_time_us, b->index);
    });
    frames->clear();
    for (const FrameRecord* f : records) {
      LoadedFrame loaded{f, Image(), Image(), Image()};
      THINSLAB_RETURN_IF_ERROR(LoadFrame(dir_, session_, *f, &loaded.raw));
      loaded.signal = loaded.raw;
      LinearizeFrame(context.calibration.response_or_null(), &loaded.signal);
      loaded.variance = loaded.signal;
      for (float& v : loaded.variance.data()) v = static_cast<float>(context.noise.Variance(v));
      // A raw value near saturation is clipped whatever the dark under it: no variance, so that
      // no comparison or peak takes it (the signal alone would not show it).
      const double clip = options_.pair.max_saturation_fraction * context.saturation;
      for (size_t i = 0; i < loaded.raw.data().size(); ++i) {
        if (loaded.raw.data()[i] >= clip) loaded.variance.data()[i] = std::numeric_limits<float>::quiet_NaN();
      }
      const auto dark = context.dark_linear.find(f->exposure_time_us);
      if (dark != context.dark_linear.end() && dark->second.data().size() == loaded.signal.data().size()) {
        const int n = context.dark_count.at(f->exposure_time_us);
        for (size_t i = 0; i < loaded.signal.data().size(); ++i) {
          loaded.signal.data()[i] -= dark->second.data()[i];
          loaded.variance.data()[i] += static_cast<float>(context.noise.Variance(dark->second.data()[i]) / n);
        }
      }
      frames->push_back(std::move(loaded));
    }
    return Status::Ok();
  }

  Status CheckStates(const CameraContext& context) {
    std::map<StateKey, std::vector<const FrameRecord*>> states;
    std::vector<StateKey> order;
    for (const FrameRecord& f : session_.frames) {
      if (f.status == FrameStatus::kFailed || f.camera_id != context.camera.id || f.kind == "dark") continue;
      auto& list = states[KeyOf(f)];
      if (list.empty()) order.push_back(KeyOf(f));
      list.push_back(&f);
    }
    std::vector<LoadedFrame> frames;
    bool checked_board = false;
    for (const StateKey& key : order) {
      THINSLAB_RETURN_IF_ERROR(LoadState(context, states.at(key), &frames));
      const FrameRecord& first = *frames.front().record;
      StateRecord state{KindLabel(first), StateLabel(first), first.index};
      MeasureSaturation(context, frames, &state);
      MeasurePeak(context, frames, &state);
      THINSLAB_RETURN_IF_ERROR(ComparePairs(context, frames, state));
      states_.push_back(state);
      if (first.light.laser_on && session_.rig.laser.present && session_.rig.board.present) {
        CheckBeam(context, frames, state);
      }
      if (!checked_board && (first.kind == "reference" || (first.kind == "flat" && session_.kind == "laser_lobe"))) {
        CheckBoardLit(context, frames, state);
        checked_board = true;
      }
    }
    return Status::Ok();
  }

  void MeasureSaturation(const CameraContext& context, const std::vector<LoadedFrame>& frames, StateRecord* state) {
    if (!std::isfinite(context.saturation)) return;
    const double shortest = frames.front().record->exposure_time_us;
    const auto dark = context.dark_raw.find(shortest);
    for (const LoadedFrame& f : frames) {
      if (f.record->exposure_time_us != shortest) break;
      int64_t saturated = 0;
      for (size_t i = 0; i < f.raw.data().size(); ++i) {
        if (f.raw.data()[i] < context.saturation - 0.5) continue;
        // A hot pixel saturates in the dark frame too: no light was lost there.
        if (dark != context.dark_raw.end() && dark->second.data()[i] >= context.saturation - 0.5) continue;
        ++saturated;
      }
      state->saturated_fraction =
          std::max(state->saturated_fraction, static_cast<double>(saturated) / f.raw.data().size());
    }
  }

  // Peak: the brightest pixel in the longest exposure, in noise sigmas at its level.
  void MeasurePeak(const CameraContext& context, const std::vector<LoadedFrame>& frames, StateRecord* state) {
    const LoadedFrame& longest = frames.back();
    // The brightest pixel (a dot's image can be one pixel; hot pixels are in the dark subtracted).
    // Over the unclipped pixels; a state with clipped pixels has light enough (infinite sigmas).
    const auto dark = context.dark_raw.find(longest.record->exposure_time_us);
    const double clip = options_.pair.max_saturation_fraction * context.saturation;
    double peak = -kInf, variance = 1;
    bool clipped = false;
    for (size_t i = 0; i < longest.signal.data().size(); ++i) {
      const double v = longest.variance.data()[i];
      if (!std::isfinite(v)) {
        // Light, unless a hot pixel clipped in the dark frame too.
        clipped = clipped || dark == context.dark_raw.end() || dark->second.data()[i] < clip;
      } else if (longest.signal.data()[i] > peak) {
        peak = longest.signal.data()[i];
        variance = v;
      }
    }
    state->lit = true;
    state->peak_sigmas = clipped ? kInf : peak / std::sqrt(std::max(variance, 1e-30));
    Eigen::Vector2i raw_where(0, 0);
    state->range_fraction =
        std::isfinite(context.saturation) ? std::min(1.0, BoxMax(longest.raw, 0, &raw_where) / context.saturation) : 0;
  }

  Status ComparePairs(const CameraContext& context, const std::vector<LoadedFrame>& frames, const StateRecord& state) {
    for (size_t k = 0; k + 1 < frames.size(); ++k) {
      const LoadedFrame &a = frames[k], &b = frames[k + 1];
      PairRecord pair{state.kind,      state.state,     a.record->exposure_time_us, b.record->exposure_time_us,
                      a.record->index, b.record->index, FramePairComparison()};
      THINSLAB_RETURN_IF_ERROR(
          CompareFramePair(a.signal, b.signal, a.variance, b.variance, pair.t_b / pair.t_a, context.saturation,
                           options_.pair, &pair.comparison)
              .WithContext("frames " + std::to_string(pair.frame_a) + " and " + std::to_string(pair.frame_b)));
      if (pair.comparison.measured()) pairs_.push_back(pair);
    }
    return Status::Ok();
  }

  // The laser spot (the brightest 5 x 5 patch of the state's radiance, as `fit phase` finds the
  // beam centre) must stand out, lie on the board region the fit rectifies, and sit where the
  // manifest's beam meets the board (z = -distance): the fit centres its rings on the spot it
  // finds, but takes the beam's direction and the board's distance from the manifest.
  void CheckBeam(const CameraContext& context, const std::vector<LoadedFrame>& frames, const StateRecord& state) {
    const LaserInfo& laser = session_.rig.laser;
    const SampleInfo& sample = session_.rig.sample;
    const double d = session_.rig.board.distance_m;
    const CameraInfo& camera = context.camera;
    const Image radiance = RadianceOf(frames, context.saturation);
    Eigen::Vector2i found(0, 0);
    const double peak = BoxMax(radiance, 2, &found);
    const double median = Median(radiance.data());
    if (!(peak > 20 * std::max(median, 0.0))) {
      Add(CheckSeverity::kRetake, "beam",
          state.state + ": no laser spot stands out (brightest 5 x 5 patch " +
              Fixed(peak / std::max(median, 1e-30), 1) + " x the median): is the laser on and aimed at the board?",
          {state.first_frame});
      return;
    }
    // The spot's pixel back-projected onto the board plane.
    const Rigid3d sample_from_cam = camera.cam_from_sample.Inverse();
    const Eigen::Vector3d centre = sample_from_cam.translation;
    auto on_board = [&](const Eigen::Vector2d& pixel) -> Eigen::Vector3d {
      const Eigen::Vector3d ray = sample_from_cam.rotation * PixelToCameraRay(camera, pixel);
      return centre + ((-d - centre.z()) / ray.z()) * ray;
    };
    // Sub-pixel: the centroid of the spot's pixels above half its brightest, as `fit phase`.
    const float top = radiance.at(found.x(), found.y());
    double sw = 0, sx = 0, sy = 0;
    for (int y = std::max(0, found.y() - 3); y <= std::min(radiance.height() - 1, found.y() + 3); ++y) {
      for (int x = std::max(0, found.x() - 3); x <= std::min(radiance.width() - 1, found.x() + 3); ++x) {
        const double w = radiance.at(x, y) - 0.5 * top;
        if (w <= 0) continue;
        sw += w;
        sx += w * (x + 0.5);
        sy += w * (y + 0.5);
      }
    }
    const Eigen::Vector2d pixel =
        sw > 0 ? Eigen::Vector2d(sx / sw, sy / sw) : found.cast<double>() + Eigen::Vector2d(0.5, 0.5);
    const Eigen::Vector3d spot = on_board(pixel);
    if (!spot.allFinite()) return;
    const bool on_region = spot.x() >= sample.region_min_m.x() && spot.x() <= sample.region_max_m.x() &&
                           spot.y() >= sample.region_min_m.y() && spot.y() <= sample.region_max_m.y();
    const std::string where = "the laser spot (pixel " + Fixed(pixel.x(), 1) + ", " + Fixed(pixel.y(), 1) +
                              ") is at (" + Fixed(spot.x() * 1e3, 2) + ", " + Fixed(spot.y() * 1e3, 2) +
                              ") mm on the board";
    if (!on_region) {
      Add(CheckSeverity::kRetake, "beam",
          state.state + ": " + where + ", outside the region the fit uses (rig.sample region [" +
              Fixed(sample.region_min_m.x() * 1e3, 1) + ", " + Fixed(sample.region_max_m.x() * 1e3, 1) + "] x [" +
              Fixed(sample.region_min_m.y() * 1e3, 1) + ", " + Fixed(sample.region_max_m.y() * 1e3, 1) +
              "] mm): aim the beam at the sample region",
          {state.first_frame});
      return;
    }
    const double dz = laser.direction_in_sample.z();
    if (std::abs(dz) < 1e-9) return;
    const Eigen::Vector3d expected =
        laser.origin_in_sample + ((-d - laser.origin_in_sample.z()) / dz) * laser.direction_in_sample;
    // What one camera pixel covers on the board there: the spot is found to about that.
    const double footprint = (on_board(pixel + Eigen::Vector2d(1, 0)) - spot).norm();
    const double tolerance = std::max(options_.max_spot_offset_mm * 1e-3, 2 * footprint);
    const double offset = (spot - expected).head<2>().norm();
    check_->geometry.push_back("beam: " + state.state + ": " + where + ", " + Fixed(offset * 1e3, 2) +
                               " mm from the manifest's beam");
    if (offset > tolerance) {
      Add(CheckSeverity::kWarning, "beam",
          state.state + ": " + where + ", " + Fixed(offset * 1e3, 2) +
              " mm from where the manifest's laser puts the "
              "beam (" +
              Fixed(expected.x() * 1e3, 2) + ", " + Fixed(expected.y() * 1e3, 2) +
              "): the beam, board or camera moved, or the manifest's laser is off; `fit phase` centres its rings on "
              "the spot it finds but takes the beam's direction and the board distance from the manifest",
          {state.first_frame});
    }
  }

  // The board region the fits use (the sample region, carried along the projector's light for
  // shadow maps, onto the board plane) must be in view and lit in the reference / flat frame.
  void CheckBoardLit(const CameraContext& context, const std::vector<LoadedFrame>& frames, const StateRecord& state) {
    if (!session_.rig.board.present) return;
    const SampleInfo& sample = session_.rig.sample;
    const double d = session_.rig.board.distance_m;
    Eigen::Vector3d along(0, 0, -1);
    if (session_.kind == "shadow_map" && session_.rig.projector.present) {
      along = session_.rig.projector.direction_in_sample;
    }
    if (along.z() > -1e-6) return;
    const Image& signal = frames.back().signal;
    constexpr int kGrid = 24;
    int lit = 0;
    for (int j = 0; j < kGrid; ++j) {
      for (int i = 0; i < kGrid; ++i) {
        const Eigen::Vector2d p = sample.region_min_m + Eigen::Vector2d((i + 0.5) / kGrid, (j + 0.5) / kGrid)
                                                            .cwiseProduct(sample.region_max_m - sample.region_min_m);
        const Eigen::Vector3d on_board = Eigen::Vector3d(p.x(), p.y(), 0) + (d / -along.z()) * along;
        Eigen::Vector2d pixel;
        if (!ProjectSamplePoint(context.camera, on_board, &pixel)) continue;
        const int x = static_cast<int>(std::floor(pixel.x())), y = static_cast<int>(std::floor(pixel.y()));
        if (x < 0 || y < 0 || x >= signal.width() || y >= signal.height()) continue;
        const double variance = frames.back().variance.at(x, y);
        // Clipped (no variance): lit.
        lit += !std::isfinite(variance) ||
               BoxMean(signal, x, y, 1) > options_.min_peak_sigmas / 2 * std::sqrt(std::max(variance, 1e-30));
      }
    }
    const double fraction = static_cast<double>(lit) / (kGrid * kGrid);
    check_->geometry.push_back("board: " + Percent(fraction) + " of the region the fits use in view and lit in " +
                               state.state);
    if (fraction < options_.min_lit_fraction) {
      Add(CheckSeverity::kRetake, "board",
          state.state + ": only " + Percent(fraction) +
              " of the board region the fits use is in the camera's view and lit (signal above " +
              Fixed(options_.min_peak_sigmas / 2, 0) +
              " sigma): aim the camera and projector at the sample region of the manifest",
          {state.first_frame});
    }
  }

  Status CheckDots(const CameraContext& context) {
    if (session_.kind != "dot_scan" || !session_.rig.monitor.present) return Status::Ok();
    if (session_.UsableFrames("all_dots", "none").empty()) {
      Add(CheckSeverity::kNote, "dots",
          "no all-dots frame without the sample: the dot positions cannot be checked (and `fit dmf` needs one, or a "
          "rig.json from `thinslab calib dots`)");
      return Status::Ok();
    }
    std::set<std::pair<double, double>> by_yx;
    for (const FrameRecord* f : session_.UsableFrames("dot")) {
      if (f->light.dot_px) by_yx.insert({f->light.dot_px->y(), f->light.dot_px->x()});
    }
    std::vector<Eigen::Vector2d> displayed;
    for (const auto& [y, x] : by_yx) displayed.emplace_back(x, y);
    DotGeometryOptions geometry_options;
    std::string radius_source;
    geometry_options.dot_radius_px = ResolveDotRadiusPx(0, session_.rig.monitor, &radius_source);
    DotGeometryResult geometry;
    std::string source;
    const Status measured =
        MeasureAllDotsGeometry(dir_, session_, context.camera, context.calibration.response_or_null(), displayed,
                               geometry_options, &geometry, &source);
    if (!measured.ok()) {
      Add(CheckSeverity::kRetake, "dots", "the dots of the all-dots frame: " + measured.message());
      return Status::Ok();
    }
    int in_view = 0, found = 0;
    for (const DotRecord& dot : geometry.dots) {
      Eigen::Vector2d pixel;
      if (!ProjectSamplePoint(context.camera, dot.position_in_sample_m, &pixel)) continue;
      const double margin = 3;
      if (pixel.x() < margin || pixel.y() < margin || pixel.x() > context.camera.width_px - margin ||
          pixel.y() > context.camera.height_px - margin) {
        continue;
      }
      ++in_view;
      found += dot.detected;
    }
    check_->geometry.push_back("dots: " + std::to_string(found) + " of the " + std::to_string(in_view) +
                               " dots in view found in " + source + ", rms residual " +
                               Fixed(geometry.rms_residual_m * 1e3, 3) + " mm");
    if (in_view == 0) {
      Add(CheckSeverity::kRetake, "dots", source + ": no displayed dot is in the camera's view");
    } else if (found < options_.min_dots_found_fraction * in_view) {
      Add(CheckSeverity::kWarning, "dots",
          source + ": " + std::to_string(found) + " of the " + std::to_string(in_view) +
              " dots in the camera's view were found where the monitor geometry puts them: check focus, the "
              "monitor's pose in the manifest and the dot radius");
    }
    const std::string distance = MonitorDistanceWarning(geometry.distance_error_m, geometry.distance_error_sigma_m);
    if (!distance.empty()) Add(CheckSeverity::kWarning, "dots", source + ": " + distance);
    return Status::Ok();
  }

  void Summarise() {
    // Flicker: a pair's brightness ratio against the other states' for the same exposures.
    std::map<std::tuple<std::string, double, double>, std::vector<double>> by_exposures;
    for (const PairRecord& p : pairs_) by_exposures[{p.kind, p.t_a, p.t_b}].push_back(p.normalized());
    std::map<std::tuple<std::string, double, double>, double> reference;
    for (const auto& [key, values] : by_exposures) {
      reference[key] = values.size() >= 3 ? Median(values) : 1.0;
      const auto& [kind, t_a, t_b] = key;
      if (values.size() >= 3 && t_a != t_b && std::abs(reference[key] - 1) > kExposureCheckTolerance) {
        Add(CheckSeverity::kNote, "exposure_times",
            "'" + kind + "' frames at " + DurationText(t_b) + " are x" + Fixed(reference[key], 4) + " those at " +
                DurationText(t_a) +
                " beyond the exposure ratio, in every state: the camera applies other exposures "
                "than it reports (calib hdr --exposures measured corrects the merge)");
      }
    }
    std::map<std::string, std::vector<const PairRecord*>> moved, flickered;
    std::map<std::string, std::pair<double, double>> worst_pair;  // kind -> (moved, brightness)
    std::map<std::string, int> pair_count;
    for (const PairRecord& p : pairs_) {
      const double ref = reference.at({p.kind, p.t_a, p.t_b});
      const double change = p.normalized() / ref - 1;
      const double sigma = p.comparison.ratio_sigma / (p.t_b / p.t_a) / ref;
      auto& worst = worst_pair[p.kind];
      worst.first = std::max(worst.first, p.comparison.outlier_fraction);
      worst.second = std::max(worst.second, std::abs(change));
      ++pair_count[p.kind];
      if (p.comparison.outlier_fraction > options_.max_moved_fraction) moved[p.kind].push_back(&p);
      if (std::abs(change) > options_.max_brightness_change && std::abs(change) > 5 * sigma) {
        flickered[p.kind].push_back(&p);
      }
    }
    for (const auto& [kind, list] : moved) {
      const PairRecord& p = *list.front();
      std::vector<int> frames;
      for (const PairRecord* q : list) frames.push_back(q->frame_b);
      Add(CheckSeverity::kRetake, "moved",
          "'" + kind + "': " + std::to_string(list.size()) +
              " frame pair(s) of one light state differ beyond the "
              "noise, e.g. frames " +
              std::to_string(p.frame_a) + " and " + std::to_string(p.frame_b) + " of " + p.state + " in " +
              Percent(p.comparison.outlier_fraction) + " of " + std::to_string(p.comparison.pixels) + " pixels (> " +
              Fixed(options_.pair.outlier_sigmas, 0) +
              " sigma): the sample, board or camera moved between them, or the light changed its shape",
          frames);
    }
    for (const auto& [kind, list] : flickered) {
      const PairRecord& p = *list.front();
      const double ref = reference.at({p.kind, p.t_a, p.t_b});
      std::vector<int> frames;
      for (const PairRecord* q : list) frames.push_back(q->frame_b);
      Add(CheckSeverity::kRetake, "flicker",
          "'" + kind + "': " + std::to_string(list.size()) +
              " frame pair(s) changed brightness as a whole, e.g. frame " + std::to_string(p.frame_b) + " of " +
              p.state + " is x" + Fixed(p.normalized() / ref, 4) + " of what frame " + std::to_string(p.frame_a) +
              " and the exposure ratio predict: the light flickered "
              "or drifted, or the shutter did not apply the exposure",
          frames);
    }

    std::map<std::string, std::vector<const StateRecord*>> by_kind;
    std::vector<std::string> kind_order;
    for (const StateRecord& s : states_) {
      if (by_kind[s.kind].empty()) kind_order.push_back(s.kind);
      by_kind[s.kind].push_back(&s);
    }
    for (const std::string& kind : kind_order) SummariseKind(kind, by_kind.at(kind), worst_pair, pair_count);
  }

  void SummariseKind(const std::string& kind, const std::vector<const StateRecord*>& states,
                     std::map<std::string, std::pair<double, double>>& worst_pair,
                     std::map<std::string, int>& pair_count) {
    CheckedKind k;
    k.label = kind;
    k.states = static_cast<int>(states.size());
    std::set<double> exposures;
    for (const FrameRecord& f : session_.frames) {
      if (f.status == FrameStatus::kFailed || f.kind == "dark" || KindLabel(f) != kind) continue;
      ++k.frames;
      exposures.insert(f.exposure_time_us);
    }
    k.exposures = static_cast<int>(exposures.size());
    k.shortest_us = exposures.empty() ? 0 : *exposures.begin();
    k.longest_us = exposures.empty() ? 0 : *exposures.rbegin();
    std::vector<double> peaks;
    std::vector<int> saturated, underexposed;
    for (const StateRecord* s : states) {
      if (s->saturated_fraction > 0) {
        ++k.saturated_states;
        saturated.push_back(s->first_frame);
      }
      k.worst_saturated_fraction = std::max(k.worst_saturated_fraction, s->saturated_fraction);
      if (!s->lit) continue;
      ++k.lit;
      peaks.push_back(s->peak_sigmas);
      k.max_range_fraction = std::max(k.max_range_fraction, s->range_fraction);
      if (s->peak_sigmas < options_.min_peak_sigmas) {
        ++k.underexposed_states;
        underexposed.push_back(s->first_frame);
      }
    }
    k.median_peak_sigmas = Median(peaks);
    k.frame_pairs = pair_count[kind];
    k.worst_moved_fraction = worst_pair[kind].first;
    k.worst_brightness_change = worst_pair[kind].second;
    check_->kinds.push_back(k);

    const std::string what = "'" + kind + "': ";
    if (k.saturated_states > 0) {
      const bool lost = k.worst_saturated_fraction > options_.max_saturated_fraction;
      Add(lost ? CheckSeverity::kRetake : CheckSeverity::kWarning, "saturation",
          what + std::to_string(k.saturated_states) + " of " + std::to_string(k.states) +
              " state(s) saturate in their shortest exposure (" + DurationText(k.shortest_us) + "; worst " +
              Percent(k.worst_saturated_fraction) + " of a frame" + (lost ? "" : ", below the re-take threshold") +
              "): those pixels are lost in every exposure; add a shorter exposure or dim the light",
          saturated);
    }
    if (k.underexposed_states > 0) {
      // Many dots light little of what the camera sees (their lobes fall outside it); one dark
      // state of a kind fitted as a whole (a shadow map, a lobe) is a failed capture.
      const double fraction = static_cast<double>(k.underexposed_states) / k.lit;
      const bool many_states = k.lit > 8;
      const CheckSeverity severity = !many_states || fraction > 0.5 ? CheckSeverity::kRetake
                                     : fraction > 0.25              ? CheckSeverity::kWarning
                                                                    : CheckSeverity::kNote;
      Add(severity, "exposure",
          what + std::to_string(k.underexposed_states) + " of " + std::to_string(k.lit) + " lit state(s) peak below " +
              Fixed(options_.min_peak_sigmas, 0) + " noise sigmas in their longest " + "exposure (" +
              DurationText(k.longest_us) + "): nothing to fit there; lengthen the longest exposure, " +
              "brighten the light, or check that it reaches the sample",
          underexposed);
    }
    if (k.lit > 0 && k.underexposed_states < k.lit && std::isfinite(k.max_range_fraction) && k.max_range_fraction > 0 &&
        k.max_range_fraction < options_.min_range_fraction) {
      Add(CheckSeverity::kWarning, "exposure",
          what + "the brightest state peaks at " + Percent(k.max_range_fraction) +
              " of the range in the longest exposure (" + DurationText(k.longest_us) +
              "): a longer exposure would gain signal to noise");
    }
  }

  const std::string& dir_;
  const Session& session_;
  const CaptureCheckOptions& options_;
  CaptureCheck* check_;
  std::vector<StateRecord> states_;
  std::vector<PairRecord> pairs_;
};

}  // namespace

Status CheckCapture(const std::string& session_dir, const CaptureCheckOptions& options, CaptureCheck* check) {
  *check = CaptureCheck();
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  Session session;
  int journaled = 0;
  THINSLAB_RETURN_IF_ERROR(ReadSessionWithJournal(session_dir, &session, &journaled));
  check->capture = session_dir;
  check->session_kind = session.kind;
  check->frames = static_cast<int>(session.frames.size());
  CaptureChecker checker(session_dir, session, options, check);
  return checker.Run(journaled);
}

}  // namespace thinslab
