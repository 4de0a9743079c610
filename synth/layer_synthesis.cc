// SPDX-License-Identifier: Apache-2.0
#include "thinslab/synth/layer_synthesis.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "thinslab/core/file.h"

namespace thinslab {
namespace {

// SplitMix64 finaliser: independent per-layer seeds from the run seed and the layer index.
uint64_t MixSeed(uint64_t seed, uint64_t index) {
  uint64_t z = seed + 0x9E3779B97F4A7C15ULL * (index + 1);
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

const Prototype* FindPrototype(const std::vector<Prototype>& library, const std::string& name) {
  for (const auto& p : library) {
    if (p.name == name) return &p;
  }
  return nullptr;
}

Image Resample(const Image& tau, double ratio) {
  const int w = std::max(1, static_cast<int>(std::lround(tau.width() * ratio)));
  const int h = std::max(1, static_cast<int>(std::lround(tau.height() * ratio)));
  cv::Mat src(tau.height(), tau.width(), CV_32F, const_cast<float*>(tau.data().data()));
  cv::Mat dst;
  cv::resize(src, dst, cv::Size(w, h), 0, 0, ratio < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
  Image out(w, h, {"tau"});
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) out.at(x, y) = std::max(0.0f, dst.at<float>(y, x));
  }
  return out;
}

Status ReadRange(const nlohmann::json& j, const std::string& where, const std::string& key, double* lo, double* hi) {
  if (!j.contains(key)) return Status::Ok();
  const auto& v = j[key];
  if (!v.is_array() || v.size() != 2 || !v[0].is_number() || !v[1].is_number()) {
    return Status::Error(where + "." + key + " must be [min, max] numbers");
  }
  *lo = v[0].get<double>();
  *hi = v[1].get<double>();
  return Status::Ok();
}

template <typename T>
Status ReadNumber(const nlohmann::json& j, const std::string& where, const std::string& key, T* value) {
  if (!j.contains(key)) return Status::Ok();
  if (!j[key].is_number()) return Status::Error(where + "." + key + " is not a number");
  if constexpr (std::is_integral_v<T>) {
    if (!j[key].is_number_integer()) return Status::Error(where + "." + key + " is not an integer");
    if (j[key].is_number_unsigned() && std::is_unsigned_v<T>) {
      *value = j[key].get<T>();
    } else {
      const int64_t v = j[key].get<int64_t>();
      if (v < 0 && std::is_unsigned_v<T>) return Status::Error(where + "." + key + " is negative");
      *value = static_cast<T>(v);
    }
  } else {
    *value = j[key].get<T>();
  }
  return Status::Ok();
}

Status ReadBool(const nlohmann::json& j, const std::string& where, const std::string& key, bool* value) {
  if (!j.contains(key)) return Status::Ok();
  if (!j[key].is_boolean()) return Status::Error(where + "." + key + " must be true or false");
  *value = j[key].get<bool>();
  return Status::Ok();
}

Status ReadSelection(const nlohmann::json& j, const std::string& where, QuiltingSelection* selection) {
  if (!j.contains("selection")) return Status::Ok();
  const auto& v = j["selection"];
  if (v == "mass_matched") {
    *selection = QuiltingSelection::kMassMatched;
  } else if (v == "ssd") {
    *selection = QuiltingSelection::kSsd;
  } else {
    return Status::Error(where + ".selection = " + v.dump() + ": must be \"mass_matched\" or \"ssd\"");
  }
  return Status::Ok();
}

// A misspelt key ("max_tlit") would otherwise leave its default in force without a word.
const std::vector<std::string> kSpecKeys = {"format", "format_version", "width_px", "height_px",
                                            "seed",   "pixel_pitch_m",  "layers"};
const std::vector<std::string> kLayerKeys = {
    "prototype", "density",   "scale",          "rotation_deg",    "x",         "y",        "top_bias",
    "patch_px",  "overlap_px", "tolerance",     "variance_tolerance", "max_candidates", "match_histogram",
    "selection", "max_tilt",  "mass_feedback"};

Status RejectUnknownKeys(const nlohmann::json& j, const std::string& where, const std::vector<std::string>& known) {
  for (const auto& item : j.items()) {
    if (std::find(known.begin(), known.end(), item.key()) != known.end()) continue;
    std::string list;
    for (const auto& k : known) list += (list.empty() ? "" : ", ") + k;
    return Status::Error(where + ": unknown field '" + item.key() + "' (known: " + list + ")");
  }
  return Status::Ok();
}

}  // namespace

bool SynthesisOptions::Check(std::string* error) const {
  std::ostringstream e;
  if (width_px < 1 || height_px < 1 || width_px > kMaxSynthesisSidePx || height_px > kMaxSynthesisSidePx) {
    e << "SynthesisOptions::size = " << width_px << "x" << height_px << " is impossible: each side must be in [1, "
      << kMaxSynthesisSidePx << "] px";
  } else if (static_cast<int64_t>(width_px) * height_px > kMaxSynthesisPixels) {
    e << "SynthesisOptions::size = " << width_px << "x" << height_px << " has more than 2^26 pixels (8192x8192)";
  } else if (!(pixel_pitch_m >= 0 && std::isfinite(pixel_pitch_m))) {
    e << "SynthesisOptions::pixel_pitch_m = " << pixel_pitch_m << ". Violated constraint: >= 0";
  } else if (layers.empty()) {
    e << "SynthesisOptions::layers is empty: select at least one prototype";
  }
  if (e.str().empty()) return true;
  *error = e.str();
  return false;
}

Status ReadSynthesisSpec(const std::string& path, SynthesisOptions* options) {
  std::string text;
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(path, &text));
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object()) return Status::Error(path + ": not a JSON object");
  if (!j.contains("format") || j["format"] != "thinslab-synth-spec") {
    return Status::Error(path + ": field 'format' must be \"thinslab-synth-spec\"");
  }
  if (!j.contains("format_version") || !j["format_version"].is_string() ||
      j["format_version"].get<std::string>().rfind("1.", 0) != 0) {
    return Status::Error(path + ": field 'format_version' must be \"1.x\"");
  }
  THINSLAB_RETURN_IF_ERROR(RejectUnknownKeys(j, path, kSpecKeys));
  THINSLAB_RETURN_IF_ERROR(ReadNumber(j, path, "width_px", &options->width_px));
  THINSLAB_RETURN_IF_ERROR(ReadNumber(j, path, "height_px", &options->height_px));
  for (const auto& [key, value] : {std::pair<const char*, int>{"width_px", options->width_px},
                                   std::pair<const char*, int>{"height_px", options->height_px}}) {
    if (value < 1 || value > kMaxSynthesisSidePx) {
      return Status::Error(path + ": field '" + key + "' = " + std::to_string(value) +
                           " is impossible: each side must be in [1, " + std::to_string(kMaxSynthesisSidePx) + "] px");
    }
  }
  THINSLAB_RETURN_IF_ERROR(ReadNumber(j, path, "seed", &options->seed));
  THINSLAB_RETURN_IF_ERROR(ReadNumber(j, path, "pixel_pitch_m", &options->pixel_pitch_m));
  if (!j.contains("layers") || !j["layers"].is_array())
    return Status::Error(path + ": field 'layers' must be an array");
  options->layers.clear();
  for (size_t k = 0; k < j["layers"].size(); ++k) {
    const auto& l = j["layers"][k];
    const std::string where = path + ": layers[" + std::to_string(k) + "]";
    if (!l.is_object()) return Status::Error(where + " is not an object");
    THINSLAB_RETURN_IF_ERROR(RejectUnknownKeys(l, where, kLayerKeys));
    SynthLayerSpec spec;
    if (!l.contains("prototype") || !l["prototype"].is_string())
      return Status::Error(where + ".prototype must be a string");
    spec.prototype = l["prototype"].get<std::string>();
    THINSLAB_RETURN_IF_ERROR(ReadNumber(l, where, "density", &spec.density));
    static const char* kPlacementKeys[] = {"scale", "rotation_deg", "x", "y", "top_bias"};
    for (const char* key : kPlacementKeys) spec.has_placement |= l.contains(key);
    THINSLAB_RETURN_IF_ERROR(ReadRange(l, where, "scale", &spec.placement.scale_min, &spec.placement.scale_max));
    THINSLAB_RETURN_IF_ERROR(
        ReadRange(l, where, "rotation_deg", &spec.placement.rotation_min_deg, &spec.placement.rotation_max_deg));
    THINSLAB_RETURN_IF_ERROR(ReadRange(l, where, "x", &spec.placement.x_min, &spec.placement.x_max));
    THINSLAB_RETURN_IF_ERROR(ReadRange(l, where, "y", &spec.placement.y_min, &spec.placement.y_max));
    THINSLAB_RETURN_IF_ERROR(ReadNumber(l, where, "top_bias", &spec.placement.top_bias));
    THINSLAB_RETURN_IF_ERROR(ReadNumber(l, where, "patch_px", &spec.quilting.patch_px));
    THINSLAB_RETURN_IF_ERROR(ReadNumber(l, where, "overlap_px", &spec.quilting.overlap_px));
    THINSLAB_RETURN_IF_ERROR(ReadNumber(l, where, "tolerance", &spec.quilting.tolerance));
    THINSLAB_RETURN_IF_ERROR(ReadNumber(l, where, "variance_tolerance", &spec.quilting.variance_tolerance));
    THINSLAB_RETURN_IF_ERROR(ReadNumber(l, where, "max_candidates", &spec.quilting.max_candidates));
    THINSLAB_RETURN_IF_ERROR(ReadBool(l, where, "match_histogram", &spec.quilting.match_histogram));
    THINSLAB_RETURN_IF_ERROR(ReadSelection(l, where, &spec.quilting.selection));
    THINSLAB_RETURN_IF_ERROR(ReadNumber(l, where, "max_tilt", &spec.quilting.max_tilt));
    THINSLAB_RETURN_IF_ERROR(ReadNumber(l, where, "mass_feedback", &spec.quilting.mass_feedback));
    options->layers.push_back(spec);
  }
  return Status::Ok();
}

