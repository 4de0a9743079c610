// SPDX-License-Identifier: Apache-2.0
// Failure boundaries of the dual-microfacet fit (issue #8, part 3; docs/stability.md): sweeps
// one axis at a time on the simulated dot rig and records, per value, the share of points that
// fit within tolerance, that carry a flag (status other than ok), and that are silently wrong
// (status ok, held-out error above tolerance), plus the median held-out error of the ok points.
//   roughness  one region, GGX rough top face, alpha 0.02 .. 1.5
//   dots       dot grid per side 5 .. 24 (two regions: GGX 0.2 both faces, GGX 0.6 top)
//   exposure   dot radiance x 0.01 .. 30 (same two regions); a refused capture is "refused"
//   pose       camera translation error 0 .. 8 mm in the manifest (2 px per mm at the sample)
//   monitor_distance  error of the monitor distance d in the manifest, -4 .. 8 mm (d = 40 mm)
//   monitor_distance_refined  the same, with d set from the grid's scale (refine_distance)
//   monitor_tilt      error of the monitor's tilt about the sample x axis, 0 .. 4 degrees
// The monitor axes use MonitorRig (GGX 0.2 both faces, GGX 0.3 top). Besides the tally, each row
// has the dot calibration's rms residual and the median NDF L2 error against the truth of the
// one-sided region (ggx_0.6_top, ggx_0.3_top on the monitor axes): the held-out dots are
// predicted through the same (wrong) geometry, so only the truth can see what it does to the NDF.
// Writes OUTDIR/stability_dmf.csv and OUTDIR/stability_dmf_<axis>.png.
//
//   stability_dmf OUTDIR        e.g. build/bench/stability_dmf docs/stability
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/plot.h"
#include "thinslab/fit/dmf_evaluation.h"
#include "thinslab/fit/dmf_map_fit.h"
#include "thinslab/fit/dmf_processing.h"
#include "thinslab/sim/synthesize_dot_scan_session.h"

