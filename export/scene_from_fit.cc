// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/scene_from_fit.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>
#include <sstream>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/provenance.h"
#include "thinslab/pipeline/layer_from_phase.h"

namespace thinslab {

namespace {

constexpr double kDefaultSlabThicknessM = 1e-3;
constexpr double kDefaultBacklightDistanceM = 0.02;
constexpr double kNoNumber = -1e300;

// The number at JSON pointer `pointer`, or `fallback` where the path is absent or holds another
// type (a summary edited by hand must not throw).
double NumberAt(const nlohmann::json& j, const std::string& pointer, double fallback) {
  const nlohmann::json::json_pointer path(pointer);
  if (!j.contains(path) || !j.at(path).is_number()) return fallback;
  return j.at(path).get<double>();
}

std::string Fixed(double value, int digits) {
  std::ostringstream s;
  s.setf(std::ios::fixed);
  s.precision(digits);
  s << value;
  return s.str();
}

Status CheckRange(const std::string& field, const std::string& option, double value, double lo, double hi) {
  if (!(value >= lo && value <= hi)) {
    return Status::Error("ExportOptions::" + field + " (--" + option + "): must be in [" + Fixed(lo, 4) + ", " +
                         Fixed(hi, 4) + "], got " + std::to_string(value));
  }
  return Status::Ok();
}

// The camera: the fit's rig pose when it recorded one, else straight above the grid.
void PlaceCamera(const Image& map, const ExportOptions& options, RenderScene* scene) {
  Rigid3d cam_from_sample;
  if (GetWorldToCamera(map, &cam_from_sample)) {
    scene->cam_from_sample = cam_from_sample;
  } else {
    scene->cam_from_sample = CameraAbove(scene->grid, 2 * scene->grid.size_m().maxCoeff());
    scene->notes.push_back("the fit recorded no camera pose (worldToCamera): the camera looks straight down");
  }
  scene->image_width = options.image_width;
  scene->image_height = options.image_height;
  scene->fov_x_rad = FramingFovX(scene->grid, scene->cam_from_sample, options.image_width, options.image_height);
}

// One channel of `map` as a single-channel image named Y (what the renderers' textures hold).
Image ChannelAsY(const Image& map, int channel) {
  Image y(map.width(), map.height(), {"Y"});
  y.data() = map.Channel(channel).data();
  return y;
}

void PlaceBacklight(double distance_m, RenderScene* scene) {
  scene->backlight_distance_m = distance_m;
  scene->backlight_half_size_m = scene->grid.size_m().maxCoeff() + 2 * distance_m;
}

Status ReadSlab(const std::string& fit_dir, const ExportOptions& options, RenderScene* scene) {
  const std::string maps_file = JoinPath(fit_dir, "maps.exr"), summary_file = JoinPath(fit_dir, "summary.json");
  Image maps;
  THINSLAB_RETURN_IF_ERROR(ReadExr(maps_file, &maps));
  std::vector<double> grid_min, pitch, eta;
  THINSLAB_RETURN_IF_ERROR(RequireNumericAttribute(maps, maps_file, "grid_min_m", 2, &grid_min));
  THINSLAB_RETURN_IF_ERROR(RequireNumericAttribute(maps, maps_file, "pixel_pitch_m", 1, &pitch));
  THINSLAB_RETURN_IF_ERROR(RequireNumericAttribute(maps, maps_file, "eta", 1, &eta));
  if (!(pitch[0] > 0) || !(eta[0] > 1)) return Status::Error(maps_file + ": needs pixel_pitch_m > 0 and eta > 1");
  int c_roughness, c_family, c_weight;
  for (const auto& [name, index] :
       {std::make_pair("equivalent_roughness", &c_roughness), std::make_pair("ndf_family", &c_family),
        std::make_pair("top_face_weight", &c_weight)}) {
    const Status found = RequireChannel(maps, maps_file, name, index);
    if (!found.ok()) return Status::Error(found.message() + " (fitted before the equivalent NDF existed? fit again)");
  }
  nlohmann::json summary;
  THINSLAB_RETURN_IF_ERROR(ReadJsonObjectFile(summary_file, "a `thinslab fit dmf` output", &summary));

  scene->grid = {maps.width(), maps.height(), Eigen::Vector2d(grid_min[0], grid_min[1]), pitch[0]};
  RoughSlab slab;
  slab.eta = eta[0];
  const double fit_thickness_m = NumberAt(summary, "/glass_thickness_m", 0.0);
  if (options.slab_thickness_mm >= 0) {
    slab.thickness_m = options.slab_thickness_mm * 1e-3;
  } else if (fit_thickness_m > 0) {
    slab.thickness_m = fit_thickness_m;
  } else {
    slab.thickness_m = kDefaultSlabThicknessM;
    scene->notes.push_back(
        "the fit's slab is infinitely thin (glass_thickness_m 0, Dai et al. 2009): exported 1 mm "
        "thick (--slab-thickness-mm)");
  }
  slab.top_alpha = Image(maps.width(), maps.height(), {"Y"}, static_cast<float>(options.min_alpha));
  slab.bottom_alpha = slab.top_alpha;
  int family_counts[3] = {0, 0, 0}, unfitted = 0;
  for (int row = 0; row < maps.height(); ++row) {
    for (int col = 0; col < maps.width(); ++col) {
      const double alpha = maps.at(col, row, c_roughness);
      const int family = std::clamp(static_cast<int>(std::lround(maps.at(col, row, c_family))), 0, 2);
      if (!(alpha > 0)) {  // Nothing fitted here (roughness 0): smooth glass.
        ++unfitted;
        continue;
      }
      ++family_counts[family];
      double top, bottom;
      SplitRoughness(alpha, maps.at(col, row, c_weight), options.min_alpha, &top, &bottom);
      slab.top_alpha.at(col, row) = static_cast<float>(top);
      slab.bottom_alpha.at(col, row) = static_cast<float>(bottom);
    }
  }
  const int fitted = maps.width() * maps.height() - unfitted;
  if (fitted == 0) return Status::Error(maps_file + ": no point has a fitted roughness (equivalent_roughness > 0)");
  // Renderers take one microfacet family per material: the one most fitted points chose.
  slab.distribution = family_counts[1] > family_counts[0] ? "beckmann" : "ggx";
  scene->notes.push_back("microfacet family " + slab.distribution + " for every point (fitted points: " +
                         std::to_string(family_counts[0]) + " GGX, " + std::to_string(family_counts[1]) +
                         " Beckmann, " + std::to_string(family_counts[2]) + " undecided)");
  if (unfitted > 0) {
    scene->notes.push_back(std::to_string(unfitted) + " of " + std::to_string(maps.width() * maps.height()) +
                           " points without a fit are smooth glass (alpha " + Fixed(options.min_alpha, 4) + ")");
  }
  scene->notes.push_back(
      "the tabulated NDF of each point is exported as its nearest analytic one "
      "(equivalent_roughness; its misfit: summary.json equivalent_ndf), split between the faces "
      "by Dai's top-face weight: alpha_top^2 = w alpha^2, alpha_bottom^2 = (1 - w) alpha^2");
  scene->slab = slab;

  double backlight_m = options.backlight_distance_mm * 1e-3;
  if (backlight_m < 0) {
    const double monitor_z = NumberAt(summary, "/monitor/sample_from_monitor/translation_m/2", 0.0);
    backlight_m = monitor_z < 0 ? -monitor_z : kDefaultBacklightDistanceM;
  }
  PlaceBacklight(backlight_m, scene);
  PlaceCamera(maps, options, scene);
  return Status::Ok();
}

// tau.exr of `fit tau`: the grid from region_min_m and the pitch; g and albedo from the fit's
// summary (its layer model), a `fit phase` or the options.
Status ReadTauLayer(const std::string& fit_dir, const ExportOptions& options, RenderScene* scene) {
  const std::string tau_file = JoinPath(fit_dir, "tau.exr"), summary_file = JoinPath(fit_dir, "summary.json");
  Image map;
  THINSLAB_RETURN_IF_ERROR(ReadExr(tau_file, &map));
  std::vector<double> region_min, pitch;
  THINSLAB_RETURN_IF_ERROR(RequireNumericAttribute(map, tau_file, "region_min_m", 2, &region_min));
  THINSLAB_RETURN_IF_ERROR(RequireNumericAttribute(map, tau_file, "pixel_pitch_m", 1, &pitch));
  if (!(pitch[0] > 0)) return Status::Error(tau_file + ": needs pixel_pitch_m > 0");
  int c_tau;
  THINSLAB_RETURN_IF_ERROR(RequireChannel(map, tau_file, "tau", &c_tau));
  scene->grid = {map.width(), map.height(), Eigen::Vector2d(region_min[0], region_min[1]), pitch[0]};
  ScatteringLayer layer;
  layer.tau = ChannelAsY(map, c_tau);

  nlohmann::json summary;
  THINSLAB_RETURN_IF_ERROR(ReadJsonObjectFile(summary_file, "a `thinslab fit tau` output", &summary));
  layer.g = NumberAt(summary, "/layer/g", kNoNumber);
  layer.albedo = NumberAt(summary, "/layer/albedo", kNoNumber);
  if (layer.g == kNoNumber || layer.albedo == kNoNumber) {
    return Status::Error(summary_file + ": layer.g and layer.albedo are missing (give --g and --albedo)");
  }
  std::string source = summary_file + " (the fit's layer model)";
  if (!options.phase_dir.empty()) {
    PhaseLayerChoice choice;
    THINSLAB_RETURN_IF_ERROR(ReadPhaseLayerChoice(options.phase_dir, &choice).WithContext("option --phase"));
    layer.g = choice.rung == 2 ? choice.g : 0.0;
    if (choice.rung == 0) layer.albedo = 0;  // The lobe fit saw no scattered light: an attenuator.
    source = choice.summary_path + " (ladder rung " + std::to_string(choice.rung) + ")";
  }
  scene->notes.push_back("layer g " + Fixed(layer.g, 3) + " and albedo " + Fixed(layer.albedo, 3) + " from " + source);
  scene->layer = layer;
  PlaceBacklight(options.backlight_distance_mm >= 0 ? options.backlight_distance_mm * 1e-3 : kDefaultBacklightDistanceM,
                 scene);
  PlaceCamera(map, options, scene);
  return Status::Ok();
}

// layer.exr of `synth layer`: per-pixel tau, g, albedo; renderers take one g and albedo per
// medium, so the tau-weighted means (the scattered light's).
Status ReadSynthLayer(const std::string& dir, const ExportOptions& options, RenderScene* scene) {
  const std::string file = JoinPath(dir, "layer.exr");
  Image map;
  THINSLAB_RETURN_IF_ERROR(ReadExr(file, &map));
  std::vector<double> pitch;
  THINSLAB_RETURN_IF_ERROR(RequireNumericAttribute(map, file, "pixel_pitch_m", 1, &pitch));
  if (!(pitch[0] > 0)) return Status::Error(file + ": needs pixel_pitch_m > 0");
  int c_tau, c_g, c_albedo;
  THINSLAB_RETURN_IF_ERROR(RequireChannel(map, file, "tau", &c_tau));
  THINSLAB_RETURN_IF_ERROR(RequireChannel(map, file, "g", &c_g));
  THINSLAB_RETURN_IF_ERROR(RequireChannel(map, file, "albedo", &c_albedo));
  SceneGrid grid{map.width(), map.height(), Eigen::Vector2d::Zero(), pitch[0]};
  grid.min_m = -0.5 * grid.size_m();  // A synthesized layer is centred on the sample origin.
  scene->grid = grid;
  ScatteringLayer layer;
  layer.tau = ChannelAsY(map, c_tau);
  double sum_tau = 0, sum_g = 0, sum_albedo = 0;
  for (int row = 0; row < map.height(); ++row) {
    for (int col = 0; col < map.width(); ++col) {
      const double tau = map.at(col, row, c_tau);
      sum_tau += tau;
      sum_g += tau * map.at(col, row, c_g);
      sum_albedo += tau * map.at(col, row, c_albedo);
    }
  }
  if (!(sum_tau > 0)) return Status::Error(file + ": tau is 0 everywhere: nothing to export");
  layer.g = sum_g / sum_tau;
  layer.albedo = sum_albedo / sum_tau;
  scene->notes.push_back("layer g " + Fixed(layer.g, 3) + " and albedo " + Fixed(layer.albedo, 3) +
                         ": tau-weighted means of layer.exr's maps (a renderer's medium takes one of each)");
  scene->layer = layer;
  PlaceBacklight(options.backlight_distance_mm >= 0 ? options.backlight_distance_mm * 1e-3 : kDefaultBacklightDistanceM,
                 scene);
  PlaceCamera(map, options, scene);
  return Status::Ok();
}

}  // namespace

Status ExportOptions::Check() const {
  if (!(slab_thickness_mm < 0)) {
    THINSLAB_RETURN_IF_ERROR(CheckRange("slab_thickness_mm", "slab-thickness-mm", slab_thickness_mm, 1e-3, 100));
  }
  THINSLAB_RETURN_IF_ERROR(CheckRange("min_alpha", "min-alpha", min_alpha, 1e-4, 0.1));
  THINSLAB_RETURN_IF_ERROR(CheckRange("layer_thickness_mm", "layer-thickness-mm", layer_thickness_mm, 1e-4, 10));
  THINSLAB_RETURN_IF_ERROR(CheckRange("glass_thickness_mm", "glass-thickness-mm", glass_thickness_mm, 1e-3, 100));
  THINSLAB_RETURN_IF_ERROR(CheckRange("glass_eta", "glass-eta", glass_eta, 1.0001, 4));
  if (g != kFromFit) THINSLAB_RETURN_IF_ERROR(CheckRange("g", "g", g, -0.99, 0.99));
  if (albedo != kFromFit) THINSLAB_RETURN_IF_ERROR(CheckRange("albedo", "albedo", albedo, 0, 1));
  if (!(backlight_distance_mm < 0)) {
    THINSLAB_RETURN_IF_ERROR(
        CheckRange("backlight_distance_mm", "backlight-distance-mm", backlight_distance_mm, 0.01, 10000));
  }
  THINSLAB_RETURN_IF_ERROR(CheckRange("image_width", "image-width", image_width, 16, 16384));
  THINSLAB_RETURN_IF_ERROR(CheckRange("image_height", "image-height", image_height, 16, 16384));
  return Status::Ok();
}

void SplitRoughness(double alpha, double top_face_weight, double min_alpha, double* top, double* bottom) {
  const double w = std::clamp(top_face_weight, 0.0, 1.0);
  *top = std::max(min_alpha, alpha * std::sqrt(w));
  *bottom = std::max(min_alpha, alpha * std::sqrt(1 - w));
}

Status SceneFromFit(const std::string& fit_dir, const ExportOptions& options, RenderScene* scene) {
  THINSLAB_RETURN_IF_ERROR(options.Check());
  *scene = RenderScene();
  scene->source = fit_dir;
  if (!DirectoryExists(fit_dir)) return Status::Error(fit_dir + ": not a folder (expected a fit output folder)");
  if (FileExists(JoinPath(fit_dir, "maps.exr"))) {
    if (!options.phase_dir.empty())
      return Status::Error("option --phase: applies to a `fit tau` folder, not a `fit dmf`");
    THINSLAB_RETURN_IF_ERROR(ReadSlab(fit_dir, options, scene));
  } else if (FileExists(JoinPath(fit_dir, "tau.exr"))) {
    THINSLAB_RETURN_IF_ERROR(ReadTauLayer(fit_dir, options, scene));
  } else if (FileExists(JoinPath(fit_dir, "layer.exr"))) {
    if (!options.phase_dir.empty()) return Status::Error("option --phase: applies to a `fit tau` folder, not a layer");
    THINSLAB_RETURN_IF_ERROR(ReadSynthLayer(fit_dir, options, scene));
  } else {
    return Status::Error(fit_dir + ": holds no maps.exr (fit dmf), tau.exr (fit tau) or layer.exr (synth layer)");
  }
  if (scene->layer) {
    ScatteringLayer& layer = *scene->layer;
    const bool given_g = options.g != ExportOptions::kFromFit, given_albedo = options.albedo != ExportOptions::kFromFit;
    if (given_g) layer.g = options.g;
    if (given_albedo) layer.albedo = options.albedo;
    if (given_g || given_albedo) {
      scene->notes.push_back("g " + Fixed(layer.g, 3) + ", albedo " + Fixed(layer.albedo, 3) +
                             " as given (--g, --albedo)");
    }
    layer.thickness_m = options.layer_thickness_mm * 1e-3;
    layer.glass_eta = options.glass_eta;
    layer.glass_thickness_m = options.glass_thickness_mm * 1e-3;
    for (int y = 0; y < layer.tau.height(); ++y) {
      for (int x = 0; x < layer.tau.width(); ++x) {
        float& tau = layer.tau.at(x, y);
        if (!std::isfinite(tau)) {
          return Status::Error(fit_dir + ": tau is not finite at map pixel (" + std::to_string(x) + ", " +
                               std::to_string(y) + ")");
        }
        tau = std::max(tau, 0.0f);
      }
    }
  }
  return Status::Ok();
}

}  // namespace thinslab
