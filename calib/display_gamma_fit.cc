// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/display_gamma_fit.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <set>
#include <sstream>

#include "thinslab/calib/hdr_merge.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "thinslab/drivers/pattern_id.h"

namespace thinslab {
namespace {

// One bracket: consecutive "level" frames of one pattern, each exposure once.
struct Bracket {
  double level = 0;
  std::string pattern;
  std::vector<const FrameRecord*> frames;
  std::set<double> exposures;
  HdrImage hdr;
};

// q-quantile (q in [0, 1]) of `values` (reordered).
double Quantile(std::vector<double>* values, double q) {
  if (values->empty()) return 0;
  const size_t k = std::min(values->size() - 1, static_cast<size_t>(std::floor(q * (values->size() - 1))));
  std::nth_element(values->begin(), values->begin() + k, values->end());
  return (*values)[k];
}

// Scaled MAD (1.4826 MAD: the sigma of a normal distribution) and median of `values` (reordered).
double ScaledMad(std::vector<double>* values, double* median) {
  *median = Quantile(values, 0.5);
  for (double& v : *values) v = std::abs(v - *median);
  return 1.4826 * Quantile(values, 0.5);
}

// The signal of a bracket whose region values are `v`, given the level-1 values `full` of the
// same pixels: the region is not uniform (pixels partly covering the screen, falloff), so a
// robust mean of `v` itself would treat its edge pixels as outliers, and differently at each
// level. The pixel ratios q = v / full are uniform for a display whose curve is the same at
// every pixel; pixels whose q is further than `mads` scaled MADs from the median (a hot pixel,
// a cosmic ray, dust that moved) are left out, and the signal is mean(full) * sum(v) / sum(full)
// over the pixels kept: the same scale for every level whatever pixels were left out.
double RobustSignal(const std::vector<double>& v, const std::vector<double>& full, double mean_full, double mads,
                    int64_t* rejected) {
  std::vector<double> q(v.size());
  for (size_t i = 0; i < v.size(); ++i) q[i] = v[i] / full[i];
  std::vector<double> scratch = q;
  double median = 0;
  const double sigma = ScaledMad(&scratch, &median);
  double sum_v = 0, sum_full = 0;
  for (size_t i = 0; i < v.size(); ++i) {
    if (sigma > 0 && std::abs(q[i] - median) > mads * sigma) {
      ++*rejected;
      continue;
    }
    sum_v += v[i];
    sum_full += full[i];
  }
  return sum_full > 0 ? mean_full * sum_v / sum_full : 0;
}

std::string Num(double v) {
  std::ostringstream s;
  s.precision(4);
  s << v;
  return s.str();
}

}  // namespace

bool DisplayGammaFitOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(lit_fraction > 0 && lit_fraction < 1)) {
    msg << "DisplayGammaFitOptions::lit_fraction = " << lit_fraction << ". Violated constraint: in (0, 1)";
  } else if (!(lit_percentile > 0 && lit_percentile <= 1)) {
    msg << "DisplayGammaFitOptions::lit_percentile = " << lit_percentile << ". Violated constraint: in (0, 1]";
  } else if (!(outlier_mads > 0)) {
    msg << "DisplayGammaFitOptions::outlier_mads = " << outlier_mads << ". Violated constraint: > 0";
  } else if (!(near_saturation > 0 && near_saturation <= 1)) {
    msg << "DisplayGammaFitOptions::near_saturation = " << near_saturation << ". Violated constraint: in (0, 1]";
  } else if (!(max_near_saturated_fraction >= 0 && max_near_saturated_fraction < 1)) {
    msg << "DisplayGammaFitOptions::max_near_saturated_fraction = " << max_near_saturated_fraction
        << ". Violated constraint: in [0, 1)";
  } else if (!(max_saturated_fraction >= 0 && max_saturated_fraction < 1)) {
    msg << "DisplayGammaFitOptions::max_saturated_fraction = " << max_saturated_fraction
        << ". Violated constraint: in [0, 1)";
  } else if (!(fallback_read_noise_dn > 0)) {
    msg << "DisplayGammaFitOptions::fallback_read_noise_dn = " << fallback_read_noise_dn
        << ". Violated constraint: > 0";
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

Status FitDisplayGammaSession(const std::string& session_dir, const Session& session, const CameraResponse* response,
                              const DisplayGammaFitOptions& options, DisplayGammaFitSummary* summary) {
  *summary = DisplayGammaFitSummary();
  auto fail = [&](const std::string& message) {
    summary->message = message;
    return Status::Error(message);
  };
  std::string error;
  if (!options.Check(&error)) return fail(error);
  const std::string manifest = JoinPath(session_dir, kSessionManifestName);
  if (session.rig.cameras.empty()) return fail(manifest + ": rig.cameras: no camera");
  const CameraInfo& camera = session.rig.cameras[0];
  summary->response = response != nullptr ? response->method : "linear";

  // Brackets in session order (a resumed session's frames are in plan order too).
  std::vector<Bracket> brackets;
  for (const FrameRecord* f : session.UsableFrames("level")) {
    if (f->camera_id != camera.id) continue;
    PatternSpec spec;
    const Status parsed = ParsePatternId(f->light.projector_pattern, &spec);
    if (!parsed.ok() || spec.kind != PatternSpec::Kind::kFlat) {
      return fail(JoinPath(session_dir, f->file) + ": frame of kind 'level' with pattern '" +
                  f->light.projector_pattern + "': expected flat:<level>");
    }
    if (brackets.empty() || brackets.back().pattern != f->light.projector_pattern ||
        brackets.back().exposures.count(f->exposure_time_us) > 0) {
      brackets.emplace_back();
      brackets.back().level = spec.level;
      brackets.back().pattern = f->light.projector_pattern;
    }
    brackets.back().frames.push_back(f);
    brackets.back().exposures.insert(f->exposure_time_us);
  }
  if (brackets.empty()) {
    return fail(manifest + ": frames: no usable frame of kind 'level' for camera " + camera.id + " (session kind '" +
                session.kind + "'; `thinslab acquire gamma` writes display_gamma sessions)");
  }
  std::set<double> levels;
  for (const Bracket& b : brackets) levels.insert(b.level);
  if (levels.count(1.0) == 0) return fail(manifest + ": frames: no usable 'level' frame of pattern flat:1");
  if (levels.count(0.0) == 0) return fail(manifest + ": frames: no usable 'level' frame of pattern flat:0");
  if (levels.size() < 3) {
    return fail(manifest + ": frames: " + std::to_string(levels.size()) +
                " distinct drive levels; a gamma table needs at least 3 (0, 1 and one between)");
  }
  summary->num_levels = static_cast<int>(levels.size());

  std::vector<const FrameRecord*> darks;
  for (const FrameRecord* f : session.UsableFrames("dark")) {
    if (f->camera_id == camera.id) darks.push_back(f);
  }
  summary->num_darks = static_cast<int>(darks.size());
  FrameNoiseModel noise;
  {
    const Status resolved = ResolveFrameNoise(session_dir, session, camera, &noise);
    if (!resolved.ok()) return fail(resolved.message());
  }
  // Whole frames near saturation are left out of their bracket. Dropping only the saturated
  // samples, as the merge does, censors a flat level whose pixels sit near full well: the pixels
  // that noise pushed over are lost and the rest merge low (measured: 6e-4 of full light at a
  // level 4 refresh periods put at 99 % of full well, where one unsaturated exposure gives
  // 1.5e-4). With whole frames left out, every pixel of a level is merged from the same exposures.
  const double z_near = options.near_saturation * (camera.saturation_dn - camera.black_level_dn);
  for (Bracket& b : brackets) {
    std::vector<const FrameRecord*> kept;
    int64_t fewest_near = -1;
    for (const FrameRecord* f : b.frames) {
      Image z;
      const Status loaded = LoadFrame(session_dir, session, *f, &z);
      if (!loaded.ok()) return fail(loaded.message());
      int64_t near = 0;
      for (float v : z.data()) near += v >= z_near;
      if (near <= options.max_near_saturated_fraction * z.num_pixels()) {
        kept.push_back(f);
      } else {
        ++summary->frames_near_saturation;
      }
      fewest_near = fewest_near < 0 ? near : std::min(fewest_near, near);
    }
    if (kept.empty()) {
      return fail(JoinPath(session_dir, b.frames[0]->file) + ": every exposure of " + b.pattern + " is saturated or " +
                  "near it (at least " + std::to_string(fewest_near) + " px at or above " +
                  Num(100 * options.near_saturation) + " % of saturation, more than " +
                  Num(100 * options.max_near_saturated_fraction) + " % of the frame); shorten the exposures (--exposures-us)");
    }
    b.frames = kept;
    SessionMergeInfo info;
    const Status merged = MergeSessionBracket(session_dir, session, camera, b.frames, darks, response, HdrMergeOptions(),
                                              options.fallback_read_noise_dn, noise, &b.hdr, &info);
    if (!merged.ok()) return fail(merged.WithContext(JoinPath(session_dir, b.frames[0]->file)).message());
  }

  // The lit region, from the mean level-1 radiance.
  const int width = brackets[0].hdr.radiance.width(), height = brackets[0].hdr.radiance.height();
  const size_t n = static_cast<size_t>(width) * height;
  std::vector<double> full(n, 0.0);
  std::vector<uint8_t> saturated(n, 0);
  int full_count = 0;
  std::string full_file;
  for (const Bracket& b : brackets) {
    for (size_t i = 0; i < n; ++i) saturated[i] |= b.hdr.all_saturated.data()[i] > 0;
    if (b.level != 1.0) continue;
    if (full_file.empty()) full_file = JoinPath(session_dir, b.frames[0]->file);
    for (size_t i = 0; i < n; ++i) full[i] += b.hdr.radiance.data()[i];
    ++full_count;
  }
  std::vector<double> finite;
  for (double& v : full) {
    v /= full_count;
    if (std::isfinite(v)) finite.push_back(v);
  }
  const double threshold = options.lit_fraction * Quantile(&finite, options.lit_percentile);
  std::vector<size_t> region;
  for (size_t i = 0; i < n; ++i) {
    if (!(std::isfinite(full[i]) && full[i] > threshold && threshold > 0)) continue;
    if (saturated[i]) {
      ++summary->pixels_saturated;
    } else {
      region.push_back(i);
    }
  }
  summary->lit_pixels = static_cast<int64_t>(region.size());
  const int64_t candidates = summary->lit_pixels + summary->pixels_saturated;
  if (candidates > 0 && summary->pixels_saturated > options.max_saturated_fraction * candidates) {
    // What is left is the rim of the lit area (pixels partly covering the screen): few and not
    // what the exposures were chosen for.
    return fail(full_file + ": " + std::to_string(summary->pixels_saturated) + " of the " + std::to_string(candidates) +
                " lit pixels are saturated at every exposure of some level (more than " +
                Num(100 * options.max_saturated_fraction) + " %); shorten the exposures (--exposures-us)");
  }
  if (region.empty()) {
    return fail(full_file + ": the display is never lit: no pixel of the level-1 frames is above " +
                Num(options.lit_fraction) + " x its " + Num(100 * options.lit_percentile) + "th percentile");
  }

  // Signals; then the display must be measurably lit.
  std::vector<std::pair<double, double>> pairs;
  std::map<double, std::vector<double>> by_level;
  double sigma0 = 0;  // Largest pixel spread of a level-0 bracket.
  std::vector<double> full_in_region;
  double mean_full = 0;
  for (size_t i : region) {
    full_in_region.push_back(full[i]);
    mean_full += full[i] / region.size();
  }
  std::map<double, int> repeats;
  for (const Bracket& b : brackets) {
    std::vector<double> values;
    values.reserve(region.size());
    for (size_t i : region) values.push_back(b.hdr.radiance.data()[i]);
    DisplayGammaMeasurement m;
    m.signal = RobustSignal(values, full_in_region, mean_full, options.outlier_mads, &summary->outliers_rejected);
    if (b.level == 0.0) {
      double median = 0;
      sigma0 = std::max(sigma0, ScaledMad(&values, &median));
    }
    m.level = b.level;
    m.repeat = repeats[b.level]++;
    m.num_frames = static_cast<int>(b.frames.size());
    m.first_file = b.frames[0]->file;
    summary->measurements.push_back(m);
    pairs.push_back({m.level, m.signal});
    by_level[m.level].push_back(m.signal);
  }
  auto mean_of = [](const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return s / v.size();
  };
  const double s0 = mean_of(by_level[0.0]), s1 = mean_of(by_level[1.0]);
  // The lit region is chosen on the level-1 images, so with a display that is off it is the
  // pixels whose noise happened to be high there: s1 - s0 is then a pixel sigma or two, whereas
  // a lit display raises the region by hundreds. Five level-0 pixel sigmas separate the two.
  if (!(s1 - s0 > 5 * sigma0)) {
    return fail(full_file + ": the display is never lit: the level-1 signal " + Num(s1) +
                " DN/us is not above the level-0 signal " + Num(s0) + " DN/us by 5 pixel sigmas (" + Num(5 * sigma0) +
                "); is the camera looking at the display?");
  }
  const Status fitted = FitGammaTable(pairs, &summary->table);
  if (!fitted.ok()) return fail(fitted.WithContext(manifest).message());

  // Residuals, repeat spread and the power-law exponent.
  std::map<double, double> level_light;
  for (const auto& [level, signals] : by_level) level_light[level] = (mean_of(signals) - s0) / (s1 - s0);
  double sum_sq = 0, repeat_sq = 0, num = 0, den = 0;
  int repeat_n = 0;
  for (DisplayGammaMeasurement& m : summary->measurements) {
    m.light = (m.signal - s0) / (s1 - s0);
    m.residual = m.light - summary->table.LightForDrive(m.level);
    sum_sq += m.residual * m.residual;
    summary->max_abs_residual = std::max(summary->max_abs_residual, std::abs(m.residual));
    if (by_level[m.level].size() > 1) {
      repeat_sq += (m.light - level_light[m.level]) * (m.light - level_light[m.level]);
      ++repeat_n;
    }
  }
  summary->rms_residual = std::sqrt(sum_sq / summary->measurements.size());
  summary->repeat_rms = repeat_n > 0 ? std::sqrt(repeat_sq / repeat_n) : 0;
  for (const auto& [drive, light] : summary->table.drive_to_light) {
    // ln L = gamma ln d through the origin; levels whose light is within noise of 0 or 1 say nothing.
    if (drive <= 0 || drive >= 1 || light <= 0.002) continue;
    num += std::log(drive) * std::log(light);
    den += std::log(drive) * std::log(drive);
  }
  summary->power_exponent = den > 0 ? num / den : 0;
  summary->ok = true;
  summary->message = "fitted";
  return Status::Ok();
}

std::string DisplayGammaFitSummary::BriefReport() const {
  std::ostringstream out;
  out << "display gamma: " << message << "; " << num_levels << " levels, " << measurements.size() << " brackets, "
      << num_darks << " darks, response " << response << "; lit region " << lit_pixels << " px ("
      << pixels_saturated << " saturated px left out, " << frames_near_saturation << " frames near saturation left out, "
      << outliers_rejected << " outlier samples); fit residual rms "
      << Num(rms_residual) << " max " << Num(max_abs_residual) << " of full light, repeat rms " << Num(repeat_rms)
      << "; power-law exponent " << Num(power_exponent) << " (information only)";
  return out.str();
}

std::string DisplayGammaFitSummary::FullReport() const {
  std::ostringstream out;
  out << BriefReport() << "\n";
  for (const auto& [drive, light] : table.drive_to_light) {
    out << "  drive " << Num(drive) << "  light " << Num(light) << "\n";
  }
  return out.str();
}

}  // namespace thinslab