namespace thinslab {
namespace {

constexpr double kHeldOutTolerance = 0.5;  // As tests/stability_dmf_test.cc.

struct Outcome {
  std::string axis;
  double value = 0;
  bool refused = false;
  std::string message;
  int points = 0, within = 0, flagged = 0, silent_wrong = 0;
  double median_held_out = -1;
  double dot_rms_residual_m = -1;
  double one_sided_ndf_l2 = -1;  // Median NDF relative L2 error of the one-sided region(s).
};

SlabRegion Region(const std::string& name, double x0, double x1, const SlabFace& top, const SlabFace& bottom) {
  SlabRegion r;
  r.name = name;
  r.min_m = Eigen::Vector2d(x0, -0.04);
  r.max_m = Eigen::Vector2d(x1, 0.04);
  r.material.top = top;
  r.material.bottom = bottom;
  return r;
}

SlabFace Ggx(double alpha) { return SlabFace{RoughSlabNdf::kGgx, alpha, alpha}; }

SyntheticDotScanOptions TwoRegionRig() {
  SyntheticDotScanOptions sim;
  sim.sample.regions = {Region("ggx_0.2_both", -0.04, 0, Ggx(0.2), Ggx(0.2)),
                        Region("ggx_0.6_top", 0, 0.04, Ggx(0.6), SlabFace())};
  sim.session.grid_nx = sim.session.grid_ny = 16;
  return sim;
}

// The monitor axes: a one-sided region of moderate roughness, whose NDF the truth can judge
// (the GGX 0.6 lobe of TwoRegionRig is wider than the monitor and mostly flagged).
SyntheticDotScanOptions MonitorRig() {
  SyntheticDotScanOptions sim;
  sim.sample.regions = {Region("ggx_0.2_both", -0.04, 0, Ggx(0.2), Ggx(0.2)),
                        Region("ggx_0.3_top", 0, 0.04, Ggx(0.3), SlabFace())};
  sim.session.grid_nx = sim.session.grid_ny = 16;
  return sim;
}

Outcome Evaluate(const std::string& axis, double value, const std::string& session, bool refine_distance) {
  Outcome o;
  o.axis = axis;
  o.value = value;
  DmfProcessingOptions processing;
  processing.pitch_m = 0.008;
  processing.hold_out = true;
  processing.dot_geometry.refine_distance = refine_distance;
  DmfSliceSet slices;
  DmfProcessingReport report;
  Status s = PrepareDotScanSlices(session, processing, &slices, &report);
  DmfMaps maps;
  DmfMapFitOptions options;
  options.cluster = false;
  if (s.ok()) s = FitDualMicrofacetMaps(slices, options, &maps);
  std::vector<DmfTruthRegion> truth;
  if (s.ok()) s = ReadDmfTruth(session, &truth);
  if (!s.ok()) {
    o.refused = true;
    o.message = s.message();
    return o;
  }
  std::vector<double> held;
  o.dot_rms_residual_m = report.dot_rms_residual_m;
  std::vector<double> l2;
  for (const DmfRegionAccuracy& a : CompareDmfWithTruth(slices, maps, truth, kHeldOutTolerance)) {
    if (a.median_ndf_l2 >= 0) l2.push_back(a.median_ndf_l2);
    o.points += a.points;
    o.flagged += a.flagged;
    o.silent_wrong += a.silent_wrong;
    o.within += a.ok - a.silent_wrong;
    if (a.median_held_out >= 0) held.push_back(a.median_held_out);
  }
  if (!held.empty()) {
    double sum = 0;
    for (double h : held) sum += h;
    o.median_held_out = sum / held.size();  // Mean over regions of their medians.
  }
  if (!l2.empty()) {
    double sum = 0;
    for (double e : l2) sum += e;
    o.one_sided_ndf_l2 = sum / l2.size();
  }
  return o;
}

// Simulates `sim` into dir/axis_value (or copies `copy_from`, an already simulated session),
// applies `edit` to the manifest, evaluates and removes the session.
Outcome Simulate(const std::string& dir, const std::string& axis, double value, const SyntheticDotScanOptions& sim,
                 const std::function<void(nlohmann::json*)>& edit = nullptr, const std::string& copy_from = "",
                 bool refine_distance = false) {
  const std::string session = dir + "/" + axis + "_" + std::to_string(value);
  std::filesystem::remove_all(session);
  const Status s = copy_from.empty() ? SynthesizeDotScanSession(sim, session) : Status::Ok();
  if (!copy_from.empty()) std::filesystem::copy(copy_from, session, std::filesystem::copy_options::recursive);
  if (!s.ok()) {
    Outcome o;
    o.axis = axis;
    o.value = value;
    o.refused = true;
    o.message = "simulation: " + s.message();
    return o;
  }
  if (edit) {
    nlohmann::json manifest;
    std::ifstream(session + "/session.json") >> manifest;
    edit(&manifest);
    std::ofstream(session + "/session.json") << manifest.dump(2);
  }
  Outcome o = Evaluate(axis, value, session, refine_distance);
  std::filesystem::remove_all(session);
  std::fprintf(stderr,
               "%s %g: %s points %d within %d flagged %d silent-wrong %d held-out %.3f dot rms %.4f mm ndf l2 %.3f\n",
               axis.c_str(), value, o.refused ? ("refused (" + o.message + ")").c_str() : "", o.points, o.within,
               o.flagged, o.silent_wrong, o.median_held_out, o.dot_rms_residual_m * 1e3, o.one_sided_ndf_l2);
  return o;
}

Status Chart(const std::string& path, const std::vector<Outcome>& outcomes, const std::string& axis,
             const std::string& x_label, bool log_x) {
  PlotSeries within, flagged, wrong, refused, held, tolerance;
  within.label = "within tolerance";
  within.line = true;
  within.color_bgr = 0x2ca02c;
  flagged.label = "flagged (status says why)";
  flagged.line = true;
  flagged.color_bgr = 0x1f77b4;
  wrong.label = "silent wrong (ok, held-out > 0.5)";
  wrong.line = true;
  wrong.color_bgr = 0xd62728;
  refused.label = "capture refused (clear error)";
  refused.color_bgr = 0x000000;
  held.label = "median held-out in-lobe RMS";
  held.line = true;
  held.color_bgr = 0x9467bd;
  PlotSeries ndf, dot_rms;
  ndf.label = "median NDF L2 vs truth (one-sided)";
  ndf.line = true;
  ndf.color_bgr = 0xff7f0e;
  dot_rms.label = "dot calibration rms residual";
  dot_rms.line = true;
  dot_rms.color_bgr = 0x17becf;
  tolerance.label = "tolerance";
  tolerance.line = true;
  tolerance.color_bgr = 0x888888;
  for (const Outcome& o : outcomes) {
    if (o.axis != axis) continue;
    if (o.refused) {
      refused.x.push_back(o.value);
      refused.y.push_back(1.0);
      continue;
    }
    const double n = std::max(1, o.points);
    within.x.push_back(o.value);
    within.y.push_back(o.within / n);
    flagged.x.push_back(o.value);
    flagged.y.push_back(o.flagged / n);
    wrong.x.push_back(o.value);
    wrong.y.push_back(o.silent_wrong / n);
    if (o.median_held_out >= 0) {
      held.x.push_back(o.value);
      held.y.push_back(o.median_held_out);
    }
    if (o.one_sided_ndf_l2 >= 0) {
      ndf.x.push_back(o.value);
      ndf.y.push_back(o.one_sided_ndf_l2);
    }
    if (o.dot_rms_residual_m >= 0) {
      dot_rms.x.push_back(o.value);
      dot_rms.y.push_back(o.dot_rms_residual_m * 1e3);
    }
    tolerance.x.push_back(o.value);
    tolerance.y.push_back(kHeldOutTolerance);
  }
  PlotPanel shares;
  shares.y_label = "share of points";
  shares.series = {within, flagged, wrong};
  if (!refused.x.empty()) shares.series.push_back(refused);
  shares.height_weight = 1.4;
  PlotPanel errors;
  errors.y_label = "relative error (log)";
  errors.log_y = true;
  errors.series = {held, ndf, tolerance};
  PlotPanel calibration;
  calibration.y_label = "dot rms residual [mm] (log)";
  calibration.log_y = true;
  calibration.series = {dot_rms};
  calibration.height_weight = 0.6;
  PlotOptions options;
  options.title = "Dual-microfacet fit stability: " + axis;
  options.x_label = x_label;
  options.log_x = log_x;
  return WritePlotPng(path, {shares, errors, calibration}, options);
}

}  // namespace
}  // namespace thinslab

