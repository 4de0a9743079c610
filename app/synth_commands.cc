// SPDX-License-Identifier: Apache-2.0
// `thinslab synth`: the contamination synthesis tool of Gu et al. 2007, Sec. 5.3
// (docs/models/contamination_synthesis.md): a prototype library built from `fit tau` /
// `fit phase` results, layer synthesis, and a pane preview of the canonical scenes of Fig. 8.
#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "thinslab/app/commands.h"
#include "thinslab/app/subcommands.h"
#include "thinslab/app/data_directory.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/core/output_guard.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/false_color.h"
#include "thinslab/core/file.h"
#include "thinslab/core/version.h"
#include "thinslab/synth/layer_synthesis.h"
#include "thinslab/synth/pane_preview.h"
#include "thinslab/synth/prototype_library.h"
#include "thinslab/pipeline/folder_report.h"

namespace thinslab {
namespace {

Status ParseCrop(const std::string& text, PrototypeFromFitOptions* o) {
  if (text.empty()) return Status::Ok();
  int x, y, w, h;
  char tail;
  if (std::sscanf(text.c_str(), "%d,%d,%d,%d%c", &x, &y, &w, &h, &tail) != 4 || w <= 0 || h <= 0) {
    return Status::Error("--crop '" + text + "': expected x,y,width,height in map pixels (width, height > 0)");
  }
  o->crop_x = x;
  o->crop_y = y;
  o->crop_width = w;
  o->crop_height = h;
  return Status::Ok();
}

std::vector<std::string> SplitCommas(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (!item.empty()) out.push_back(item);
  }
  return out;
}

// A small viewable copy of the tau channel (box-filtered to at most 1024 px per side).
Status WriteLayerFalseColor(const std::string& path, const Image& layer) {
  const int f = std::max(1, (std::max(layer.width(), layer.height()) + 1023) / 1024);
  const int w = (layer.width() + f - 1) / f, h = (layer.height() + f - 1) / f;
  const int c = layer.ChannelIndex("tau");
  Image small(w, h, {"tau"});
  double max_tau = 0.1;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      double sum = 0;
      int n = 0;
      for (int yy = y * f; yy < std::min(layer.height(), (y + 1) * f); ++yy) {
        for (int xx = x * f; xx < std::min(layer.width(), (x + 1) * f); ++xx, ++n) sum += layer.at(xx, yy, c);
      }
      small.at(x, y) = static_cast<float>(sum / n);
      max_tau = std::max(max_tau, sum / n);
    }
  }
  FalseColorOptions color;
  color.label = "tau";
  color.max_value = max_tau;
  color.scale = w < 256 ? 2 : 1;
  return WriteFalseColorPng(path, small, 0, nullptr, color);
}

std::string PanelsJson(const std::vector<PanePreviewPanel>& panels) {
  nlohmann::json j;
  j["format"] = "thinslab-pane-preview";
  j["format_version"] = "1.0";
  j["scenes"] = nlohmann::json::array();
  for (const auto& p : panels) {
    j["scenes"].push_back({{"scene", p.scene},
                           {"contrast_bright_background", p.contrast_bright_background},
                           {"contrast_dark_background", p.contrast_dark_background}});
  }
  return j.dump(2) + "\n";
}

// A --width / --height value, checked before anything runs so that the message names it.
Status CheckSideOption(const std::string& option, int value_px) {
  if (value_px >= 1 && value_px <= kMaxSynthesisSidePx) return Status::Ok();
  return Status::Error("--" + option + " " + std::to_string(value_px) + " is impossible: each side must be in [1, " +
                       std::to_string(kMaxSynthesisSidePx) + "] px");
}

