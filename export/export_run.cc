// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/export_run.h"

#include <nlohmann/json.hpp>

#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/provenance.h"
#include "thinslab/export/blender_scene.h"
#include "thinslab/export/mitsuba_scene.h"
#include "thinslab/export/pbrt_scene.h"

namespace thinslab {

namespace {

struct Renderer {
  const char* name;
  const char* scene_file;
  Status (*write)(const RenderScene&, const std::string&, const Provenance&);
};

constexpr Renderer kRenderers[] = {{"mitsuba", "scene.xml", WriteMitsubaScene},
                                   {"pbrt", "scene.pbrt", WritePbrtScene},
                                   {"blender", "scene.py", WriteBlenderScene}};

nlohmann::json ExportSummary(const RenderScene& scene, const Renderer& renderer, const Provenance& provenance) {
  nlohmann::json j;
  j["format"] = "thinslab-export-summary";
  j["format_version"] = "1.0";
  j["renderer"] = renderer.name;
  j["scene_file"] = renderer.scene_file;
  j["source"] = scene.source;
  j["grid"] = {{"width", scene.grid.width},
               {"height", scene.grid.height},
               {"min_m", {scene.grid.min_m.x(), scene.grid.min_m.y()}},
               {"pixel_pitch_m", scene.grid.pitch_m}};
  if (scene.slab) {
    j["slab"] = {
        {"eta", scene.slab->eta},
        {"thickness_m", scene.slab->thickness_m},
        {"distribution", scene.slab->distribution},
        {"textures", {{"top_alpha", "textures/top_alpha.exr"}, {"bottom_alpha", "textures/bottom_alpha.exr"}}}};
  }
  if (scene.layer) {
    j["layer"] = {{"g", scene.layer->g},
                  {"albedo", scene.layer->albedo},
                  {"thickness_m", scene.layer->thickness_m},
                  {"glass_eta", scene.layer->glass_eta},
                  {"glass_thickness_m", scene.layer->glass_thickness_m},
                  {"textures", {{"tau", "textures/tau.exr"}}}};
  }
  j["backlight"] = {
      {"distance_m", scene.backlight_distance_m}, {"half_size_m", scene.backlight_half_size_m}, {"radiance", 1}};
  j["image"] = {
      {"width", scene.image_width}, {"height", scene.image_height}, {"fov_x_deg", scene.fov_x_rad * 180 / kPi}};
  j["notes"] = scene.notes;
  j["provenance"] = ProvenanceJson(provenance);
  return j;
}

}  // namespace

std::vector<std::string> ExportRenderers() {
  std::vector<std::string> names;
  for (const Renderer& r : kRenderers) names.push_back(r.name);
  return names;
}

Status ExportFit(const ExportRun& run, std::ostream& log) {
  const Renderer* renderer = nullptr;
  for (const Renderer& r : kRenderers) {
    if (run.renderer == r.name) renderer = &r;
  }
  if (renderer == nullptr) {
    std::string names;
    for (const std::string& name : ExportRenderers()) names += (names.empty() ? "" : ", ") + name;
    return Status::Error("RENDERER: '" + run.renderer + "' is not one of " + names);
  }
  if (run.out_dir.empty()) return Status::Error("OUT: an output folder is required");
  StagedDirectory out(run.out_dir, "export", {{run.fit_dir, {}}});
  THINSLAB_RETURN_IF_ERROR(out.Init());
  RenderScene scene;
  THINSLAB_RETURN_IF_ERROR(SceneFromFit(run.fit_dir, run.options, &scene));
  const Provenance provenance{std::string("export ") + renderer->name, run.fit_dir, "", run.options_ini};
  THINSLAB_RETURN_IF_ERROR(renderer->write(scene, out.path(), provenance));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "export.json"),
                                               ExportSummary(scene, *renderer, provenance).dump(2) + "\n"));
  if (!run.options_ini.empty()) {
    THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "options.ini"), run.options_ini));
  }
  THINSLAB_RETURN_IF_ERROR(out.Commit());
  log << "export " << renderer->name << ": " << JoinPath(run.out_dir, renderer->scene_file) << " ("
      << (scene.slab ? "rough slab, " + scene.slab->distribution : std::string("scattering layer")) << ", "
      << scene.grid.width << " x " << scene.grid.height << " texels)\n";
  for (const std::string& note : scene.notes) log << "  note: " << note << "\n";
  return Status::Ok();
}

}  // namespace thinslab
