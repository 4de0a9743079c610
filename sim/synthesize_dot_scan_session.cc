// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/synthesize_dot_scan_session.h"

#include <nlohmann/json.hpp>

#include <chrono>
#include <cmath>

#include "thinslab/acquire/session_writer.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/version.h"
#include "thinslab/sim/sim_session.h"

namespace thinslab {
namespace {

nlohmann::json Vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }
nlohmann::json Vec(const Eigen::Vector2d& v) { return {v.x(), v.y()}; }

nlohmann::json FaceJson(const SlabFace& f) {
  return {{"ndf", RoughSlabNdfName(f.ndf)}, {"alpha_x", f.alpha_x}, {"alpha_y", f.alpha_y}, {"flat", f.IsFlat()}};
}

}  // namespace

SyntheticDotScanOptions::SyntheticDotScanOptions() {
  rig.camera_width_px = 240;
  rig.camera_height_px = 180;
  rig.camera_view_width_m = 0.12;
  rig.camera_distortion = {};
  rig.render_supersample = 2;
  rig.dot_radiance = 0.05;  // A directly seen dot fills ~40 % of full well in one refresh period.
  rig.monitor_center_in_sample_m = Eigen::Vector2d(0, rig.monitor_distance_m * std::tan(rig.camera_tilt_deg * kPi / 180));
  session.grid_nx = 16;
  session.grid_ny = 16;
  session.margin_fraction = 0.02;  // 96 % of the 0.1 m screen: 1.2 x the 0.08 m sample.
  session.sample_state = "contaminated";
  // 1 and 800 refresh periods: the all-dots frame and dots seen straight through the smooth
  // region are unsaturated at the short one, the lobes of the rough regions peak below
  // saturation at the long one (docs/models/dot_scan_rig.md, measured there).
  session.bracket.exposures_us = {1e6 / 85, 800 * 1e6 / 85};
  sample.photons_per_region = 200000;
  sample.table_bins = 64;
}

Status SyntheticDotScanOptions::Check() const {
  THINSLAB_RETURN_IF_ERROR(rig.Check());
  if (validation_dots < 0 || validation_dots > 10000) {
    return Status::Error("SyntheticDotScanOptions::validation_dots (--validation-dots): must be in [0, 10000], got " +
                         std::to_string(validation_dots));
  }
  DotScanSessionOptions s = session;
  s.monitor_width_px = rig.monitor_width_px;
  s.monitor_height_px = rig.monitor_height_px;
  std::string error;
  if (!s.Check(&error)) return Status::Error(error);
  if (session.sample_state == "none") {
    return Status::Error("DotScanSessionOptions::sample_state: 'none' would scan without the sample");
  }
  SlabSampleOptions so = sample;
  if (so.regions.empty()) so.regions = DefaultSlabRegions(so.min_m, so.max_m);
  THINSLAB_RETURN_IF_ERROR(so.Check());
  if (!(truth_pitch_m > 0) || (sample.max_m - sample.min_m).maxCoeff() / truth_pitch_m > 16384) {
    return Status::Error("SyntheticDotScanOptions::truth_pitch_m: must be > 0 m and give <= 16384 px per side");
  }
  if (name.empty()) return Status::Error("SyntheticDotScanOptions::name: must not be empty");
  return Status::Ok();
}

Status BuildDotScanRig(const SyntheticDotScanOptions& options, std::unique_ptr<SimDotMonitor>* rig,
                       std::shared_ptr<const SlabSample>* sample) {
  THINSLAB_RETURN_IF_ERROR(options.Check());
  std::unique_ptr<SimDotMonitor> monitor;
  THINSLAB_RETURN_IF_ERROR(SimDotMonitor::Create(options.rig, &monitor));
  std::unique_ptr<SlabSample> slab;
  THINSLAB_RETURN_IF_ERROR(SlabSample::Create(options.sample, monitor->CameraCentreInSample(), &slab));
  std::shared_ptr<const SlabSample> shared(std::move(slab));
  monitor->SetSample(shared);
  THINSLAB_RETURN_IF_ERROR(monitor->SetSampleState("none"));
  *rig = std::move(monitor);
  *sample = std::move(shared);
  return Status::Ok();
}

