// SPDX-License-Identifier: Apache-2.0
#include "thinslab/synth/prototype_library.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/version.h"

namespace thinslab {
namespace {

std::string Num(double v) {
  std::ostringstream os;
  os.precision(17);
  os << v;
  return os.str();
}

Status ReadJson(const std::string& path, nlohmann::json* j) {
  std::string text;
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(path, &text));
  *j = nlohmann::json::parse(text, nullptr, false);
  if (j->is_discarded() || !j->is_object()) return Status::Error(path + ": not a JSON object");
  return Status::Ok();
}

Status GetNumber(const nlohmann::json& j, const std::string& path, const std::string& key, double* value) {
  if (!j.contains(key)) return Status::Error(path + ": missing field '" + key + "'");
  if (!j[key].is_number()) return Status::Error(path + ": field '" + key + "' is not a number");
  *value = j[key].get<double>();
  return Status::Ok();
}

Status GetString(const nlohmann::json& j, const std::string& path, const std::string& key, std::string* value) {
  if (!j.contains(key)) return Status::Error(path + ": missing field '" + key + "'");
  if (!j[key].is_string()) return Status::Error(path + ": field '" + key + "' is not a string");
  *value = j[key].get<std::string>();
  return Status::Ok();
}

}  // namespace

bool IsValidPrototypeName(const std::string& name) {
  if (name.empty() || name.size() > 64) return false;
  return std::all_of(name.begin(), name.end(),
                     [](char c) { return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' || c == '-'; });
}

Status DefaultsForCategory(const std::string& category, CategoryDefaults* d) {
  // Gu et al. 2007, Fig. 2: dust has no interface with air (n2 = n1 = 1); g at the middle of
  // the category's range. Albedo and the dirt/lipid indices are not measured by thinslab:
  // typical values (water deposits ~1.33, skin lipids ~1.47), docs/models/contamination_synthesis.md.
  if (category == "dust") {
    *d = {0.65, 0.5, 1.0};
  } else if (category == "dirt") {
    *d = {0.4, 0.3, 1.33};
  } else if (category == "lipid") {
    *d = {0.85, 0.8, 1.47};
  } else {
    return Status::Error("category '" + category + "' is not one of dust, dirt, lipid (Gu et al. 2007, Fig. 2)");
  }
  return Status::Ok();
}

Status Prototype::Check(const std::string& where) const {
  const std::string w = where + ": ";
  if (!IsValidPrototypeName(name)) {
    return Status::Error(w + "name '" + name + "' must be 1-64 characters of [a-z0-9_-]");
  }
  CategoryDefaults unused;
  THINSLAB_RETURN_IF_ERROR(DefaultsForCategory(category, &unused).WithContext(where));
  if (!(g > -1 && g < 1)) return Status::Error(w + "g = " + Num(g) + ". Violated constraint: -1 < g < 1");
  if (!(sigma_g >= 0 && std::isfinite(sigma_g)))
    return Status::Error(w + "sigma_g = " + Num(sigma_g) + ". Violated constraint: >= 0");
  if (!(albedo >= 0 && albedo <= 1))
    return Status::Error(w + "albedo = " + Num(albedo) + ". Violated constraint: in [0, 1]");
  if (!(n2 >= 1 && n2 <= 3)) return Status::Error(w + "n2 = " + Num(n2) + ". Violated constraint: in [1, 3]");
  if (!(pixel_pitch_m > 0 && std::isfinite(pixel_pitch_m))) {
    return Status::Error(w + "pixel_pitch_m = " + Num(pixel_pitch_m) + ". Violated constraint: > 0");
  }
  if (tau.width() < 8 || tau.height() < 8) {
    return Status::Error(w + "tau map is " + std::to_string(tau.width()) + "x" + std::to_string(tau.height()) +
                         "; a prototype needs at least 8x8 pixels");
  }
  if (tau.num_channels() != 1) return Status::Error(w + "tau map must have exactly one channel 'tau'");
  double max_tau = 0;
  for (int y = 0; y < tau.height(); ++y) {
    for (int x = 0; x < tau.width(); ++x) {
      const float v = tau.at(x, y);
      if (!std::isfinite(v) || v < 0) {
        return Status::Error(w + "tau at pixel (" + std::to_string(x) + ", " + std::to_string(y) + ") is " + Num(v) +
                             "; tau must be finite and >= 0");
      }
      max_tau = std::max(max_tau, static_cast<double>(v));
    }
  }
  if (max_tau <= 0) return Status::Error(w + "tau map is zero everywhere: no contaminant to synthesize from");
  return Status::Ok();
}

Status ReadPrototype(const std::string& dir, Prototype* p) {
  const std::string manifest = JoinPath(dir, kPrototypeManifestName);
  nlohmann::json j;
  THINSLAB_RETURN_IF_ERROR(ReadJson(manifest, &j));
  std::string format, version;
  THINSLAB_RETURN_IF_ERROR(GetString(j, manifest, "format", &format));
  if (format != "thinslab-prototype")
    return Status::Error(manifest + ": format is '" + format + "', expected 'thinslab-prototype'");
  THINSLAB_RETURN_IF_ERROR(GetString(j, manifest, "format_version", &version));
  if (version.rfind("1.", 0) != 0)
    return Status::Error(manifest + ": format_version '" + version + "' is not supported (need 1.x)");
  *p = Prototype();
  THINSLAB_RETURN_IF_ERROR(GetString(j, manifest, "name", &p->name));
  THINSLAB_RETURN_IF_ERROR(GetString(j, manifest, "category", &p->category));
  THINSLAB_RETURN_IF_ERROR(GetNumber(j, manifest, "g", &p->g));
  THINSLAB_RETURN_IF_ERROR(GetNumber(j, manifest, "albedo", &p->albedo));
  THINSLAB_RETURN_IF_ERROR(GetNumber(j, manifest, "n2", &p->n2));
  THINSLAB_RETURN_IF_ERROR(GetNumber(j, manifest, "pixel_pitch_m", &p->pixel_pitch_m));
  if (j.contains("sigma_g")) THINSLAB_RETURN_IF_ERROR(GetNumber(j, manifest, "sigma_g", &p->sigma_g));
  if (j.contains("g_source")) THINSLAB_RETURN_IF_ERROR(GetString(j, manifest, "g_source", &p->g_source));
  if (j.contains("albedo_source")) THINSLAB_RETURN_IF_ERROR(GetString(j, manifest, "albedo_source", &p->albedo_source));
  if (j.contains("n2_source")) THINSLAB_RETURN_IF_ERROR(GetString(j, manifest, "n2_source", &p->n2_source));
  if (j.contains("provenance")) THINSLAB_RETURN_IF_ERROR(GetString(j, manifest, "provenance", &p->provenance));
  const std::string folder = std::filesystem::path(dir).lexically_normal().filename().string();
  const std::string folder_name =
      folder.empty() ? std::filesystem::path(dir).parent_path().filename().string() : folder;
  if (p->name != folder_name) {
    return Status::Error(manifest + ": name '" + p->name + "' differs from its folder name '" + folder_name + "'");
  }
  const std::string tau_path = JoinPath(dir, kPrototypeTauName);
  Image image;
  THINSLAB_RETURN_IF_ERROR(ReadExr(tau_path, &image));
  const int c = image.ChannelIndex("tau");
  if (c < 0) return Status::Error(tau_path + ": no channel 'tau'");
  p->tau = image.Channel(c);
  p->tau.attributes() = image.attributes();
  return p->Check(manifest);
}

Status ReadPrototypeLibrary(const std::string& library_dir, std::vector<Prototype>* prototypes) {
  prototypes->clear();
  if (!DirectoryExists(library_dir)) return Status::Error(library_dir + ": prototype library folder does not exist");
  std::vector<std::string> dirs;
  std::error_code ec;
  for (const auto& entry : std::filesystem::directory_iterator(library_dir, ec)) {
    if (entry.is_directory() && FileExists(JoinPath(entry.path().string(), kPrototypeManifestName))) {
      dirs.push_back(entry.path().string());
    }
  }
  if (ec) return Status::Error(library_dir + ": cannot list folder: " + ec.message());
  std::sort(dirs.begin(), dirs.end());
  for (const auto& d : dirs) {
    Prototype p;
    THINSLAB_RETURN_IF_ERROR(ReadPrototype(d, &p));
    prototypes->push_back(std::move(p));
  }
  if (prototypes->empty()) return Status::Error(library_dir + ": no prototype (no sub-folder with prototype.json)");
  return Status::Ok();
}

Status WritePrototype(const std::string& library_dir, const Prototype& p, bool overwrite) {
  THINSLAB_RETURN_IF_ERROR(p.Check("Prototype '" + p.name + "'"));
  const std::string dir = JoinPath(library_dir, p.name);
  if (DirectoryExists(dir) && !overwrite) {
    return Status::Error(dir + ": prototype already exists (use --overwrite to replace it)");
  }
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(library_dir));
  nlohmann::json j;
  j["format"] = "thinslab-prototype";
  j["format_version"] = "1.0";
  j["name"] = p.name;
  j["category"] = p.category;
  j["g"] = p.g;
  j["sigma_g"] = p.sigma_g;
  j["albedo"] = p.albedo;
  j["n2"] = p.n2;
  j["pixel_pitch_m"] = p.pixel_pitch_m;
  j["g_source"] = p.g_source;
  j["albedo_source"] = p.albedo_source;
  j["n2_source"] = p.n2_source;
  j["provenance"] = p.provenance;
  j["size_px"] = {p.tau.width(), p.tau.height()};
  j["thinslab_version"] = THINSLAB_VERSION_STRING;
  j["git_hash"] = THINSLAB_GIT_HASH;
  StagedDirectory out(dir, "synth add-prototype");
  THINSLAB_RETURN_IF_ERROR(out.Init());
  Image tau = p.tau;
  tau.attributes()["prototype"] = p.name;
  tau.attributes()["category"] = p.category;
  tau.numeric_attributes()["pixel_pitch_m"] = {p.pixel_pitch_m};
  THINSLAB_RETURN_IF_ERROR(WriteMapExr(JoinPath(out.path(), kPrototypeTauName), tau, {"tau", {}},
                                       {"synth add-prototype", p.provenance, "", ""}));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), kPrototypeManifestName), j.dump(2) + "\n"));
  return out.Commit();
}