Image BlendLayers(const std::vector<BlendInput>& inputs) {
  CHECK(!inputs.empty());
  const int w = inputs[0].tau->width(), h = inputs[0].tau->height();
  Image out(w, h, {"tau", "g", "albedo", "n2"});
  const size_t n = out.num_pixels();
  std::vector<double> tau(n, 0.0), coverage(n, 0.0), g(n, 0.0), albedo(n, 0.0), n2(n, 0.0);
  for (const auto& in : inputs) {
    CHECK_EQ(in.tau->width(), w);
    CHECK_EQ(in.tau->height(), h);
    const std::vector<float>& t = in.tau->data();
    const int stride = in.tau->num_channels();
    for (size_t i = 0; i < n; ++i) {
      const double tk = t[i * stride];
      if (tk <= 0) continue;
      // Coverage alpha = 1 - e^{-tau} (Gu et al. 2007, Eq. 5 at normal incidence); "over".
      const double alpha = -std::expm1(-tk);
      tau[i] += tk;
      coverage[i] = coverage[i] * (1 - alpha) + alpha;
      g[i] = g[i] * (1 - alpha) + alpha * in.g;
      albedo[i] = albedo[i] * (1 - alpha) + alpha * in.albedo;
      n2[i] = n2[i] * (1 - alpha) + alpha * in.n2;
    }
  }
  std::vector<float>& d = out.data();
  for (size_t i = 0; i < n; ++i) {
    const bool clean = coverage[i] <= 0;
    d[i * 4 + 0] = static_cast<float>(tau[i]);
    d[i * 4 + 1] = clean ? 0.0f : static_cast<float>(g[i] / coverage[i]);
    d[i * 4 + 2] = clean ? 0.0f : static_cast<float>(albedo[i] / coverage[i]);
    d[i * 4 + 3] = clean ? 1.0f : static_cast<float>(n2[i] / coverage[i]);
  }
  return out;
}