int main(int argc, char** argv) {
  using namespace thinslab;
  if (argc != 2) {
    std::fprintf(stderr, "usage: stability_dmf OUTDIR\n");
    return 2;
  }
  const std::string out = argv[1];
  std::filesystem::create_directories(out);
  const std::string work = (std::filesystem::temp_directory_path() / "thinslab_stability_dmf").string();
  std::filesystem::create_directories(work);
  std::vector<Outcome> outcomes;
  for (double alpha : {0.02, 0.04, 0.07, 0.1, 0.2, 0.4, 0.7, 1.0, 1.5}) {
    SyntheticDotScanOptions sim;
    sim.sample.regions = {Region("ggx_top", -0.04, 0.04, Ggx(alpha), SlabFace())};
    sim.session.grid_nx = sim.session.grid_ny = 16;
    outcomes.push_back(Simulate(work, "roughness", alpha, sim));
  }
  for (int dots : {5, 6, 8, 10, 12, 16, 20, 24}) {
    SyntheticDotScanOptions sim = TwoRegionRig();
    sim.session.grid_nx = sim.session.grid_ny = dots;
    outcomes.push_back(Simulate(work, "dots", dots, sim));
  }
  for (double scale : {0.01, 0.03, 0.1, 0.25, 1.0, 4.0, 10.0, 30.0}) {
    SyntheticDotScanOptions sim = TwoRegionRig();
    sim.rig.dot_radiance *= scale;
    outcomes.push_back(Simulate(work, "exposure", scale, sim));
  }
  const std::string pose_base = work + "/pose_base";
  std::filesystem::remove_all(pose_base);
  const Status base = SynthesizeDotScanSession(TwoRegionRig(), pose_base);
  if (!base.ok()) {
    std::fprintf(stderr, "error: %s\n", base.message().c_str());
    return 1;
  }
  for (double shift_mm : {0.0, 1.0, 2.0, 4.0, 8.0}) {
    outcomes.push_back(Simulate(
        work, "pose", shift_mm, TwoRegionRig(),
        [&](nlohmann::json* m) {
          auto& t = (*m)["rig"]["cameras"][0]["cam_from_sample"]["translation_m"];
          t[0] = t[0].get<double>() + shift_mm * 1e-3;
        },
        pose_base));
  }
  // The monitor pose in the manifest: d wrong by delta (the screen plane z = -d of the sample
  // frame moved along its normal), as given and with the distance set from the grid's scale;
  // or the screen tilted about the sample x axis through its centre.
  const std::string monitor_base = work + "/monitor_base";
  std::filesystem::remove_all(monitor_base);
  const Status monitor_sim = SynthesizeDotScanSession(MonitorRig(), monitor_base);
  if (!monitor_sim.ok()) {
    std::fprintf(stderr, "error: %s\n", monitor_sim.message().c_str());
    return 1;
  }
  for (const bool refine : {false, true}) {
    for (double delta_mm : {-4.0, -2.0, -1.0, -0.5, 0.0, 0.5, 1.0, 2.0, 4.0, 8.0}) {
      outcomes.push_back(Simulate(
          work, refine ? "monitor_distance_refined" : "monitor_distance", delta_mm, MonitorRig(),
          [&](nlohmann::json* m) {
            auto& t = (*m)["rig"]["monitor"]["sample_from_monitor"]["translation_m"];
            t[2] = t[2].get<double>() - delta_mm * 1e-3;
          },
          monitor_base, refine));
    }
  }
  for (double tilt_deg : {0.0, 0.25, 0.5, 1.0, 2.0, 4.0}) {
    outcomes.push_back(Simulate(
        work, "monitor_tilt", tilt_deg, MonitorRig(),
        [&](nlohmann::json* m) {
          auto& pose = (*m)["rig"]["monitor"]["sample_from_monitor"];
          auto& q = pose["rotation_wxyz"];
          auto& t = pose["translation_m"];
          const Eigen::Quaterniond rotation(q[0].get<double>(), q[1].get<double>(), q[2].get<double>(),
                                            q[3].get<double>());
          const Eigen::Vector3d translation(t[0].get<double>(), t[1].get<double>(), t[2].get<double>());
          const int w = (*m)["rig"]["monitor"]["width_px"].get<int>(), h = (*m)["rig"]["monitor"]["height_px"].get<int>();
          const double pitch = (*m)["rig"]["monitor"]["pixel_pitch_m"].get<double>();
          const Eigen::Vector3d centre = rotation * Eigen::Vector3d(0.5 * w * pitch, 0.5 * h * pitch, 0) + translation;
          const Eigen::Quaterniond tilt(Eigen::AngleAxisd(tilt_deg * kPi / 180, Eigen::Vector3d::UnitX()));
          const Eigen::Quaterniond r = (tilt * rotation).normalized();
          const Eigen::Vector3d tr = tilt * (translation - centre) + centre;
          pose["rotation_wxyz"] = {r.w(), r.x(), r.y(), r.z()};
          pose["translation_m"] = {tr.x(), tr.y(), tr.z()};
        },
        monitor_base));
  }
  std::ostringstream csv;
  csv << "axis,value,refused,points,within_tolerance,flagged,silent_wrong,median_held_out,dot_rms_residual_m,"
         "one_sided_ndf_l2,message\n";
  for (const Outcome& o : outcomes) {
    std::string message = o.message;
    for (char& c : message) c = c == ',' || c == '"' ? ';' : c;
    csv << o.axis << "," << o.value << "," << o.refused << "," << o.points << "," << o.within << "," << o.flagged
        << "," << o.silent_wrong << "," << o.median_held_out << "," << o.dot_rms_residual_m << ","
        << o.one_sided_ndf_l2 << "," << message << "\n";
  }
  Status s = WriteFileAtomically(out + "/stability_dmf.csv", csv.str());
  if (s.ok()) s = Chart(out + "/stability_dmf_roughness.png", outcomes, "roughness", "GGX alpha of the top face (log)", true);
  if (s.ok()) s = Chart(out + "/stability_dmf_dots.png", outcomes, "dots", "dots per side of the grid", false);
  if (s.ok()) s = Chart(out + "/stability_dmf_exposure.png", outcomes, "exposure", "dot radiance / rig default (log)", true);
  if (s.ok()) s = Chart(out + "/stability_dmf_pose.png", outcomes, "pose", "camera translation error [mm] (2 px/mm)", false);
  if (s.ok()) {
    s = Chart(out + "/stability_dmf_monitor_distance.png", outcomes, "monitor_distance",
              "d error in the manifest [mm] (d = 40 mm)", false);
  }
  if (s.ok()) {
    s = Chart(out + "/stability_dmf_monitor_distance_refined.png", outcomes, "monitor_distance_refined",
              "d error in the manifest [mm], then set from the grid scale", false);
  }
  if (s.ok()) {
    s = Chart(out + "/stability_dmf_monitor_tilt.png", outcomes, "monitor_tilt",
              "monitor tilt error in the manifest [deg]", false);
  }
  std::filesystem::remove_all(work);
  if (!s.ok()) {
    std::fprintf(stderr, "error: %s\n", s.message().c_str());
    return 1;
  }
  return 0;
}