Status WriteDotScanTruth(const SyntheticDotScanOptions& options, const SlabSample& sample, const SimDotMonitor& monitor,
                         double acquisition_s, const std::string& session_dir) {
  const SlabSampleOptions& so = sample.options();
  const std::string truth_dir = JoinPath(session_dir, "ground_truth");
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(truth_dir));
  const int map_w = static_cast<int>(std::lround((so.max_m.x() - so.min_m.x()) / options.truth_pitch_m));
  const int map_h = static_cast<int>(std::lround((so.max_m.y() - so.min_m.y()) / options.truth_pitch_m));
  Image regions(std::max(1, map_w), std::max(1, map_h), {"region"}, -1.0f);
  for (int j = 0; j < regions.height(); ++j) {
    for (int i = 0; i < regions.width(); ++i) {
      const Eigen::Vector2d x = so.min_m + Eigen::Vector2d(i + 0.5, j + 0.5) * options.truth_pitch_m;
      regions.at(i, j) = static_cast<float>(sample.RegionIndexAt(x));
    }
  }
  regions.attributes()["thinslab_version"] = THINSLAB_VERSION_STRING;
  regions.attributes()["git_hash"] = THINSLAB_GIT_HASH;
  regions.attributes()["grid"] = "pixel (i, j) = sample point region_min_m + (i + 0.5, j + 0.5) * pitch_m";
  THINSLAB_RETURN_IF_ERROR(WriteExr(JoinPath(truth_dir, "regions.exr"), regions));

  std::vector<std::string> table_channels;
  int bins = 0;
  for (int k = 0; k < sample.num_regions(); ++k) {
    if (sample.table(k)) {
      table_channels.push_back("region_" + std::to_string(k));
      bins = sample.table(k)->bins;
    }
  }
  if (!table_channels.empty()) {
    Image tables(bins, bins, table_channels);
    int c = 0;
    for (int k = 0; k < sample.num_regions(); ++k) {
      const SlabBtdfTable* t = sample.table(k);
      if (!t) continue;
      for (int row = 0; row < bins; ++row) {
        for (int col = 0; col < bins; ++col) tables.at(col, row, c) = t->rho[row * bins + col];
      }
      ++c;
    }
    tables.attributes()["grid"] =
        "pixel (col, row) = cell-mean BTDF [1/sr] for light direction i (sample frame, i.z < 0) with "
        "i.x in [-1 + col h, -1 + (col + 1) h), i.y in [-1 + row h, ...), h = 2 / bins, towards the region's view "
        "direction";
    THINSLAB_RETURN_IF_ERROR(WriteExr(JoinPath(truth_dir, "btdf_tables.exr"), tables));
  }

  nlohmann::json j;
  j["conventions"] = {
      {"top_face", "towards the monitor (light enters here); bottom = towards the camera"},
      {"optical_frame", "v_opt = (v.x, -v.y, -v.z): light direction i_opt.z > 0, view direction o_opt.z < 0"},
      {"anisotropy_axes", "alpha_x along sample x, alpha_y along sample y"},
      {"transmission", "R(x, i, o) = rho_d + k_s rho(x, i, o) [1/sr] (Dai Eq. 13)"},
      {"pixel_radiance",
       "L = sum over shown dots q of R(x, i_q, o) L_q A_q cos_e cos_i / r^2, cos_e = cos_i = d / r; L_q A_q = "
       "dot_radiance x rasterised dot area (the all-dots frame's integrated dot signal)"},
      {"btdf_source", "adjoint Monte Carlo table per region (sim/slab_sample.h), not the dual-microfacet formula"}};
  j["sample"] = {{"min_m", Vec(so.min_m)}, {"max_m", Vec(so.max_m)}};
  j["region_map"] = {{"file", "ground_truth/regions.exr"},
                     {"channel", "region"},
                     {"region_min_m", Vec(so.min_m)},
                     {"pitch_m", options.truth_pitch_m},
                     {"width_px", regions.width()},
                     {"height_px", regions.height()},
                     {"outside_value", -1}};
  j["tables"] = {{"file", table_channels.empty() ? "" : "ground_truth/btdf_tables.exr"},
                 {"bins", bins},
                 {"photons_per_region", so.photons_per_region},
                 {"slab_thickness_m", so.thickness_m},
                 {"max_interactions", so.max_interactions},
                 {"seed", so.seed},
                 {"tracing_s", sample.tracing_seconds()}};
  nlohmann::json regions_json = nlohmann::json::array();
  for (int k = 0; k < sample.num_regions(); ++k) {
    const SlabRegion& r = sample.region(k);
    const SlabBtdfTable* t = sample.table(k);
    nlohmann::json rj = {{"index", k},
                         {"name", r.name},
                         {"min_m", Vec(r.min_m)},
                         {"max_m", Vec(r.max_m)},
                         {"top", FaceJson(r.material.top)},
                         {"bottom", FaceJson(r.material.bottom)},
                         {"eta", r.material.eta},
                         {"rho_d", r.material.rho_d},
                         {"k_s", r.material.k_s},
                         {"smooth", r.material.IsSmooth()},
                         {"view_direction", Vec(sample.ViewDirection(k))},
                         {"view_direction_optical", Vec(SlabSample::ToOpticalFrame(sample.ViewDirection(k)))}};
    if (t) {
      rj["table"] = {{"channel", "region_" + std::to_string(k)},
                     {"transmitted", t->transmitted},
                     {"reflected", t->reflected},
                     {"masked", t->masked},
                     {"capped", t->capped},
                     {"seed", t->seed}};
    } else {
      rj["flat_slab_transmittance_at_view"] =
          SlabSample::FlatSlabTransmittance(sample.ViewDirection(k).z(), r.material.eta);
    }
    regions_json.push_back(rj);
  }
  j["regions"] = regions_json;
  const SimDotMonitorOptions& m = options.rig;
  j["rig"] = {{"monitor_distance_m", m.monitor_distance_m},
              {"monitor_center_in_sample_m", Vec(m.monitor_center_in_sample_m)},
              {"monitor_pixel_pitch_m", m.monitor_pixel_pitch_m},
              {"dot_radius_px", m.dot_radius_px},
              {"dot_radiance", m.dot_radiance},
              {"black_radiance", m.black_radiance},
              {"electrons_per_radiance_us", m.electrons_per_radiance_us},
              {"camera_centre_in_sample_m", Vec(monitor.CameraCentreInSample())},
              {"render_supersample", m.render_supersample},
              {"blur_sigma_px", m.blur_sigma_px},
              {"seed", m.seed}};
  j["sensor"] = {{"full_well_e", m.sensor.full_well_e},
                 {"read_noise_e", m.sensor.read_noise_e},
                 {"bit_depth", m.sensor.bit_depth},
                 {"black_level_dn", m.sensor.black_level_dn},
                 {"noise", m.sensor.enable_noise}};
  j["acquisition_s"] = acquisition_s;
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(truth_dir, "truth.json"), j.dump(2) + "\n"));
  return Status::Ok();
}

