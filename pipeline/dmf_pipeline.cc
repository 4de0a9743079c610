// SPDX-License-Identifier: Apache-2.0
#include "thinslab/pipeline/dmf_pipeline.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <tuple>
#include <utility>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/false_color.h"
#include "thinslab/core/file.h"
#include "thinslab/core/memory.h"
#include "thinslab/core/parallel.h"
#include "thinslab/core/process_group.h"
#include "thinslab/core/progress.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/version.h"
#include "thinslab/fit/dmf_equivalent_roughness.h"
#include "thinslab/fit/dmf_evaluation.h"
#include "thinslab/fit/dmf_map_fit.h"
#include "thinslab/fit/dmf_model_ladder.h"
#include "thinslab/fit/dmf_processing.h"
#include "thinslab/pipeline/calibration_summary.h"
#include "thinslab/pipeline/capture_reading.h"
#include "thinslab/pipeline/folder_report.h"

namespace thinslab {
namespace {

// Per region: predictions of validation or held-out dots (EvaluateValidationDots); an empty array
// when there was nothing to predict.
nlohmann::json DotPredictionRegionsJson(const std::vector<DmfValidationError>& errors) {
  nlohmann::json regions = nlohmann::json::array();
  if (std::all_of(errors.begin(), errors.end(), [](const DmfValidationError& e) { return e.points == 0; })) return regions;
  for (const DmfValidationError& e : errors) {
    regions.push_back({{"region", e.region},
                       {"points", e.points},
                       {"pairs", e.pairs},
                       {"relative_rms", e.relative_rms},
                       {"noise_relative_rms", e.noise_relative_rms},
                       {"median_point_relative_rms", e.median_point_relative_rms},
                       {"unsampled_peak_points", e.unsampled_peak_points},
                       {"unsampled_peak_error_share", e.unsampled_peak_error_share}});
  }
  return regions;
}

std::string DotPredictionRegionsText(const std::vector<DmfValidationError>& errors) {
  std::string out;
  for (const DmfValidationError& e : errors) {
    if (e.pairs == 0) continue;
    char line[300];
    std::snprintf(line, sizeof(line), "  %s: %.3f (%.3f) over %d points, %d pairs; median per point %.3f",
                  e.region.c_str(), e.relative_rms, e.noise_relative_rms, e.points, e.pairs,
                  e.median_point_relative_rms);
    out += line;
    if (e.unsampled_peak_points > 0) {
      std::snprintf(line, sizeof(line), "; %d points with a peak between their training dots hold %.0f %% of the error",
                    e.unsampled_peak_points, 100 * e.unsampled_peak_error_share);
      out += line;
    }
    out += "\n";
  }
  return out;
}

Status ParsePixels(const std::string& text, std::vector<std::pair<int, int>>* pixels) {
  std::stringstream list(text);
  std::string item;
  while (std::getline(list, item, ';')) {
    int x = 0, y = 0;
    char comma = 0;
    std::stringstream s(item);
    if (!(s >> x >> comma >> y) || comma != ',') {
      return Status::Error("--ndf-pixels: '" + item + "' is not <col>,<row> (list separated by ';')");
    }
    pixels->emplace_back(x, y);
  }
  return Status::Ok();
}


// Issue #8 model ladder: fitted at every fitted point (or at the representatives, whose choice
// their cluster's points inherit from the highest-weight neighbour), decided per tile; points
// without a resolvable lobe are the attenuator. ladder.exr channels: rung (0, 3, 4, 5; -1
// none), held-out error of rungs 3, 4, 5 (-1 not scored), noise floor. With `apply`, the maps of
// points on rungs 3 and 4 are replaced by that rung's model (ReplaceWithLadderRung), so that
// maps.exr and the NDF atlas hold what was chosen.
struct LadderMaps {
  Image image;
  std::map<int, int> rung_counts;
  int evaluated = 0;
  int replaced = 0;  // Points whose maps now hold rung 3 or 4.
  double parameters_saved = 0, seconds_saved = 0, seconds = 0;
};

Status RunLadder(const DmfSliceSet& slices, DmfMaps* maps_out, const DmfMapFitOptions& fit, int tile,
                 const std::string& criterion, bool apply, LadderMaps* out) {
  const DmfMaps& maps = *maps_out;
  if (tile < 1) return Status::Error("--ladder-tile must be >= 1, got " + std::to_string(tile));
  if (std::none_of(slices.train.begin(), slices.train.end(), [](uint8_t t) { return t == 0; })) {
    return Status::Error("--ladder scores models on held-out dots: add --hold-out true");
  }
  const auto start = std::chrono::steady_clock::now();
  LadderOptions options;
  options.point = fit.point;
  options.criterion = criterion == "bic" ? LadderCriterion::kBic : LadderCriterion::kHeldOut;
  const DmfNdfGrid grid(fit.point.ndf_resolution);
  std::vector<int> points;
  if (fit.cluster) {
    points = maps.clustering.representatives;
  } else {
    for (int p = 0; p < slices.num_points(); ++p) {
      if (!maps.fits[p].log_ndf.empty() || maps.fits[p].status == DmfStatus::kSpecular) points.push_back(p);
    }
  }
  std::vector<LadderResult> results(points.size());
  ProgressTracker progress(fit.progress, "fit dmf: model ladder (rungs 0-5)", static_cast<int64_t>(points.size()));
  if (!ParallelFor(
          static_cast<int>(points.size()), fit.num_threads,
          [&](int k) { results[k] = FitLadder(slices.Slice(points[k]), grid, options); }, &progress)) {
    return Status::Error("fit dmf --ladder: cancelled");
  }
  out->image = Image(slices.width, slices.height, {"rung", "held_out_single_interface", "held_out_dmf_analytic",
                                                   "held_out_dmf_tabulated", "noise_floor"}, -1.0f);
  // Pixel clusters of the ladder: tiles of tile x tile grid points, whose evaluated points pool
  // their held-out dots (ChooseLadderRung).
  std::map<int, std::vector<const LadderResult*>> tiles;
  auto tile_of = [&](int p) { return (p / slices.width / tile) * slices.width + (p % slices.width) / tile; };
  for (size_t k = 0; k < points.size(); ++k) tiles[tile_of(points[k])].push_back(&results[k]);
  std::map<int, int> rung_of_tile;
  for (const auto& [t, group] : tiles) {
    const int k = ChooseLadderRung(group, options.significance_sigmas, options.criterion);
    const bool all_specular = std::all_of(group.begin(), group.end(), [](const LadderResult* r) { return r->specular; });
    rung_of_tile[t] = all_specular ? 0 : k >= 0 ? kLadderRungIds[k] : -1;
  }
  std::vector<int> rung_of_point(slices.num_points(), -1);
  std::vector<int> source_of_point(slices.num_points(), -1);  // Index into `results` (own or representative's).
  for (size_t k = 0; k < points.size(); ++k) {
    source_of_point[points[k]] = static_cast<int>(k);
    const LadderResult& r = results[k];
    const int p = points[k];
    rung_of_point[p] = r.specular ? 0 : rung_of_tile[tile_of(p)];
    const int chosen = rung_of_point[p] == 3 ? 0 : rung_of_point[p] == 4 ? 1 : rung_of_point[p] == 5 ? 2 : -1;
    const int x = p % slices.width, y = p / slices.width;
    for (int j = 0; j < kNumLadderRungs; ++j) out->image.at(x, y, 1 + j) = static_cast<float>(r.held_out[j]);
    out->image.at(x, y, 4) = static_cast<float>(r.noise_floor);
    if (chosen >= 0) {
      out->parameters_saved += r.parameters[2] - r.parameters[chosen];
      out->seconds_saved += r.seconds[2] - r.seconds[chosen];
    }
  }
  out->evaluated = static_cast<int>(points.size());
  if (fit.cluster) {
    const DmfClustering& c = maps.clustering;
    for (int p = 0; p < slices.num_points(); ++p) {
      if (rung_of_point[p] >= 0 || maps.fits[p].log_ndf.empty()) continue;
      int best = -1;
      double best_w = 0;
      for (int k = 0; k < c.num_neighbors; ++k) {
        const size_t idx = static_cast<size_t>(p) * c.num_neighbors + k;
        if (c.neighbors[idx] >= 0 && c.weights[idx] > best_w) {
          best_w = c.weights[idx];
          best = c.neighbors[idx];
        }
      }
      if (best >= 0) {
        rung_of_point[p] = rung_of_point[c.representatives[best]];
        source_of_point[p] = best;  // `points` are the representatives in order.
      }
    }
  }
  if (apply) {
    // The evaluated points first (their own rung fits), then the points that inherit a
    // representative's choice take its replaced model with their own k_s.
    std::vector<uint8_t> replaced(slices.num_points(), 0);
    maps_out->representative_ndf.clear();  // Representatives' NDFs may be replaced below.
    const DmfPointFitOptions rung_options = AnalyticRungOptions(options);  // k_s as rungs 3-4 fit it.
    auto rung_index = [&](int p) { return rung_of_point[p] == 3 ? 0 : rung_of_point[p] == 4 ? 1 : -1; };
    ParallelFor(static_cast<int>(points.size()), fit.num_threads, [&](int k) {
      const int p = points[k];
      if (rung_index(p) < 0 || maps.fits[p].log_ndf.empty()) return;
      replaced[p] = ReplaceWithLadderRung(results[k], rung_index(p), slices.Slice(p), grid, rung_options,
                                          &maps_out->fits[p]);
    });
    ParallelFor(slices.num_points(), fit.num_threads, [&](int p) {
      const int src = source_of_point[p];
      if (src < 0 || points[src] == p || rung_index(p) < 0 || maps.fits[p].log_ndf.empty()) return;
      if (!replaced[points[src]]) return;
      replaced[p] = AdoptLadderShape(maps.fits[points[src]], slices.Slice(p), grid, rung_options, &maps_out->fits[p]);
    });
    for (uint8_t r : replaced) out->replaced += r;
  }
  for (int p = 0; p < slices.num_points(); ++p) {
    const DmfStatus status = maps.fits[p].status;
    if (status == DmfStatus::kSpecular || status == DmfStatus::kNoLobe) rung_of_point[p] = 0;
    out->image.at(p % slices.width, p / slices.width, 0) = static_cast<float>(rung_of_point[p]);
    ++out->rung_counts[rung_of_point[p]];
  }
  out->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return Status::Ok();
}

// The run's own options (the stages' Options::Check() hold theirs).
Status CheckFitDmfRun(const FitDmfRun& run) {
  std::ostringstream msg;
  if (!(run.eta == 0 || run.eta > 1) || run.eta > 4) {
    msg << "--eta " << run.eta << ": must be 0 (the manifest's sample.glass_ior) or a refractive index in (1, 4]";
  } else if (!(run.cluster_fraction >= 0 && run.cluster_fraction <= 1)) {
    msg << "--cluster-fraction " << run.cluster_fraction << ": must be in [0, 1] (0 = fit every point)";
  } else if (run.atlas_stride < 0) {
    msg << "--atlas-stride " << run.atlas_stride << ": must be >= 0 (0 = at most 64 x 64 tiles)";
  } else if (run.ladder_tile < 1 || run.ladder_tile > 4096) {
    msg << "--ladder-tile " << run.ladder_tile << ": must be in 1..4096 grid points";
  } else if (!(run.processing.pitch_m >= 0)) {
    msg << "--pitch-mm " << run.processing.pitch_m * 1e3 << ": must be >= 0 (0 = the manifest's pixel_pitch_m)";
  } else if (run.fit.num_threads < 1 || run.fit.num_threads > kMaxThreads) {
    msg << "--threads " << run.fit.num_threads << ": must be in 1.." << kMaxThreads;
  } else {
    return Status::Ok();
  }
  return Status::Error(msg.str());
}

}  // namespace

Status FitDmfPipeline(const std::string& session_dir, const std::string& out_dir, FitDmfRun run, std::string* brief) {
  THINSLAB_RETURN_IF_ERROR(CheckFitDmfRun(run));
  // Under mpirun (issue #29 item 2) every process reads the capture and fits; rank 0 alone stages
  // and writes the output (the others would clear its staging folder as a killed run's).
  ProcessGroup& group = ProcessGroup::World();
  if (group.distributed() && run.ladder) {
    return Status::Error("--ladder runs on one process (without mpirun, or mpirun -n 1)");
  }
  // Refused before the work: an output that would replace an input or a folder of the user's.
  std::unique_ptr<StagedDirectory> staged;
  if (group.root()) {
    staged = std::make_unique<StagedDirectory>(out_dir, "fit dmf", std::vector<InputPath>{{session_dir, {"fit"}}});
  }
  THINSLAB_RETURN_IF_ERROR(group.Agree(staged ? staged->Init() : Status::Ok()));
  Session session;
  THINSLAB_RETURN_IF_ERROR(ReadCaptureForCommand(session_dir, run.allow_incomplete_capture, &session));
  run.processing.incomplete_capture =
      run.allow_incomplete_capture ? IncompleteCapture::kAccept : IncompleteCapture::kRefuse;
  run.fit.point.eta = run.eta > 0 ? run.eta : session.rig.sample.glass_ior;
  run.processing.eta = run.fit.point.eta;
  run.fit.cluster = run.cluster_fraction > 0;
  run.fit.clustering.fraction = run.cluster_fraction > 0 ? run.cluster_fraction : 1;
  std::string error;
  if (!run.fit.Check(&error)) return Status::Error("options: " + error);
  if (run.ladder_criterion != "held-out" && run.ladder_criterion != "bic") {
    return Status::Error("--ladder-criterion must be held-out or bic, got '" + run.ladder_criterion + "'");
  }
  std::vector<std::pair<int, int>> pixels;
  THINSLAB_RETURN_IF_ERROR(ParsePixels(run.ndf_pixels, &pixels));

  // The memory budget (issue #29): over it, the slices go to an unlinked file beside the output.
  run.processing.fit_ndf_resolution = run.fit.point.ndf_resolution;
  run.processing.num_threads = run.fit.num_threads;
  run.processing.fit_cluster_fraction = run.fit.cluster ? run.fit.clustering.fraction : 1.0;
  if ((run.processing.max_memory_bytes > 0 || run.processing.stream_band_points > 0) && run.processing.spill_dir.empty()) {
    // Beside the output: in its staging folder, or (the other processes) in the folder that holds it.
    const std::string parent = std::filesystem::path(out_dir).parent_path().string();
    run.processing.spill_dir = staged ? staged->path() : (parent.empty() ? "." : parent);
  }
  // The ladder keeps the NDFs it replaces per point: in memory only.
  if (run.ladder) run.processing.streaming_refused_by = "--ladder";
  DmfSliceSet slices;
  DmfProcessingReport processing;
  THINSLAB_RETURN_IF_ERROR(PrepareDotScanSlices(session_dir, run.processing, &slices, &processing));
  if (processing.memory.streamed) {
    char line[160];
    std::snprintf(line, sizeof(line), "memory: the slices (%.2f GiB) streamed in bands of %d points",
                  processing.memory.spill_file_bytes / double(1u << 30), processing.memory.band_points);
    std::cout << line << " from " << run.processing.spill_dir << "\n";
  }
  if (processing.dots_placed_from_geometry > 0) {
    std::cout << "dot geometry: " << processing.dots_placed_from_geometry << " of " << processing.num_dots
              << " dots placed from the monitor geometry (outside the camera's view, not found, or "
              << processing.dots_clipped << " cut by the image border), with the median L_q\n";
  }
  std::vector<std::string> warnings;  // Printed now, kept in summary.json and report.html.
  if (processing.dot_radius_source == "default") {
    warnings.push_back(AssumedDotRadiusWarning(JoinPath(session_dir, kSessionManifestName)));
  }
  if (!processing.dot_distance_warning.empty()) {
    warnings.push_back(processing.dot_geometry_source + ": " + processing.dot_distance_warning);
  }
  if (!processing.dark_level_warning.empty()) warnings.push_back(session_dir + "/" + processing.dark_level_warning);
  if (!processing.exposure_warning.empty()) warnings.push_back(session_dir + ": " + processing.exposure_warning);
  for (const std::string& w : warnings) std::cerr << "warning: " << w << "\n";
  DmfMaps maps;
  THINSLAB_RETURN_IF_ERROR(FitDualMicrofacetMaps(slices, run.fit, &maps));
  if (!group.root()) return Status::Ok();  // Every process has the maps; rank 0 writes them.
  StagedDirectory& out = *staged;
  for (const auto& [x, y] : pixels) {
    if (x < 0 || y < 0 || x >= maps.width || y >= maps.height) {
      return Status::Error("--ndf-pixels: (" + std::to_string(x) + ", " + std::to_string(y) + ") is outside the " +
                           std::to_string(maps.width) + " x " + std::to_string(maps.height) + " map");
    }
  }
  if (pixels.empty()) {
    for (int k = 1; k <= 3; ++k) pixels.emplace_back(k * maps.width / 4, k * maps.height / 4);
  }

  LadderMaps ladder;
  if (run.ladder) {
    THINSLAB_RETURN_IF_ERROR(
        RunLadder(slices, &maps, run.fit, run.ladder_tile, run.ladder_criterion, run.ladder_apply, &ladder));
  }

  // Simulated captures carry their ground truth: compare per region.
  std::vector<DmfTruthRegion> truth;
  const bool has_truth = FileExists(JoinPath(JoinPath(session_dir, "ground_truth"), "truth.json"));
  if (has_truth) THINSLAB_RETURN_IF_ERROR(ReadDmfTruth(session_dir, &truth));

  const auto write_start = std::chrono::steady_clock::now();
  const Provenance provenance{"fit dmf", session_dir, "", run.options_ini};
  Image image = maps.ToImage(run.fit.point.roughness);
  image.attributes()["model"] = "dai2009_dual_microfacet";
  image.numeric_attributes()["grid_min_m"] = {slices.grid_min_m.x(), slices.grid_min_m.y()};
  image.numeric_attributes()["pixel_pitch_m"] = {slices.pitch_m};
  image.numeric_attributes()["eta"] = {run.fit.point.eta};
  SetWorldToCamera(processing.cam_from_sample, &image);
  // Which model each point's maps hold: rung 5 (tabulated) unless the ladder replaced it
  // (ladder.exr channel rung).
  image.attributes()["ladder_applied"] = run.ladder && run.ladder_apply ? "true" : "false";
  THINSLAB_RETURN_IF_ERROR(WriteMapExr(JoinPath(out.path(), "maps.exr"), image,
                                       {"smith_alpha", {"status", "ndf_family", "rough_face"}}, provenance));

  // NDF atlas: tiles in the orthographic projection of optics/dual_microfacet_btdf.h.
  const int n = maps.ndf_resolution;
  const int stride = run.atlas_stride > 0 ? run.atlas_stride : std::max(1, (std::max(maps.width, maps.height) + 63) / 64);
  const int tiles_x = (maps.width + stride - 1) / stride, tiles_y = (maps.height + stride - 1) / stride;
  Image atlas(tiles_x * n, tiles_y * n, {"D"});
  for (int ty = 0; ty < tiles_y; ++ty) {
    for (int tx = 0; tx < tiles_x; ++tx) {
      const int p = (ty * stride) * maps.width + tx * stride;
      if (!maps.fits[p].HasNdf()) continue;
      const DmfPointFit f = maps.FitWithNdf(p);
      for (int cell = 0; cell < n * n; ++cell) atlas.at(tx * n + cell % n, ty * n + cell / n) = std::exp(f.log_ndf[cell]);
    }
  }
  atlas.numeric_attributes()["ndf_resolution"] = {static_cast<double>(n)};
  atlas.numeric_attributes()["atlas_stride"] = {static_cast<double>(stride)};
  atlas.attributes()["projection"] = "orthographic: cell (row, col) at h = (-1 + (col + 0.5) 2/N, -1 + (row + 0.5) 2/N), optical frame";
  THINSLAB_RETURN_IF_ERROR(WriteMapExr(JoinPath(out.path(), "ndf_atlas.exr"), atlas, {"D", {}}, provenance));
  if (run.ladder) {
    ladder.image.attributes() = image.attributes();
    ladder.image.numeric_attributes() = image.numeric_attributes();
    THINSLAB_RETURN_IF_ERROR(WriteMapExr(JoinPath(out.path(), "ladder.exr"), ladder.image, {"rung", {}}, provenance));
    Image undecided(maps.width, maps.height);
    for (int p = 0; p < maps.width * maps.height; ++p) undecided.data()[p] = ladder.image.data()[p * 5] < 0 ? 1.f : 0.f;
    FalseColorOptions color;
    color.scale_kind = ColorScale::kCategorical;
    color.label = "model rung";
    color.category_names = {"attenuator", "-", "-", "single_interface", "dmf_analytic", "dmf_tabulated"};
    color.scale = std::max(1, 256 / std::max(maps.width, maps.height));
    color.pixel_pitch_m = slices.pitch_m;
    THINSLAB_RETURN_IF_ERROR(
        WriteFalseColorPng(JoinPath(out.path(), "ladder_rung_falsecolor.png"), ladder.image, 0, &undecided, color));
  }

  // Pictures: maps (grey where nothing was fitted) and NDFs at the chosen points.
  Image unfitted(maps.width, maps.height);
  for (int p = 0; p < maps.width * maps.height; ++p) {
    unfitted.data()[p] = maps.fits[p].HasNdf() ? 0.f : 1.f;
  }
  const struct {
    const char* name;
    int channel;
    double max;
  } pictures[] = {{"top_face_weight", 0, 1}, {"smith_alpha", 1, 1},      {"k_s", 2, 1.5},
                  {"rho_d", 3, 0.2},          {"log_rms_residual", 4, 1}, {"measured_ndf_fraction", 6, 1},
                  {"equivalent_roughness", 8, 1}};
  for (const auto& pic : pictures) {
    FalseColorOptions color;
    color.label = pic.name;
    color.max_value = pic.max;
    color.scale = std::max(1, 256 / std::max(maps.width, maps.height));
    color.pixel_pitch_m = slices.pitch_m;
    THINSLAB_RETURN_IF_ERROR(WriteFalseColorPng(JoinPath(out.path(), std::string(pic.name) + "_falsecolor.png"), image,
                                                pic.channel, &unfitted, color));
  }
  {
    FalseColorOptions color;  // Every point has a status: nothing greyed out.
    color.scale_kind = ColorScale::kCategorical;
    color.label = "status";
    color.category_names = DmfStatusNames();
    color.scale = std::max(1, 256 / std::max(maps.width, maps.height));
    color.pixel_pitch_m = slices.pitch_m;
    THINSLAB_RETURN_IF_ERROR(WriteFalseColorPng(JoinPath(out.path(), "status_falsecolor.png"), image, 5, nullptr, color));
  }
  for (const auto& [name, channel, names] :
       {std::make_tuple("ndf_family", 9, NdfFamilyNames()), std::make_tuple("rough_face", 10, RoughFaceNames())}) {
    FalseColorOptions color;
    color.scale_kind = ColorScale::kCategorical;
    color.label = name;
    color.category_names = names;
    color.scale = std::max(1, 256 / std::max(maps.width, maps.height));
    color.pixel_pitch_m = slices.pitch_m;
    THINSLAB_RETURN_IF_ERROR(WriteFalseColorPng(JoinPath(out.path(), std::string(name) + "_falsecolor.png"), image,
                                                channel, &unfitted, color));
  }
  // NDF pictures (Dai Fig. 6): fitted on the left; the true face NDF on the right where the
  // capture has ground truth and the point's region has one rough face.
  for (const auto& [x, y] : pixels) {
    const DmfPointFit f = maps.FitWithNdf(y * maps.width + x);
    const Eigen::Vector3d point = slices.PointPosition(y * maps.width + x);
    const DmfTruthFace* face = nullptr;
    for (const DmfTruthRegion& r : truth) {
      if (point.x() >= r.min_m.x() && point.x() < r.max_m.x() && point.y() >= r.min_m.y() && point.y() < r.max_m.y()) {
        face = r.SingleRoughFace();
      }
    }
    const DmfNdfGrid grid(n);
    Image ndf(face ? 2 * n + 2 : n, n);
    double peak = 0;
    for (int cell = 0; cell < n * n; ++cell) {
      const float fitted = f.log_ndf.empty() ? 0.f : static_cast<float>(std::exp(f.log_ndf[cell]));
      ndf.at(cell % n, cell / n) = fitted;
      peak = std::max(peak, static_cast<double>(fitted));
      if (face && grid.InDisk(cell)) {
        const double hx = grid.CellCentre(cell % n), hy = grid.CellCentre(cell / n);
        const double t = TrueNdf(*face, Eigen::Vector3d(hx, hy, std::sqrt(std::max(0.0, 1 - hx * hx - hy * hy))));
        ndf.at(n + 2 + cell % n, cell / n) = static_cast<float>(t);
        peak = std::max(peak, t);
      }
    }
    FalseColorOptions color;
    color.label = std::string(face ? "D fitted | true" : "D") + " at (" + std::to_string(x) + ", " + std::to_string(y) + ")";
    color.max_value = peak > 0 ? peak : 1;
    color.scale = std::max(1, 256 / n);
    THINSLAB_RETURN_IF_ERROR(WriteFalseColorPng(
        JoinPath(out.path(), "ndf_" + std::to_string(x) + "_" + std::to_string(y) + ".png"), ndf, 0, nullptr, color));
  }

  // Issue #23 section 4: the capture's validation dots, predicted by the tabulated fit.
  // (DmfHeldOutError's lobe fraction: the held-out pass's point errors serve the comparison.)
  constexpr double kValidationLobeFraction = 0.1;
  std::vector<DmfValidationError> validation;
  THINSLAB_RETURN_IF_ERROR(EvaluateValidationDots(slices, maps, truth, kValidationLobeFraction, run.fit.num_threads,
                                                  &validation, run.fit.progress));
  // The held-out grid dots (--hold-out), reported with or without the ladder; their per-point
  // errors are the ground-truth comparison's, predicted once.
  std::vector<DmfValidationError> held_out;
  std::vector<double> held_out_errors;
  if (run.processing.hold_out) {
    THINSLAB_RETURN_IF_ERROR(EvaluateHeldOutDots(slices, maps, truth, kValidationLobeFraction, run.fit.num_threads,
                                                 &held_out, run.fit.progress, has_truth ? &held_out_errors : nullptr));
  }
  std::vector<DmfRegionAccuracy> accuracy;
  if (has_truth) {
    THINSLAB_RETURN_IF_ERROR(CompareDmfWithTruth(slices, maps, truth, 0.5, &accuracy, run.fit.progress,
                                                 held_out_errors.empty() ? nullptr : &held_out_errors));
    THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "comparison.json"), DmfComparisonJson(accuracy)));
  }
  // A few points whose lobe peaks between their training dots can make the pooled figure.
  for (const auto& [what, errors] :
       {std::pair{"validation dots", &validation}, std::pair{"held-out dots", &held_out}}) {
    if (errors->empty() || errors->front().unsampled_peak_error_share <= 0.5) continue;
    const DmfValidationError& all = errors->front();
    std::ostringstream msg;
    msg.precision(3);
    msg << what << ": " << all.unsampled_peak_points << " of " << all.points << " points have a dot more than "
        << kUnsampledPeakFactor
        << "x above every training dot (a lobe peak between the training dots: a specular component or a point "
           "mixing a smooth and a rough region) and hold "
        << std::lround(100 * all.unsampled_peak_error_share) << " % of the squared error of the pooled relative RMS "
        << all.relative_rms << "; the median point's is " << all.median_point_relative_rms;
    warnings.push_back(msg.str());
    std::cerr << "warning: " << session_dir << ": " << msg.str() << "\n";
  }
  std::map<std::string, int> counts;
  for (const DmfPointFit& f : maps.fits) ++counts[DmfStatusName(f.status)];
  // The NDF tail of the points fitted directly (the representatives of a clustered run; the
  // interpolated points' NDFs mix theirs).
  int direct_with_ndf = 0, direct_with_family_tail = 0;
  auto count_tail = [&](int p) {
    const DmfPointFit& f = maps.fits[p];
    if (f.log_ndf.empty()) return;
    ++direct_with_ndf;
    direct_with_family_tail += f.family_tail;
  };
  if (run.fit.cluster) {
    for (int p : maps.clustering.representatives) count_tail(p);
  } else {
    for (int p = 0; p < static_cast<int>(maps.fits.size()); ++p) count_tail(p);
  }
  // Family, rough face and equivalent roughness over the points whose fit stands (ok, interpolated).
  std::map<std::string, int> families, faces;
  std::vector<double> roughness;
  for (const DmfPointFit& f : maps.fits) {
    if ((f.status != DmfStatus::kOk && f.status != DmfStatus::kInterpolated) || !f.HasNdf()) continue;
    ++families[NdfFamilyName(f.roughness.family)];
    ++faces[RoughFaceName(RoughFaceOf(f.alpha, run.fit.point.roughness))];
    roughness.push_back(f.roughness.roughness);
  }
  std::sort(roughness.begin(), roughness.end());
  auto quantile = [&](double q) {
    if (roughness.empty()) return nlohmann::json(nullptr);
    return nlohmann::json(roughness[static_cast<size_t>(q * (roughness.size() - 1))]);
  };
  const double write_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - write_start).count();
  nlohmann::json j;
  j["format"] = "thinslab-fit-summary";
  j["provenance"] = ProvenanceJson(provenance);
  j["model"] = "dai2009_dual_microfacet";
  j["warnings"] = warnings;
  j["session"] = session_dir;
  j["grid"] = {maps.width, maps.height};
  j["dots"] = {processing.grid_nx, processing.grid_ny};
  if (run.processing.hold_out) {
    const HoldOutPattern& pattern = run.processing.hold_out_pattern;
    j["hold_out"] = {{"pattern", pattern.kind},
                     {"held_out_dots", std::count(slices.train.begin(), slices.train.end(), 0)}};
    if (pattern.kind == "random") j["hold_out"].update({{"fraction", pattern.fraction}, {"seed", pattern.seed}});
    if (pattern.kind == "blocks") j["hold_out"]["block"] = pattern.block;
  } else {
    j["hold_out"] = nullptr;
  }
  j["ndf_resolution"] = n;
  j["eta"] = run.fit.point.eta;
  j["clustered"] = run.fit.cluster;
  j["points_fitted_directly"] = maps.num_fitted;
  j["status_counts"] = counts;
  j["equivalent_ndf"] = {{"note", "points with status ok or interpolated; the analytic NDF nearest to each tabulated one"},
                         {"ndf_family_counts", families},
                         {"rough_face_counts", faces},
                         {"equivalent_roughness_quantiles", {{"p10", quantile(0.1)}, {"median", quantile(0.5)}, {"p90", quantile(0.9)}}},
                         {"family_ratio", run.fit.point.roughness.family_ratio},
                         {"one_face_alpha", run.fit.point.roughness.one_face_alpha}};
  j["ndf_tail"] = {
      {"note", "the NDF beyond the hull of the measured cells: the family fitted to them, or Eq. 17's fill"},
      {"mode", run.fit.point.ndf_tail},
      {"max_misfit", run.fit.point.ndf_tail_max_misfit},
      {"direct_fits_with_ndf", direct_with_ndf},
      {"direct_fits_with_family_tail", direct_with_family_tail}};
  j["dot_rms_residual_m"] = processing.dot_rms_residual_m;
  j["dot_radius"] = {{"monitor_px", processing.dot_radius_px}, {"source", processing.dot_radius_source}};
  j["glass_thickness_m"] = processing.glass_thickness_m;
  // What `thinslab predict` needs to light the sample with any dot (docs/format.md 9.5).
  const Eigen::Quaterniond& q = processing.sample_from_monitor.rotation;
  const Eigen::Vector3d& t = processing.sample_from_monitor.translation;
  j["monitor"] = {{"sample_from_monitor", {{"rotation_wxyz", {q.w(), q.x(), q.y(), q.z()}},
                                           {"translation_m", {t.x(), t.y(), t.z()}}}},
                  {"pixel_pitch_m", processing.monitor_pixel_pitch_m},
                  {"median_dot_radiance_dn_per_us", processing.median_dot_radiance}};
  j["dot_positions"] = {{"measured", processing.num_dots - processing.dots_placed_from_geometry},
                        {"placed_from_geometry", processing.dots_placed_from_geometry},
                        {"found_by_grid_prior", processing.dots_found_by_grid_prior},
                        {"clipped_at_border", processing.dots_clipped}};
  j["monitor_distance"] = {{"error_m", processing.dot_distance_error_m},
                           {"error_sigma_m", processing.dot_distance_error_sigma_m},
                           {"correction_m", processing.dot_distance_correction_m},
                           {"warning", processing.dot_distance_warning}};
  j["dark_frame"] = {{"exposure_us", processing.dark_exposure_us},
                     {"median_fraction_of_range_at_sample_points", processing.dark_fraction_of_range},
                     {"warning", processing.dark_level_warning}};
  j["exposure_check"] = ExposureCheckJson(processing.exposure_check, false);
  j["dot_geometry_source"] = processing.dot_geometry_source;
  j["noise"] = processing.noise.ToJson();
  j["validation"] = {{"dots", slices.validation.num_dots()},
                     {"lobe_fraction", kValidationLobeFraction},
                     {"regions", DotPredictionRegionsJson(validation)}};
  if (run.processing.hold_out) {
    j["hold_out"]["lobe_fraction"] = kValidationLobeFraction;
    j["hold_out"]["regions"] = DotPredictionRegionsJson(held_out);
  }
  j["calibration"] = CalibrationSummaryJson(processing.calibration);
  j["capture"] = CaptureSummaryJson(processing.capture);
  j["slice_memory_bytes"] = processing.slice_bytes;
  j["memory"] = {{"max_memory_bytes", run.processing.max_memory_bytes},
                 {"streamed", processing.memory.streamed},
                 {"band_points", processing.memory.band_points},
                 {"estimated_in_memory_bytes", processing.memory.in_memory_bytes},
                 {"estimated_peak_bytes", processing.memory.streamed_bytes},
                 {"spill_file_bytes", processing.memory.streamed ? processing.memory.spill_file_bytes : 0.0}};
  j["peak_memory_mib"] = PeakResidentMemoryMiB();  // Of rank 0 (each process holds as much).
  // How many processes shared the work (mpirun -n N; 1 alone): the maps do not depend on it.
  j["processes"] = group.size();
  j["timings_s"] = {{"dot_geometry", processing.geometry_s},
                    {"hdr_merge_rectify_eq12", processing.merge_s},
                    {"processing_total", processing.total_s},
                    {"diffuse_separation", maps.timings.diffuse_s},
                    {"clustering", maps.timings.clustering_s},
                    {"model_fit", maps.timings.representative_fit_s},
                    {"interpolation", maps.timings.interpolation_s},
                    {"fit_total", maps.timings.total_s},
                    {"writing", write_s}};
  if (run.fit.cluster) {
    j["clustering"] = {{"representatives", maps.clustering.representatives.size()},
                       {"pca_explained", maps.clustering.pca_explained},
                       {"mean_weight_residual", maps.clustering.mean_weight_residual}};
  }
  if (run.ladder) {
    nlohmann::json counts_json;
    for (const auto& [rung, count] : ladder.rung_counts) counts_json[std::to_string(rung)] = count;
    j["ladder"] = {{"rung_counts", counts_json},
                   {"criterion", run.ladder_criterion},
                   {"applied_to_maps", run.ladder_apply},
                   {"points_replaced", ladder.replaced},
                   {"points_evaluated", ladder.evaluated},
                   {"parameters_saved", ladder.parameters_saved},
                   {"fit_seconds_saved", ladder.seconds_saved},
                   {"seconds", ladder.seconds}};
  }
  std::ostringstream txt;
  txt << "dual-microfacet fit of " << session_dir << ": " << maps.width << " x " << maps.height << " points, "
      << processing.grid_nx << " x " << processing.grid_ny << " dots, NDF " << n << " x " << n << ", eta "
      << run.fit.point.eta << "\n";
  txt << "calibration: " << processing.calibration.Describe() << "; dot geometry from "
      << processing.dot_geometry_source << "\n";
  txt << "fitted directly: " << maps.num_fitted << (run.fit.cluster ? " representatives" : " points") << "\n";
  for (const auto& [name, count] : counts) txt << "  " << name << ": " << count << "\n";
  txt << "time: processing " << processing.total_s << " s (dots " << processing.geometry_s << " s, HDR/Eq. 12 "
      << processing.merge_s << " s), fit " << maps.timings.total_s << " s (clustering " << maps.timings.clustering_s
      << " s, model " << maps.timings.representative_fit_s << " s, interpolation " << maps.timings.interpolation_s
      << " s), writing " << write_s << " s; peak memory " << PeakResidentMemoryMiB() << " MiB\n";
  if (run.ladder) {
    txt << "model ladder (issue #8; rung 0 attenuator, 3 single GGX or Beckmann interface, 4 analytic dual-microfacet, "
           "5 tabulated; by "
        << run.ladder_criterion << "):";
    for (const auto& [rung, count] : ladder.rung_counts) txt << " rung " << rung << ": " << count;
    txt << "; over " << ladder.evaluated << " evaluated points " << ladder.parameters_saved
        << " parameters and " << ladder.seconds_saved << " s of fitting saved against rung 5 (" << ladder.seconds
        << " s); "
        << (run.ladder_apply ? std::to_string(ladder.replaced) + " points' maps hold rung 3 or 4"
                             : std::string("maps hold rung 5 everywhere (--ladder-apply false)"))
        << "\n";
  }
  if (slices.validation.num_dots() > 0) {
    txt << "validation dots: " << slices.validation.num_dots()
        << " (not fitted); in-lobe relative RMS of the prediction (noise alone):\n"
        << DotPredictionRegionsText(validation);
  }
  if (run.processing.hold_out) {
    txt << "held-out grid dots (" << run.processing.hold_out_pattern.kind
        << " pattern); in-lobe relative RMS of the prediction (noise alone):\n"
        << DotPredictionRegionsText(held_out);
  }
  if (has_truth) {
    txt << "against ground truth (medians per region; NDF L2 on one-sided regions, held-out with --hold-out):\n";
    for (const DmfRegionAccuracy& a : accuracy) {
      txt << "  " << a.name << ": " << a.fitted << "/" << a.points << " fitted, alpha " << a.median_alpha;
      if (a.median_ndf_l2 >= 0) txt << ", NDF L2 " << a.median_ndf_l2;
      if (a.median_held_out >= 0) txt << ", held-out " << a.median_held_out;
      txt << ", k_s " << a.median_k_s << " (true " << a.true_k_s << "), rho_d " << a.median_rho_d << " (true "
          << a.true_rho_d << ")\n";
    }
  }
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "summary.json"), j.dump(2) + "\n"));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "summary.txt"), txt.str()));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "options.ini"), run.options_ini));
  THINSLAB_RETURN_IF_ERROR(WriteFolderReport(out.path(), out_dir, "thinslab fit dmf: " + session_dir));
  THINSLAB_RETURN_IF_ERROR(out.Commit());
  *brief = txt.str();
  return Status::Ok();
}

}  // namespace thinslab