int RunAddPrototype(int argc, char** argv) {
  PrototypeFromFitOptions o;
  std::string library, crop;
  bool overwrite = false;
  OptionParser parser("synth add-prototype");
  parser.AddPositional("LIBRARY", &library, "prototype library folder (created if absent)");
  parser.AddString("fit-tau", &o.fit_tau_dir, "`thinslab fit tau` output folder (tau.exr, summary.json)");
  parser.AddString("fit-phase", &o.fit_phase_dir,
                   "optional `thinslab fit phase` output folder (summary.json: g, category)");
  parser.AddString("name", &o.name, "prototype name, [a-z0-9_-]");
  parser.AddString("category", &o.category, "dust, dirt or lipid (default: the fit phase category)");
  parser.AddDouble("g", &o.g, "HG g (default: fit phase, else the category default)");
  parser.AddDouble("albedo", &o.albedo, "single-scattering albedo [0, 1] (default: category default)");
  parser.AddDouble("n2", &o.n2, "refractive index of the contaminant [1, 3] (default: category default)");
  parser.AddString("crop", &crop, "x,y,width,height of the tau map to keep (default: all)");
  parser.AddDouble("tau-floor", &o.tau_floor, "fitted tau below this becomes 0 (noise floor)");
  parser.AddDouble("max-masked-fraction", &o.max_masked_fraction, "largest share of masked pixels in the crop");
  parser.AddBool("overwrite", &overwrite, "replace an existing prototype of that name");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status = ParseCrop(crop, &o);
  // The library (and the prototype folder in it) must stay out of the fits it is made from.
  if (status.ok() && !library.empty()) {
    status = CheckOutputOutsideInputs(library, {{o.fit_tau_dir, {}}, {o.fit_phase_dir, {}}});
  }
  Prototype p;
  if (status.ok()) status = PrototypeFromFit(o, &p);
  if (status.ok()) status = WritePrototype(library, p, overwrite);
  if (!status.ok()) return CommandFailed(status);
  std::cout << "added prototype " << p.name << " (" << p.category << ", " << p.tau.width() << "x" << p.tau.height()
            << " px, g=" << p.g << " [" << p.g_source << "], albedo=" << p.albedo << " [" << p.albedo_source
            << "], n2=" << p.n2 << " [" << p.n2_source << "]) to " << library << "\n";
  return 0;
}

int RunList(int argc, char** argv) {
  std::string library;
  OptionParser parser("synth list");
  parser.AddPositional("LIBRARY", &library, "prototype library folder");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  std::vector<Prototype> prototypes;
  if (status.ok()) status = ReadPrototypeLibrary(library, &prototypes);
  if (!status.ok()) return CommandFailed(status);
  for (const auto& p : prototypes) {
    std::cout << p.name << "  " << p.category << "  " << p.tau.width() << "x" << p.tau.height() << " px @ "
              << p.pixel_pitch_m * 1e6 << " um  g=" << p.g << "  albedo=" << p.albedo << "  n2=" << p.n2 << "\n";
  }
  return 0;
}