Status SynthesizeContamination(const std::vector<Prototype>& library, const SynthesisOptions& options, Image* layer,
                               SynthesisSummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  *summary = SynthesisSummary();
  std::vector<const Prototype*> selected;
  for (size_t k = 0; k < options.layers.size(); ++k) {
    const Prototype* p = FindPrototype(library, options.layers[k].prototype);
    if (!p) {
      std::string names;
      for (const auto& q : library) names += (names.empty() ? "" : ", ") + q.name;
      return Status::Error("SynthesisOptions::layers[" + std::to_string(k) + "].prototype '" +
                           options.layers[k].prototype + "' is not in the library (have: " + names + ")");
    }
    THINSLAB_RETURN_IF_ERROR(p->Check("prototype '" + p->name + "'"));
    selected.push_back(p);
  }
  const double pitch_m = options.pixel_pitch_m > 0 ? options.pixel_pitch_m : selected[0]->pixel_pitch_m;
  summary->pixel_pitch_m = pitch_m;
  const int w = options.width_px, h = options.height_px;

  std::vector<Image> taus(selected.size());
  std::vector<BlendInput> inputs;
  for (size_t k = 0; k < selected.size(); ++k) {
    const auto layer_start = std::chrono::steady_clock::now();
    const Prototype& p = *selected[k];
    const SynthLayerSpec& spec = options.layers[k];
    const uint64_t seed = MixSeed(options.seed, k);
    const double ratio = p.pixel_pitch_m / pitch_m;  // Output pixels per prototype pixel.
    if (!(ratio > 1.0 / 64 && ratio <= 64)) {
      return Status::Error("prototype '" + p.name + "': pixel pitch " + std::to_string(p.pixel_pitch_m) +
                           " m is too far from the output pitch " + std::to_string(pitch_m) + " m (ratio beyond 64)");
    }
    SynthesizedLayerInfo info;
    info.prototype = p.name;
    info.category = p.category;
    const std::string where = "SynthesisOptions::layers[" + std::to_string(k) + "] ('" + p.name + "')";
    if (p.category == "dust") {
      // Gu et al. 2007, Sec. 5.3: dust by image quilting [EF01].
      info.method = "quilting";
      info.density = spec.density < 0 ? 1.0 : spec.density;
      if (!(info.density >= 0 && info.density <= 100)) {
        return Status::Error(where + ".density = " + std::to_string(info.density) +
                             ". Violated constraint: in [0, 100]");
      }
      QuiltingOptions q = spec.quilting;
      q.seed = seed;
      const Image source = std::abs(ratio - 1) < 1e-9 ? p.tau : Resample(p.tau, ratio);
      THINSLAB_RETURN_IF_ERROR(QuiltTexture(source, w, h, q, &taus[k], nullptr, &info.quilting).WithContext(where));
      for (auto& v : taus[k].data()) v = static_cast<float>(v * info.density);
    } else {
      // Lipids: random scale/rotation/placement; dirt: limited rotation and translation,
      // biased to the top (Sec. 5.3).
      info.method = "placement";
      PlacementOptions placement = spec.has_placement ? spec.placement : DefaultPlacementForCategory(p.category);
      if (spec.density >= 0) placement.density = spec.density;
      placement.pitch_ratio = ratio;
      info.density = placement.density;
      taus[k] = Image(w, h, {"tau"});
      THINSLAB_RETURN_IF_ERROR(PlaceCopies(p.tau, w, h, placement, seed, &taus[k], &info.copies).WithContext(where));
    }
    info.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - layer_start).count();
    summary->layers.push_back(info);
    inputs.push_back({&taus[k], p.g, p.albedo, p.n2});
  }
  *layer = BlendLayers(inputs);
  int64_t covered = 0;
  double sum = 0, max_tau = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double t = layer->at(x, y, 0);
      covered += t > 0;
      sum += t;
      max_tau = std::max(max_tau, t);
    }
  }
  const double n = static_cast<double>(w) * h;
  summary->covered_fraction = covered / n;
  summary->mean_tau = sum / n;
  summary->max_tau = max_tau;
  summary->total_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return Status::Ok();
}