bool PrototypeFromFitOptions::Check(std::string* error) const {
  std::ostringstream e;
  if (fit_tau_dir.empty())
    e << "PrototypeFromFitOptions::fit_tau_dir is empty (a `thinslab fit tau` output folder)";
  else if (!IsValidPrototypeName(name))
    e << "PrototypeFromFitOptions::name = '" << name << "'. Violated constraint: 1-64 characters of [a-z0-9_-]";
  else if (crop_x < 0 || crop_y < 0 || crop_width < 0 || crop_height < 0)
    e << "PrototypeFromFitOptions::crop has a negative value";
  else if ((crop_width == 0) != (crop_height == 0))
    e << "PrototypeFromFitOptions::crop width and height must both be 0 or both > 0";
  else if (!(tau_floor >= 0 && tau_floor < 10))
    e << "PrototypeFromFitOptions::tau_floor = " << tau_floor << ". Violated constraint: in [0, 10)";
  else if (!(max_masked_fraction >= 0 && max_masked_fraction <= 1))
    e << "PrototypeFromFitOptions::max_masked_fraction = " << max_masked_fraction << ". Violated constraint: in [0, 1]";
  if (e.str().empty()) return true;
  *error = e.str();
  return false;
}

Status PrototypeFromFit(const PrototypeFromFitOptions& o, Prototype* p) {
  std::string error;
  if (!o.Check(&error)) return Status::Error(error);
  *p = Prototype();
  p->name = o.name;

  // The tau fit: tau.exr (channels tau, status) and summary.json (result success).
  const std::string tau_summary_path = JoinPath(o.fit_tau_dir, "summary.json");
  nlohmann::json tau_summary;
  THINSLAB_RETURN_IF_ERROR(ReadJson(tau_summary_path, &tau_summary));
  std::string result;
  THINSLAB_RETURN_IF_ERROR(GetString(tau_summary, tau_summary_path, "result", &result));
  if (result != "success")
    return Status::Error(tau_summary_path + ": result is '" + result +
                         "'; only a successful tau fit can become a prototype");
  const std::string tau_path = JoinPath(o.fit_tau_dir, "tau.exr");
  Image map;
  THINSLAB_RETURN_IF_ERROR(ReadExr(tau_path, &map));
  const int tc = map.ChannelIndex("tau"), sc = map.ChannelIndex("status");
  if (tc < 0 || sc < 0)
    return Status::Error(tau_path + ": needs channels 'tau' and 'status' (a `thinslab fit tau` map)");
  const std::vector<double>* pitch = map.NumericAttribute("pixel_pitch_m", 1);
  if (pitch == nullptr) return Status::Error(tau_path + ": missing numeric header attribute 'pixel_pitch_m'");
  p->pixel_pitch_m = (*pitch)[0];
  int x0 = o.crop_x, y0 = o.crop_y, w = o.crop_width, h = o.crop_height;
  if (w == 0) {
    x0 = y0 = 0;
    w = map.width();
    h = map.height();
  }
  if (x0 + w > map.width() || y0 + h > map.height()) {
    return Status::Error(tau_path + ": crop (--crop) " + std::to_string(x0) + "," + std::to_string(y0) + "," +
                         std::to_string(w) + "," + std::to_string(h) + " lies outside the " +
                         std::to_string(map.width()) + "x" + std::to_string(map.height()) + " map");
  }
  p->tau = Image(w, h, {"tau"});
  int64_t masked = 0;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const float status = map.at(x0 + x, y0 + y, sc);
      float v = map.at(x0 + x, y0 + y, tc);
      if (status >= 1 && status <= 3) {  // docs/format.md 9.2: masked, no measurement.
        ++masked;
        v = 0;
      }
      if (v < o.tau_floor) v = 0;
      p->tau.at(x, y) = v;
    }
  }
  const double masked_fraction = static_cast<double>(masked) / (static_cast<double>(w) * h);
  if (masked_fraction > o.max_masked_fraction) {
    std::ostringstream msg;
    msg << tau_path << ": " << 100 * masked_fraction << "% of the cropped pixels are masked (status 1-3), more than "
        << 100 * o.max_masked_fraction << "%; choose a crop inside the measured region (--crop)";
    return Status::Error(msg.str());
  }

  // The phase fit (optional): g, sigma_g and the category consistent with g (Fig. 2).
  bool have_phase = false;
  double phase_g = 0, phase_sigma_g = 0;
  std::string phase_category;
  if (!o.fit_phase_dir.empty()) {
    const std::string path = JoinPath(o.fit_phase_dir, "summary.json");
    nlohmann::json j;
    THINSLAB_RETURN_IF_ERROR(ReadJson(path, &j));
    std::string model, phase_result;
    THINSLAB_RETURN_IF_ERROR(GetString(j, path, "model", &model));
    if (model != "gu2007_eq8")
      return Status::Error(path + ": model is '" + model + "', expected 'gu2007_eq8' (a `thinslab fit phase` summary)");
    THINSLAB_RETURN_IF_ERROR(GetString(j, path, "result", &phase_result));
    if (phase_result != "success")
      return Status::Error(path + ": result is '" + phase_result + "'; it carries no usable g");
    THINSLAB_RETURN_IF_ERROR(GetNumber(j, path, "g", &phase_g));
    if (j.contains("sigma_g")) THINSLAB_RETURN_IF_ERROR(GetNumber(j, path, "sigma_g", &phase_sigma_g));
    if (j.contains("categories") && j["categories"].is_array() && !j["categories"].empty() &&
        j["categories"][0].is_string()) {
      phase_category = j["categories"][0].get<std::string>();
    }
    have_phase = true;
  }
  p->category = !o.category.empty() ? o.category : phase_category;
  if (p->category.empty()) {
    return Status::Error(
        "PrototypeFromFitOptions::category is not given and no `fit phase` category is available (--category "
        "dust|dirt|lipid)");
  }
  CategoryDefaults defaults;
  THINSLAB_RETURN_IF_ERROR(
      DefaultsForCategory(p->category, &defaults).WithContext("PrototypeFromFitOptions::category"));
  if (o.g > -1 && o.g < 1) {
    p->g = o.g;
    p->g_source = "option";
  } else if (o.g != -2) {
    return Status::Error("PrototypeFromFitOptions::g = " + Num(o.g) + ". Violated constraint: -1 < g < 1");
  } else if (have_phase) {
    p->g = phase_g;
    p->sigma_g = phase_sigma_g;
    p->g_source = "fit_phase";
  } else {
    p->g = defaults.g;
    p->g_source = "category_default";
  }
  if (o.albedo >= 0) {
    p->albedo = o.albedo;
    p->albedo_source = "option";
  } else {
    p->albedo = defaults.albedo;
    p->albedo_source = "category_default";
  }
  if (o.n2 >= 1) {
    p->n2 = o.n2;
    p->n2_source = "option";
  } else if (o.n2 != 0) {
    return Status::Error("PrototypeFromFitOptions::n2 = " + Num(o.n2) + ". Violated constraint: in [1, 3]");
  } else {
    p->n2 = defaults.n2;
    p->n2_source = "category_default";
  }
  std::ostringstream prov;
  prov << "tau: " << tau_path << " crop " << x0 << "," << y0 << "," << w << "," << h << " (tau_floor " << o.tau_floor
       << ")";
  const auto src = map.attributes().find("source_session");
  if (src != map.attributes().end()) prov << ", session " << src->second;
  if (have_phase) prov << "; g: " << JoinPath(o.fit_phase_dir, "summary.json");
  p->provenance = prov.str();
  return p->Check("prototype from " + o.fit_tau_dir);
}

}  // namespace thinslab