int RunLayer(int argc, char** argv) {
  SynthesisOptions options;
  std::string library, out_dir, spec_path, prototypes, background_path;
  double density = -1;
  int width = -1, height = -1, preview_px = 512;  // -1: not given.
  std::string seed_text;
  bool preview = true;
  OptionParser parser("synth layer");
  parser.AddPositional("OUT", &out_dir, "output folder (layer.exr, previews, summary.json, options.ini)");
  parser.AddString("library", &library, "prototype library folder (default: the bundled data/prototypes)");
  parser.AddString("spec", &spec_path, "synthesis spec JSON (docs/format.md); or use --prototypes");
  parser.AddString("prototypes", &prototypes,
                   "comma-separated prototype names, bottom layer first (category defaults)");
  parser.AddDouble("density", &density, "density for every --prototypes layer (default: category default)");
  parser.AddInt("width", &width, "output width [px]; -1 = the spec's, else 1024");
  parser.AddInt("height", &height, "output height [px]; -1 = the spec's, else 1024");
  parser.AddString("seed", &seed_text, "random seed, non-negative integer; empty = the spec's, else 1");
  parser.AddDouble("pixel-pitch-m", &options.pixel_pitch_m, "output pitch [m]; 0 = the first prototype's");
  parser.AddBool("preview", &preview, "also render pane_preview.png (Fig. 8 scenes)");
  parser.AddInt("preview-px", &preview_px, "largest side of each preview panel [px]");
  parser.AddString("background", &background_path, "background image for the pane preview (default: procedural)");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  if (library.empty()) library = DataDirectory() + "/prototypes";
  if (status.ok() && spec_path.empty() == prototypes.empty()) {
    status = Status::Error("synth layer: give exactly one of --spec FILE or --prototypes a,b,c");
  }
  if (status.ok() && parser.IsSet("density") && !(density >= 0 && density <= 1e6)) {
    status = Status::Error("--density " + std::to_string(density) + ": must be >= 0 (layers per unit area, "
                           "docs/format.md synthesis spec)");
  }
  if (status.ok() && !spec_path.empty()) status = ReadSynthesisSpec(spec_path, &options);
  if (status.ok() && !prototypes.empty()) {
    for (const auto& name : SplitCommas(prototypes)) {
      SynthLayerSpec spec;
      spec.prototype = name;
      spec.density = density;
      options.layers.push_back(spec);
    }
  }
  if (status.ok() && width != -1) status = CheckSideOption("width", width);
  if (status.ok() && height != -1) status = CheckSideOption("height", height);
  if (status.ok() && preview && preview_px < 8) {
    status = Status::Error("--preview-px " + std::to_string(preview_px) + ": must be >= 8");
  }
  if (width != -1) options.width_px = width;
  if (height != -1) options.height_px = height;
  if (status.ok() && static_cast<int64_t>(options.width_px) * options.height_px > kMaxSynthesisPixels) {
    status =
        Status::Error("--width " + std::to_string(options.width_px) + " --height " + std::to_string(options.height_px) +
                      (spec_path.empty() ? "" : " (or " + spec_path + ")") + ": more than 2^26 pixels (8192x8192)");
  }
  if (status.ok() && !seed_text.empty()) {
    char* end = nullptr;
    errno = 0;
    const unsigned long long value = std::strtoull(seed_text.c_str(), &end, 10);
    if (errno != 0 || end == seed_text.c_str() || *end != '\0' || seed_text[0] == '-') {
      status = Status::Error("--seed '" + seed_text + "': expected a non-negative integer");
    } else {
      options.seed = value;
    }
  }
  std::vector<Prototype> library_prototypes;
  if (status.ok()) status = ReadPrototypeLibrary(library, &library_prototypes);
  Image layer;
  SynthesisSummary summary;
  // Errors name where the layers came from (an unknown prototype, a bad density).
  const std::string layers_from = spec_path.empty() ? "--prototypes " + prototypes : spec_path;
  if (status.ok()) {
    status = SynthesizeContamination(library_prototypes, options, &layer, &summary)
                 .WithContext(layers_from + " (library " + library + ")");
  }
  Image background;
  if (status.ok() && !background_path.empty()) status = ReadBackgroundImage(background_path, &background);
  std::vector<PanePreviewPanel> panels;
  if (status.ok()) {
    const std::string ini = parser.ToIni();
    StagedDirectory out(out_dir, "synth layer", {{library, {}}, {spec_path, {}}, {background_path, {}}});
    status = out.Init();
    layer.numeric_attributes()["pixel_pitch_m"] = {summary.pixel_pitch_m};
    layer.attributes()["seed"] = std::to_string(options.seed);
    layer.attributes()["model"] = "gu2007_sec5.3_synthesis";
    std::string names;
    for (const auto& l : options.layers) names += (names.empty() ? "" : ",") + l.prototype;
    layer.attributes()["prototypes"] = names;
    layer.attributes()["source_library"] = library;
    const Provenance provenance{"synth layer", library, "", ini};
    if (status.ok()) status = WriteMapExr(JoinPath(out.path(), "layer.exr"), layer, {"tau", {}}, provenance);
    if (status.ok()) status = WriteLayerFalseColor(JoinPath(out.path(), "layer_preview.png"), layer);
    if (status.ok() && preview) {
      PanePreviewOptions preview_options;
      preview_options.max_size_px = preview_px;
      status = WritePanePreview(JoinPath(out.path(), "pane_preview.png"), layer, background, preview_options, &panels);
      if (status.ok()) status = WriteFileAtomically(JoinPath(out.path(), "pane_preview.json"), PanelsJson(panels));
    }
    if (status.ok()) {
      nlohmann::ordered_json summary_json = nlohmann::ordered_json::parse(summary.ToJson());
      summary_json["provenance"] = ProvenanceJson(provenance);
      status = WriteFileAtomically(JoinPath(out.path(), "summary.json"), summary_json.dump(2) + "\n");
    }
    if (status.ok()) status = WriteFileAtomically(JoinPath(out.path(), "options.ini"), ini);
    if (status.ok()) status = WriteFolderReport(out.path(), out_dir, "thinslab synth layer: " + layers_from);
    if (status.ok()) status = out.Commit();
  }
  if (!status.ok()) return CommandFailed(status);
  std::cout << "synthesized " << options.width_px << "x" << options.height_px << " layer from " << options.layers.size()
            << " prototype(s) in " << summary.total_s << " s (covered " << 100 * summary.covered_fraction
            << "%, mean tau " << summary.mean_tau << ")\nwrote " << out_dir << "\n";
  return 0;
}