std::string SynthesisSummary::ToJson() const {
  nlohmann::json j;
  j["format"] = "thinslab-synth-summary";
  j["format_version"] = "1.0";
  j["pixel_pitch_m"] = pixel_pitch_m;
  j["covered_fraction"] = covered_fraction;
  j["mean_tau"] = mean_tau;
  j["max_tau"] = max_tau;
  j["timings_s"] = {{"total", total_s}};
  j["layers"] = nlohmann::json::array();
  for (const auto& l : layers) {
    nlohmann::json e;
    e["prototype"] = l.prototype;
    e["category"] = l.category;
    e["method"] = l.method;
    e["density"] = l.density;
    e["seconds"] = l.seconds;
    if (l.method == "quilting") {
      e["patches"] = l.quilting.patches;
      e["candidates_evaluated"] = l.quilting.candidates_evaluated;
      e["source_zero_fraction"] = l.quilting.source_zero_fraction;
      e["quilted_zero_fraction"] = l.quilting.quilted_zero_fraction;
      e["tilt_capped_patches"] = l.quilting.tilt_capped_patches;
    } else {
      e["copies"] = nlohmann::json::array();
      for (const auto& c : l.copies) {
        e["copies"].push_back(
            {{"centre_px", {c.centre_x_px, c.centre_y_px}}, {"scale", c.scale}, {"rotation_deg", c.rotation_deg}});
      }
    }
    j["layers"].push_back(e);
  }
  return j.dump(2) + "\n";
}

Status CheckContaminationLayer(const Image& layer, const std::string& where) {
  const char* names[] = {"tau", "g", "albedo", "n2"};
  int c[4];
  for (int k = 0; k < 4; ++k) {
    c[k] = layer.ChannelIndex(names[k]);
    if (c[k] < 0) return Status::Error(where + ": missing channel '" + names[k] + "' (need tau, g, albedo, n2)");
  }
  for (int y = 0; y < layer.height(); ++y) {
    for (int x = 0; x < layer.width(); ++x) {
      const float tau = layer.at(x, y, c[0]), g = layer.at(x, y, c[1]), a = layer.at(x, y, c[2]),
                  n2 = layer.at(x, y, c[3]);
      const bool ok = std::isfinite(tau) && tau >= 0 && g > -1 && g < 1 && a >= 0 && a <= 1 && n2 >= 1 && n2 <= 3;
      if (!ok) {
        std::ostringstream msg;
        msg << where << ": pixel (" << x << ", " << y << ") has tau=" << tau << " g=" << g << " albedo=" << a
            << " n2=" << n2 << "; need tau >= 0, -1 < g < 1, albedo in [0, 1], n2 in [1, 3]";
        return Status::Error(msg.str());
      }
    }
  }
  return Status::Ok();
}

}  // namespace thinslab
