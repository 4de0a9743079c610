// SPDX-License-Identifier: Apache-2.0
#include "thinslab/export/preview_run.h"

#include <algorithm>
#include <cmath>
#include <nlohmann/json.hpp>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/png_io.h"
#include "thinslab/core/provenance.h"
#include "thinslab/synth/pane_preview.h"

namespace thinslab {

namespace {

constexpr char kCommand[] = "preview";

// The layer as synth/pane_preview.h takes it: channels tau, g, albedo, n2.
Image PaneLayer(const ScatteringLayer& layer, double n2) {
  Image out(layer.tau.width(), layer.tau.height(), {"tau", "g", "albedo", "n2"});
  for (int y = 0; y < out.height(); ++y) {
    for (int x = 0; x < out.width(); ++x) {
      const float tau = layer.tau.at(x, y);
      out.at(x, y, 0) = tau;
      out.at(x, y, 1) = tau > 0 ? static_cast<float>(layer.g) : 0.0f;
      out.at(x, y, 2) = tau > 0 ? static_cast<float>(layer.albedo) : 0.0f;
      out.at(x, y, 3) = tau > 0 ? static_cast<float>(n2) : 1.0f;
    }
  }
  return out;
}

Status PreviewSlab(const PreviewRun& run, const std::string& dir, const Provenance& provenance, std::ostream& log,
                   nlohmann::json* summary) {
  DmfFitOnDisk fit;
  THINSLAB_RETURN_IF_ERROR(ReadDmfFit(run.fit_dir, &fit));
  Image view;
  THINSLAB_RETURN_IF_ERROR(RenderSlabPreview(fit, run.slab, &view));
  // Where the fit has a model: the contrast compares the sample with clean glass there.
  int fitted = 0;
  for (int y = 0; y < view.height(); ++y) {
    for (int x = 0; x < view.width(); ++x) fitted += view.at(x, y, 2) > 0;
  }
  const double clean = CheckerContrast(view, 1, 2), sample = CheckerContrast(view, 0, 2);
  const int scale = run.panel_scale > 0 ? run.panel_scale : std::max(1, 320 / std::max(view.width(), view.height()));
  THINSLAB_RETURN_IF_ERROR(WritePngAtomically(
      JoinPath(dir, "preview.png"), SideBySide({LabelledRadianceTile(view, 1, 1.0, "clean glass", scale),
                                                LabelledRadianceTile(view, 0, 1.0, "fitted sample", scale)})));
  Image exr = view;
  StampProvenance(provenance, &exr);
  exr.numeric_attributes()["checker_m"] = {run.slab.checker_m};
  exr.numeric_attributes()["backlight_distance_m"] = {run.slab.backlight_distance_m};
  THINSLAB_RETURN_IF_ERROR(WriteExr(JoinPath(dir, "preview.exr"), exr));
  (*summary)["kind"] = "slab";
  (*summary)["scene"] = {{"checker_m", run.slab.checker_m},
                         {"backlight_distance_m", run.slab.backlight_distance_m},
                         {"dark_square", run.slab.dark_square},
                         {"view", "orthographic, straight through the sample from +z"}};
  (*summary)["points"] = {{"width", view.width()}, {"height", view.height()}, {"with_model", fitted}};
  (*summary)["checker_contrast"] = {{"clean_glass", clean}, {"fitted_sample", sample}};
  log << "preview: checker contrast (std / mean over the " << fitted << " points with a model): clean glass " << clean
      << ", fitted sample " << sample << "\n";
  return Status::Ok();
}

Status PreviewLayer(const PreviewRun& run, const std::string& dir, std::ostream& log, nlohmann::json* summary) {
  RenderScene scene;
  THINSLAB_RETURN_IF_ERROR(SceneFromFit(run.fit_dir, run.layer, &scene));
  PanePreviewOptions options;
  options.glass_index = run.layer.glass_eta;
  std::vector<PanePreviewPanel> panels;
  THINSLAB_RETURN_IF_ERROR(
      WritePanePreview(JoinPath(dir, "preview.png"), PaneLayer(*scene.layer, run.layer_n2), Image(), options, &panels));
  (*summary)["kind"] = "layer";
  (*summary)["layer"] = {{"g", scene.layer->g}, {"albedo", scene.layer->albedo}, {"n2", run.layer_n2}};
  nlohmann::json list = nlohmann::json::array();
  for (const PanePreviewPanel& p : panels) {
    list.push_back({{"scene", p.scene},
                    {"contrast_bright_background", p.contrast_bright_background},
                    {"contrast_dark_background", p.contrast_dark_background}});
    log << "preview: " << p.scene << ": contaminated / clean radiance " << p.contrast_bright_background
        << " (bright background), " << p.contrast_dark_background << " (dark)\n";
  }
  (*summary)["panels"] = list;
  (*summary)["notes"] = scene.notes;
  return Status::Ok();
}

}  // namespace

double CheckerContrast(const Image& view, int channel, int mask_channel) {
  double sum = 0, sum2 = 0;
  int n = 0;
  for (int y = 0; y < view.height(); ++y) {
    for (int x = 0; x < view.width(); ++x) {
      if (!(view.at(x, y, mask_channel) > 0)) continue;
      const double v = view.at(x, y, channel);
      sum += v;
      sum2 += v * v;
      ++n;
    }
  }
  if (n < 2 || !(sum > 0)) return 0;
  const double mean = sum / n;
  return std::sqrt(std::max(0.0, sum2 / n - mean * mean)) / mean;
}

Status PreviewFit(const PreviewRun& run, std::ostream& log) {
  if (run.out_dir.empty()) return Status::Error("OUT: an output folder is required");
  if (run.layer_n2 < 1 || run.layer_n2 > 3) return Status::Error("PreviewRun::layer_n2 (--n2): must be in [1, 3]");
  if (run.panel_scale < 0 || run.panel_scale > 64) {
    return Status::Error("PreviewRun::panel_scale (--panel-scale): must be in [0, 64]");
  }
  if (!DirectoryExists(run.fit_dir))
    return Status::Error(run.fit_dir + ": not a folder (expected a fit output folder)");
  StagedDirectory out(run.out_dir, kCommand, {{run.fit_dir, {}}});
  THINSLAB_RETURN_IF_ERROR(out.Init());
  const Provenance provenance{kCommand, run.fit_dir, "", run.options_ini};
  nlohmann::json summary;
  summary["format"] = "thinslab-preview-summary";
  summary["format_version"] = "1.0";
  summary["source"] = run.fit_dir;
  if (FileExists(JoinPath(run.fit_dir, "maps.exr"))) {
    THINSLAB_RETURN_IF_ERROR(PreviewSlab(run, out.path(), provenance, log, &summary));
  } else {
    THINSLAB_RETURN_IF_ERROR(PreviewLayer(run, out.path(), log, &summary));
  }
  summary["provenance"] = ProvenanceJson(provenance);
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "preview.json"), summary.dump(2) + "\n"));
  if (!run.options_ini.empty()) {
    THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "options.ini"), run.options_ini));
  }
  THINSLAB_RETURN_IF_ERROR(out.Commit());
  log << "preview: " << JoinPath(run.out_dir, "preview.png") << "\n";
  return Status::Ok();
}

}  // namespace thinslab
