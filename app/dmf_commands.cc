// SPDX-License-Identifier: Apache-2.0
// `thinslab fit dmf CAPTURE`: dual-microfacet SVBTDF maps from a CRT dot scan (Dai et al. 2009;
// fit/dmf_processing.h, fit/dmf_map_fit.h). Writes, atomically, into CAPTURE/fit/dmf/:
//   maps.exr         alpha, smith_alpha, k_s, rho_d, residual, status (docs/format.md)
//   ndf_atlas.exr    channel D: the N x N NDF tile of every atlas_stride-th point
//   *_falsecolor.png the maps; ndf_<col>_<row>.png the NDF at chosen points (Dai Fig. 6)
//   summary.json/.txt timings per stage, status counts, peak memory; options.ini
//   comparison.json  per-region accuracy when the capture has ground_truth/truth.json (sim)
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <sstream>

#include "app/commands.h"
#include "app/option_parser.h"
#include "core/exr_io.h"
#include "core/false_color.h"
#include "core/file.h"
#include "core/memory.h"
#include "core/session_io.h"
#include "core/version.h"
#include "fit/dmf_evaluation.h"
#include "fit/dmf_map_fit.h"
#include "fit/dmf_processing.h"

namespace thinslab {
namespace {

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

struct DmfRun {
  DmfProcessingOptions processing;
  DmfMapFitOptions fit;
  double eta = 0;  // 0 = the manifest's sample.glass_ior.
  double cluster_fraction = 0.01;
  int atlas_stride = 0;  // 0 = at most 64 x 64 tiles.
  std::string ndf_pixels;
  std::string options_ini;
};

Status FitDmfPipeline(const std::string& session_dir, const std::string& out_dir, DmfRun run, std::string* brief) {
  Session session;
  THINSLAB_RETURN_IF_ERROR(ReadSession(session_dir, &session));
  run.fit.point.eta = run.eta > 0 ? run.eta : session.rig.sample.glass_ior;
  run.fit.cluster = run.cluster_fraction > 0;
  run.fit.clustering.fraction = run.cluster_fraction > 0 ? run.cluster_fraction : 1;
  std::string error;
  if (!run.fit.Check(&error)) return Status::Error("options: " + error);
  std::vector<std::pair<int, int>> pixels;
  THINSLAB_RETURN_IF_ERROR(ParsePixels(run.ndf_pixels, &pixels));

  DmfSliceSet slices;
  DmfProcessingReport processing;
  THINSLAB_RETURN_IF_ERROR(PrepareDotScanSlices(session_dir, run.processing, &slices, &processing));
  DmfMaps maps;
  THINSLAB_RETURN_IF_ERROR(FitDualMicrofacetMaps(slices, run.fit, &maps));
  for (const auto& [x, y] : pixels) {
    if (x < 0 || y < 0 || x >= maps.width || y >= maps.height) {
      return Status::Error("--ndf-pixels: (" + std::to_string(x) + ", " + std::to_string(y) + ") is outside the " +
                           std::to_string(maps.width) + " x " + std::to_string(maps.height) + " map");
    }
  }
  if (pixels.empty()) {
    for (int k = 1; k <= 3; ++k) pixels.emplace_back(k * maps.width / 4, k * maps.height / 4);
  }

  // Simulated captures carry their ground truth: compare per region.
  std::vector<DmfTruthRegion> truth;
  const bool has_truth = FileExists(JoinPath(JoinPath(session_dir, "ground_truth"), "truth.json"));
  if (has_truth) THINSLAB_RETURN_IF_ERROR(ReadDmfTruth(session_dir, &truth));

  const auto write_start = std::chrono::steady_clock::now();
  StagedDirectory out(out_dir);
  THINSLAB_RETURN_IF_ERROR(out.Init());
  Image image = maps.ToImage();
  image.attributes()["format_version"] = "1.0";
  image.attributes()["thinslab_version"] = THINSLAB_VERSION_STRING;
  image.attributes()["git_hash"] = THINSLAB_GIT_HASH;
  image.attributes()["source_session"] = session_dir;
  image.attributes()["model"] = "dai2009_dual_microfacet";
  image.attributes()["grid_min_m"] = nlohmann::json({slices.grid_min_m.x(), slices.grid_min_m.y()}).dump();
  image.attributes()["pixel_pitch_m"] = nlohmann::json(slices.pitch_m).dump();
  image.attributes()["eta"] = nlohmann::json(run.fit.point.eta).dump();
  THINSLAB_RETURN_IF_ERROR(WriteExr(JoinPath(out.path(), "maps.exr"), image));

  // NDF atlas: tiles in the orthographic projection of optics/dual_microfacet_btdf.h.
  const int n = maps.ndf_resolution;
  const int stride = run.atlas_stride > 0 ? run.atlas_stride : std::max(1, (std::max(maps.width, maps.height) + 63) / 64);
  const int tiles_x = (maps.width + stride - 1) / stride, tiles_y = (maps.height + stride - 1) / stride;
  Image atlas(tiles_x * n, tiles_y * n, {"D"});
  for (int ty = 0; ty < tiles_y; ++ty) {
    for (int tx = 0; tx < tiles_x; ++tx) {
      const DmfPointFit& f = maps.fits[(ty * stride) * maps.width + tx * stride];
      if (f.log_ndf.empty()) continue;
      for (int cell = 0; cell < n * n; ++cell) atlas.at(tx * n + cell % n, ty * n + cell / n) = std::exp(f.log_ndf[cell]);
    }
  }
  atlas.attributes()["ndf_resolution"] = std::to_string(n);
  atlas.attributes()["atlas_stride"] = std::to_string(stride);
  atlas.attributes()["projection"] = "orthographic: cell (row, col) at h = (-1 + (col + 0.5) 2/N, -1 + (row + 0.5) 2/N), optical frame";
  THINSLAB_RETURN_IF_ERROR(WriteExr(JoinPath(out.path(), "ndf_atlas.exr"), atlas));

  // Pictures: maps (grey where nothing was fitted) and NDFs at the chosen points.
  Image unfitted(maps.width, maps.height);
  for (int p = 0; p < maps.width * maps.height; ++p) {
    unfitted.data()[p] = maps.fits[p].log_ndf.empty() ? 1.f : 0.f;
  }
  const struct {
    const char* name;
    int channel;
    double max;
  } pictures[] = {{"alpha", 0, 1}, {"smith_alpha", 1, 1}, {"k_s", 2, 1.5}, {"rho_d", 3, 0.2}, {"residual", 4, 1}};
  for (const auto& pic : pictures) {
    FalseColorOptions color;
    color.label = pic.name;
    color.max_value = pic.max;
    color.scale = std::max(1, 256 / std::max(maps.width, maps.height));
    THINSLAB_RETURN_IF_ERROR(WriteFalseColorPng(JoinPath(out.path(), std::string(pic.name) + "_falsecolor.png"), image,
                                                pic.channel, &unfitted, color));
  }
  // NDF pictures (Dai Fig. 6): fitted on the left; the true face NDF on the right where the
  // capture has ground truth and the point's region has one rough face.
  for (const auto& [x, y] : pixels) {
    const DmfPointFit& f = maps.fits[y * maps.width + x];
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

  std::vector<DmfRegionAccuracy> accuracy;
  if (has_truth) {
    accuracy = CompareDmfWithTruth(slices, maps, truth);
    THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out.path(), "comparison.json"), DmfComparisonJson(accuracy)));
  }
  std::map<std::string, int> counts;
  for (const DmfPointFit& f : maps.fits) ++counts[DmfStatusName(f.status)];
  const double write_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - write_start).count();
  nlohmann::json j;
  j["format"] = "thinslab-fit-summary";
  j["model"] = "dai2009_dual_microfacet";
  j["session"] = session_dir;
  j["grid"] = {maps.width, maps.height};
  j["dots"] = {processing.grid_nx, processing.grid_ny};
  j["ndf_resolution"] = n;
  j["eta"] = run.fit.point.eta;
  j["clustered"] = run.fit.cluster;
  j["points_fitted_directly"] = maps.num_fitted;
  j["status_counts"] = counts;
  j["dot_rms_residual_m"] = processing.dot_rms_residual_m;
  j["slice_memory_bytes"] = processing.slice_bytes;
  j["peak_memory_mib"] = PeakResidentMemoryMiB();
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
  std::ostringstream txt;
  txt << "dual-microfacet fit of " << session_dir << ": " << maps.width << " x " << maps.height << " points, "
      << processing.grid_nx << " x " << processing.grid_ny << " dots, NDF " << n << " x " << n << ", eta "
      << run.fit.point.eta << "\n";
  txt << "fitted directly: " << maps.num_fitted << (run.fit.cluster ? " representatives" : " points") << "\n";
  for (const auto& [name, count] : counts) txt << "  " << name << ": " << count << "\n";
  txt << "time: processing " << processing.total_s << " s (dots " << processing.geometry_s << " s, HDR/Eq. 12 "
      << processing.merge_s << " s), fit " << maps.timings.total_s << " s (clustering " << maps.timings.clustering_s
      << " s, model " << maps.timings.representative_fit_s << " s, interpolation " << maps.timings.interpolation_s
      << " s), writing " << write_s << " s; peak memory " << PeakResidentMemoryMiB() << " MiB\n";
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
  THINSLAB_RETURN_IF_ERROR(out.Commit());
  *brief = txt.str();
  return Status::Ok();
}

}  // namespace