int RunPreview(int argc, char** argv) {
  std::string layer_path, out_path, background_path;
  PanePreviewOptions options;
  OptionParser parser("synth preview");
  parser.AddPositional("LAYER", &layer_path, "synthesized layer EXR (channels tau, g, albedo, n2)");
  parser.AddString("out", &out_path,
                   "PNG to write (default: LAYER with _pane.png); a .json with the contrasts is written next to it");
  parser.AddString("background", &background_path, "background image (PNG/JPEG/EXR); default: procedural");
  parser.AddInt("max-size-px", &options.max_size_px, "largest side of each panel [px]");
  parser.AddDouble("glass-index", &options.glass_index, "refractive index of the pane");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  if (out_path.empty()) out_path = layer_path + "_pane.png";
  const std::string json_path =
      out_path.size() > 4 ? out_path.substr(0, out_path.size() - 4) + ".json" : out_path + ".json";
  const std::vector<InputPath> inputs = {{layer_path, {}}, {background_path, {}}};
  if (status.ok()) status = CheckOutputFile(out_path, inputs);
  if (status.ok()) status = CheckOutputFile(json_path, inputs);
  Image layer, background;
  if (status.ok()) status = ReadExr(layer_path, &layer);
  if (status.ok()) status = CheckContaminationLayer(layer, layer_path);
  if (status.ok() && !background_path.empty()) status = ReadBackgroundImage(background_path, &background);
  std::vector<PanePreviewPanel> panels;
  if (status.ok()) status = WritePanePreview(out_path, layer, background, options, &panels);
  if (status.ok()) status = WriteFileAtomically(json_path, PanelsJson(panels));
  if (!status.ok()) return CommandFailed(status);
  for (const auto& p : panels) {
    std::cout << p.scene << ": contaminated / clean = " << p.contrast_bright_background << " (bright background), "
              << p.contrast_dark_background << " (dark background)\n";
  }
  std::cout << "wrote " << out_path << " and " << json_path << "\n";
  return 0;
}

}  // namespace

const std::vector<Subcommand>& SynthSubcommands() {
  static const std::vector<Subcommand> table = {
      {"layer", RunLayer, "OUT", "synthesize a contamination layer from library prototypes (Gu Sec. 5.3)"},
      {"add-prototype", RunAddPrototype, "LIBRARY", "add a prototype to a library from a fit tau (and fit phase) output"},
      {"preview", RunPreview, "LAYER.exr", "render a layer on a window pane (Gu Fig. 8 scenes)"},
      {"list", RunList, "[LIBRARY]", "list a library's prototypes"},
  };
  return table;
}

int RunSynth(int argc, char** argv) { return DispatchSubcommand("synth", SynthSubcommands(), argc, argv); }

}  // namespace thinslab