Status SynthesizeDotScanSession(const SyntheticDotScanOptions& options, const std::string& session_dir,
                                SyntheticDotScanResult* result) {
  std::unique_ptr<SimDotMonitor> monitor;
  std::shared_ptr<const SlabSample> sample;
  THINSLAB_RETURN_IF_ERROR(BuildDotScanRig(options, &monitor, &sample));
  const SlabSampleOptions& so = sample->options();

  RigInfo rig = monitor->rig();
  rig.sample.region_min_m = so.min_m;
  rig.sample.region_max_m = so.max_m;
  rig.sample.pixel_pitch_m = options.truth_pitch_m;
  rig.sample.glass_ior = so.regions.front().material.eta;
  rig.sample.glass_thickness_m = so.thickness_m;
  DotScanSessionOptions session = options.session;
  session.sync = SyncForSensor(session.sync, options.rig.sensor);
  session.monitor_width_px = options.rig.monitor_width_px;
  session.monitor_height_px = options.rig.monitor_height_px;
  const std::vector<Eigen::Vector2d> validation = DotScanValidationDots(session, options.validation_dots);
  session.validation_dots_px.insert(session.validation_dots_px.end(), validation.begin(), validation.end());

  const auto start = std::chrono::steady_clock::now();
  SessionWriter writer;
  THINSLAB_RETURN_IF_ERROR(OpenSimulatedSession(session_dir, options.name, "dot_scan", rig, &writer));
  // The frames are most of the time at the paper's size (docs/benchmarks.md): report them.
  THINSLAB_RETURN_IF_ERROR(RunReportedSimulation(
      "sim dot-scan: frames rendered", static_cast<int64_t>(PlanDotScan(session, monitor->refresh_period_s()).size()),
      options.progress, session_dir, &writer, [&]() {
        return RunDotScanSession(session, monitor->camera(), monitor.get(), monitor->sample_changer(), &writer);
      }));
  const double acquisition_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  THINSLAB_RETURN_IF_ERROR(WriteDotScanTruth(options, *sample, *monitor, acquisition_s, session_dir));
  if (result) {
    result->sample = sample;
    result->rig = rig;
    result->tracing_s = sample->tracing_seconds();
    result->acquisition_s = acquisition_s;
    result->frames = static_cast<int>(writer.session().frames.size());
  }
  return Status::Ok();
}

}  // namespace thinslab