int RunFitDmf(int argc, char** argv) {
  DmfRun run;
  std::string session_dir, out_dir;
  double pitch_mm = 0;
  OptionParser parser("fit dmf");
  parser.AddPositional("CAPTURE", &session_dir, "CRT dot-scan capture session folder");
  parser.AddString("out", &out_dir, "output folder (default CAPTURE/fit/dmf)");
  parser.AddDouble("pitch-mm", &pitch_mm, "sample grid pitch [mm]; 0 = the manifest's");
  parser.AddDouble("eta", &run.eta, "slab refractive index; 0 = the manifest's sample.glass_ior");
  parser.AddInt("ndf-resolution", &run.fit.point.ndf_resolution, "N of the N x N NDF grid");
  parser.AddDouble("smoothness", &run.fit.point.smoothness, "weight of the Eq. 17 Laplacian rows");
  parser.AddBool("fit-smith", &run.fit.point.fit_smith_alpha, "fit the Smith roughness (Levenberg-Marquardt)");
  parser.AddDouble("cluster-fraction", &run.cluster_fraction, "k-means representatives per point; 0 = fit every point");
  parser.AddInt("neighbors", &run.fit.clustering.num_neighbors, "representatives per interpolated point (Eq. 20)");
  parser.AddBool("hold-out", &run.processing.hold_out, "hold out every other dot from the fit");
  parser.AddDouble("dot-radius-px", &run.processing.dot_radius_px, "radius of a displayed dot [monitor px]");
  parser.AddInt("threads", &run.fit.num_threads, "threads");
  parser.AddInt("atlas-stride", &run.atlas_stride, "NDF atlas keeps every n-th point; 0 = at most 64 x 64 tiles");
  parser.AddString("ndf-pixels", &run.ndf_pixels, "points for NDF pictures, '<col>,<row>;...'");
  Status status = parser.Parse(argc, argv);
  if (parser.help_requested()) {
    std::cout << parser.Usage();
    return 0;
  }
  run.processing.pitch_m = pitch_mm * 1e-3;
  if (out_dir.empty()) out_dir = JoinPath(JoinPath(session_dir, "fit"), "dmf");
  run.options_ini = parser.ToIni();
  std::string brief;
  if (status.ok()) status = FitDmfPipeline(session_dir, out_dir, run, &brief);
  if (!status.ok()) {
    std::cerr << "error: " << status.message() << "\n";
    return 1;
  }
  std::cout << brief << "wrote " << out_dir << "\n";
  return 0;
}

}  // namespace thinslab
