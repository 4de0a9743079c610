// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/dmf_processing.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <sstream>

#include "thinslab/core/grid_size.h"
#include "thinslab/core/memory.h"
#include "thinslab/calib/board_rectification.h"
#include "thinslab/calib/hdr_merge.h"
#include "thinslab/core/camera_model.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/parallel.h"
#include "thinslab/core/process_group.h"
#include "thinslab/core/session_io.h"

namespace thinslab {

namespace {
// Dots inside the camera's view (5 % margin) that detection may miss before the fit stops.
constexpr double kMaxMissedDotsInView = 0.05;
// Dot brackets a process merges at once (PrepareDotScanSlices); each holds its frames, HDR
// images and a column of every point.
constexpr int kDotBracketsInFlight = 2;

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

std::string DotName(const Eigen::Vector2d& px) {
  std::ostringstream s;
  s << "dot (" << px.x() << ", " << px.y() << ")";
  return s.str();
}

// rig.json's dots must be the scan's grid, in the same (row-major) order.
Status CheckCalibratedDots(const RigMonitorCalibration& monitor, const std::vector<Eigen::Vector2d>& displayed) {
  if (monitor.dots.size() != displayed.size()) {
    return Status::Error("dots: " + std::to_string(monitor.dots.size()) + " calibrated dots, the scan shows " +
                         std::to_string(displayed.size()) +
                         " (rerun `thinslab calib dots` on this grid, or fit with --calibration none)");
  }
  for (size_t k = 0; k < displayed.size(); ++k) {
    if ((monitor.dots[k].dot_px - displayed[k]).norm() > 1e-6) {
      return Status::Error("dots[" + std::to_string(k) + "].dot_px: " + DotName(monitor.dots[k].dot_px) +
                           ", the scan's dot " + std::to_string(k) + " is " + DotName(displayed[k]));
    }
  }
  return Status::Ok();
}

}  // namespace

Status MeasureAllDotsGeometry(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                              const CameraResponse* response, const std::vector<Eigen::Vector2d>& displayed,
                              const DotGeometryOptions& options, DotGeometryResult* geometry, std::string* source_file) {
  const std::string manifest = JoinPath(session_dir, kSessionManifestName);
  const auto all_dots = session.UsableFrames("all_dots", "none");
  if (all_dots.empty()) {
    return Status::Error(manifest + ": no usable 'all_dots' frame with sample_state 'none': the dot positions " +
                         "cannot be calibrated (Dai et al. Sec. 4.1 locate them without the sample)");
  }
  std::vector<const FrameRecord*> by_exposure = all_dots;
  std::sort(by_exposure.begin(), by_exposure.end(),
            [](const FrameRecord* a, const FrameRecord* b) { return a->exposure_time_us > b->exposure_time_us; });
  const double saturation = camera.saturation_dn - camera.black_level_dn;
  const double linear_saturation = response != nullptr ? response->Linearize(saturation) : saturation;
  bool have_geometry = false;
  std::string geometry_error;
  for (const FrameRecord* f : by_exposure) {
    Image frame;
    THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *f, &frame));
    LinearizeFrame(response, &frame);
    DotGeometryResult g;
    const Status s = CalibrateDotGeometry(frame, f->exposure_time_us, linear_saturation, camera,
                                          session.rig.monitor, displayed, options, &g);
    if (!s.ok()) {
      geometry_error = f->file + ": " + s.message();
      continue;
    }
    *geometry = g;
    *source_file = f->file;
    have_geometry = true;
    if (std::none_of(g.dots.begin(), g.dots.end(), [](const DotRecord& d) { return d.measured() && d.saturated; })) break;
  }
  if (!have_geometry) return Status::Error("dot geometry: " + geometry_error);
  if (std::none_of(geometry->dots.begin(), geometry->dots.end(),
                   [](const DotRecord& d) { return d.measured() && !d.saturated; })) {
    // The dots were found only in frames where they saturate; say why the shorter ones failed.
    return Status::Error("dot geometry: every dot is saturated in " + *source_file +
                         ", the all-dots frame in which they were found, so L_q cannot be measured (the all-dots "
                         "bracket needs an exposure in which the dots are found and not saturated)" +
                         (geometry_error.empty() ? std::string() : "; in shorter exposures: " + geometry_error));
  }
  return Status::Ok();
}

bool DmfProcessingOptions::Check(std::string* error) const {
  std::ostringstream e;
  if (pitch_m < 0) e << "pitch must be >= 0, got " << pitch_m;
  else if (!(dot_radius_px >= 0 && dot_radius_px <= 1000)) {
    e << "dot_radius_px (--dot-radius-px) must be in [0, 1000] px (0: the manifest's), got " << dot_radius_px;
  }
  else if (!(max_saturated_dots >= 0 && max_saturated_dots <= 1)) e << "max_saturated_dots must be in [0, 1]";
  else if (!(max_saturated_points >= 0 && max_saturated_points <= 1)) e << "max_saturated_points must be in [0, 1]";
  else if (supersample < 1 || supersample > 8) e << "supersample must be in [1, 8], got " << supersample;
  else if (!(glass_thickness_m <= 0.05)) e << "glass_thickness_m (--glass-thickness-mm) must be <= 50 mm";
  else if (!(eta == 0 || (eta > 1 && eta <= 4))) e << "eta must be 0 (the manifest's) or in (1, 4], got " << eta;
  else if (std::string pattern_error; !hold_out_pattern.Check(&pattern_error)) e << pattern_error;
  else if (!(max_memory_bytes >= 0)) e << "max_memory_bytes (--max-memory) must be >= 0 (0 = no budget)";
  else if (stream_band_points < 0) e << "stream_band_points (--stream-band-points) must be >= 0, got " << stream_band_points;
  else if ((max_memory_bytes > 0 || stream_band_points > 0) && spill_dir.empty()) {
    e << "spill_dir: needed with a memory budget";
  }
  else if (fit_ndf_resolution < 1) e << "fit_ndf_resolution must be >= 1";
  else if (num_threads < 1 || num_threads > kMaxThreads)
    e << "num_threads must be in 1.." << kMaxThreads;
  else if (!(fit_cluster_fraction > 0 && fit_cluster_fraction <= 1)) e << "fit_cluster_fraction must be in (0, 1]";
  *error = e.str();
  return error->empty();
}

Status PlanDmfMemory(int num_points, int grid_width, int num_dots, int num_validation_dots, double camera_pixels,
                     const DmfProcessingOptions& options, DmfMemoryPlan* plan) {
  // What the chain keeps, in bytes (fit/dmf_map_fit.cc, fit/dmf_clustering.cc):
  const double np = num_points, nd = num_dots;
  const double ndf = 8.0 * Sqr(options.fit_ndf_resolution);  // One point's log_ndf (doubles).
  const double shape = 4.0 * nd;  // A slice shape: about one u-grid node per dot (fit/dmf_slice_shape.h).
  // Per point whatever the mode: its fit and clustering entries, the map images, the
  // rectifier's sub-samples, the validation dots' values, the stages' per-point vectors and
  // (under MPI; counted on one process too, the estimate stays an upper bound) the 9 bytes a
  // point of each dot column in flight of a round.
  const double per_point = sizeof(DmfPointFit) + 4 * (4 + 8) + 24 * 4 + 16 * 4 + 3 * 8 +
                           Sqr(options.supersample) * 8.0 + 8.0 * num_validation_dots + 64 + 9.0 * kDotBracketsInFlight;
  // Whatever the grid: the process itself (about 100 MiB resident for a tiny fit: code, libraries,
  // the capture's manifest), the brackets in flight's camera frames and HDR images (about 64
  // bytes per camera pixel each), the PCA subsample's shapes.
  const double fixed = 128.0 * (1 << 20) + 64.0 * kDotBracketsInFlight * camera_pixels + 20000 * shape;
  const double representatives = std::min(np, std::max(64.0, options.fit_cluster_fraction * np));
  // The representatives' NDFs once more, linear (DmfMaps::representative_ndf).
  plan->in_memory_bytes = fixed + np * (8 * nd + shape + ndf + per_point) + representatives * ndf;
  plan->spill_file_bytes = 8 * np * nd;
  plan->streamed = options.stream_band_points > 0 ||
                   (options.max_memory_bytes > 0 && plan->in_memory_bytes > options.max_memory_bytes);
  if (!plan->streamed) {
    plan->band_points = num_points;
    plan->streamed_bytes = plan->in_memory_bytes;
    return Status::Ok();
  }
  // Streamed: a band's values, sigmas and shapes in memory (and LoadBand's 16 columns); the
  // representatives' NDFs kept, in logarithms and linear.
  const double resident = fixed + np * per_point + 2 * representatives * ndf;
  const double per_band_point = 8 * nd + shape + 64;
  double band = options.max_memory_bytes > 0 ? std::floor((options.max_memory_bytes - resident) / per_band_point) : np;
  if (options.stream_band_points > 0) band = std::max<double>(grid_width, std::min<double>(band, options.stream_band_points));
  char text[400];
  if (band < grid_width) {
    std::snprintf(text, sizeof(text),
                  "--max-memory %.2f GiB is too small for %d points x %d dots: streamed, the fit keeps %.2f GiB and a "
                  "band of one grid row (%d points) needs %.2f GiB more",
                  options.max_memory_bytes / double(1u << 30), num_points, num_dots, resident / double(1u << 30),
                  grid_width, grid_width * per_band_point / double(1u << 30));
    return Status::Error(text);
  }
  // Whole grid rows, so that a band is a strip of the map.
  plan->band_points = static_cast<int>(std::min(np, std::floor(band / grid_width) * grid_width));
  plan->streamed_bytes = resident + plan->band_points * per_band_point;
  return Status::Ok();
}

namespace {

Status MeasureDarkLevel(const std::string& session_dir, const Session& session, const CameraInfo& camera,
                        const std::vector<const FrameRecord*>& darks, const BoardRectifier& rectifier,
                        DmfProcessingReport* report) {
  const double range = camera.saturation_dn - camera.black_level_dn;
  const FrameRecord* longest = nullptr;
  for (const FrameRecord* d : darks) {
    if (d->camera_id == camera.id && (longest == nullptr || d->exposure_time_us > longest->exposure_time_us)) longest = d;
  }
  if (longest == nullptr || !(range > 0)) return Status::Ok();
  Image dark;
  THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *longest, &dark));
  std::vector<float> at_points = rectifier.Rectify(dark).data();
  std::nth_element(at_points.begin(), at_points.begin() + at_points.size() / 2, at_points.end());
  report->dark_exposure_us = longest->exposure_time_us;
  report->dark_fraction_of_range = at_points[at_points.size() / 2] / range;
  if (report->dark_fraction_of_range > kMaxDarkFractionOfRange) {
    char text[512];
    std::snprintf(text, sizeof(text),
                  "%s: at the sample points the dark frame (display black, with the sample) has a median of %.0f %% "
                  "of the camera's range at %.0f us: the display's black level (or ambient light) leaves the dots' "
                  "lobes the rest, and its shot noise hides their tails, so lobes read narrower than they are "
                  "(flagged specular). Use a display with a darker black, or darken the room: a shorter longest exposure "
                  "does not help (docs/acquisition.md, \"Exposure planning\")",
                  longest->file.c_str(), 100 * report->dark_fraction_of_range, longest->exposure_time_us);
    report->dark_level_warning = text;
  }
  return Status::Ok();
}

}  // namespace

Status PrepareDotScanSlices(const std::string& session_dir, const DmfProcessingOptions& options, DmfSliceSet* slices,
                            DmfProcessingReport* report) {
  const auto start = std::chrono::steady_clock::now();
  std::string error;
  if (!options.Check(&error)) return Status::Error("dmf processing options: " + error);
  Session session;
  THINSLAB_RETURN_IF_ERROR(ReadCapture(session_dir, options.incomplete_capture, &session, &report->capture));
  const std::string manifest = session_dir + "/session.json";
  if (session.rig.cameras.empty()) return Status::Error(manifest + ": rig.cameras is empty");
  CameraInfo camera = session.rig.cameras[0];
  THINSLAB_RETURN_IF_ERROR(LoadSessionCalibration(session_dir, options.calibration, &camera, &report->calibration));
  const CameraResponse* response = report->calibration.response_or_null();
  const MonitorInfo& monitor = session.rig.monitor;
  if (!monitor.present || !(monitor.pixel_pitch_m > 0)) {
    return Status::Error(manifest + ": rig.monitor is missing (a CRT dot scan needs the monitor geometry)");
  }

  // Dot frames grouped by displayed position; the grid must be regular (row-major, x fastest).
  std::map<std::pair<double, double>, std::vector<const FrameRecord*>> by_dot;  // (y, x) -> bracket.
  const auto dot_frames = session.UsableFrames("dot");
  if (dot_frames.empty()) return Status::Error(manifest + ": no usable frames of kind 'dot' (not a dot scan?)");
  std::string sample_state;
  for (const FrameRecord* f : dot_frames) {
    if (f->camera_id != camera.id) continue;
    if (!f->light.dot_px) {
      return Status::Error(manifest + ": frame " + std::to_string(f->index) + " (" + f->file +
                           "): light.dot_px is missing: the dot position of a 'dot' frame is required");
    }
    by_dot[{f->light.dot_px->y(), f->light.dot_px->x()}].push_back(f);
    sample_state = f->sample_state;
  }
  std::set<double> xs, ys;
  for (const auto& [yx, frames] : by_dot) {
    ys.insert(yx.first);
    xs.insert(yx.second);
  }
  const int nx = static_cast<int>(xs.size()), ny = static_cast<int>(ys.size());
  if (static_cast<size_t>(nx) * ny != by_dot.size()) {
    return Status::Error(manifest + ": the " + std::to_string(by_dot.size()) +
                         " dot positions do not form a regular grid (" + std::to_string(nx) + " x " +
                         std::to_string(ny) + " distinct x and y)");
  }
  if (nx < 4 || ny < 4) {
    return Status::Error(manifest + ": " + std::to_string(nx) + " x " + std::to_string(ny) +
                         " dots; the dual-microfacet fit needs at least 4 x 4 (Dai et al. use 40 x 40)");
  }
  std::vector<Eigen::Vector2d> displayed;
  for (const auto& [yx, frames] : by_dot) displayed.emplace_back(yx.second, yx.first);

  // 1. Dot geometry and L_q: from rig.json's monitor section (`thinslab calib dots`) if present,
  // else from the all-dots frame without the sample.
  auto t = std::chrono::steady_clock::now();
  DotGeometryResult geometry;
  const RigMonitorCalibration& calibrated = report->calibration.monitor;
  report->dot_radius_px = ResolveDotRadiusPx(options.dot_radius_px, monitor, &report->dot_radius_source);
  if (calibrated.present) {
    report->dot_radius_px = calibrated.dot_radius_px;
    report->dot_radius_source = report->calibration.rig_file;
  }
  if (calibrated.present) {
    if (options.dot_geometry.refine_distance) {
      return Status::Error(report->calibration.rig_file +
                           ": monitor: the dot positions come from `thinslab calib dots`; refine the monitor distance "
                           "there (calib dots --refine-distance), not in the fit");
    }
    THINSLAB_RETURN_IF_ERROR(
        CheckCalibratedDots(calibrated, displayed).WithContext(report->calibration.rig_file + ": monitor"));
    geometry.dots = calibrated.dots;
    geometry.sample_from_monitor = calibrated.sample_from_monitor;
    geometry.rms_residual_m = calibrated.rms_residual_m;
    geometry.distance_error_m = calibrated.distance_error_m;
    geometry.distance_error_sigma_m = calibrated.distance_error_sigma_m;
    geometry.distance_correction_m = calibrated.distance_correction_m;
    report->dot_geometry_source = report->calibration.rig_file;
  } else {
    DotGeometryOptions geometry_options = options.dot_geometry;
    geometry_options.dot_radius_px = report->dot_radius_px;
    THINSLAB_RETURN_IF_ERROR(
        MeasureAllDotsGeometry(session_dir, session, camera, response, displayed, geometry_options, &geometry,
                               &report->dot_geometry_source));
    report->dots_found_by_grid_prior = geometry.num_found_by_grid_prior;
  }
  std::vector<double> radiances;
  int missed_in_view = 0;
  for (const DotRecord& d : geometry.dots) {
    // Detection refines a dot's position; it is not a gate (issue #23): a dot the camera does not
    // see still lights the sample, from where the fitted monitor geometry puts it.
    if (!d.detected && !d.placed_from_geometry) {
      return Status::Error("dot geometry: " + DotName(d.dot_px) + " has no position in " + report->dot_geometry_source +
                           " (written before dots were placed from the monitor geometry: rerun `thinslab calib dots`)");
    }
    report->dots_placed_from_geometry += d.placed_from_geometry;
    report->dots_clipped += d.clipped;
    if (d.measured() && !d.saturated) radiances.push_back(d.radiance_dn_per_us);
    // A dot placed from the geometry although it falls well inside the frame was missed, not
    // out of view: the all-dots frame is too dark, too bright or not of this grid.
    Eigen::Vector2d px;
    const double margin = 0.05 * std::min(camera.width_px, camera.height_px);
    if (!d.detected && ProjectSamplePoint(camera, d.position_in_sample_m, &px) && px.x() > margin &&
        px.y() > margin && px.x() < camera.width_px - margin && px.y() < camera.height_px - margin) {
      ++missed_in_view;
    }
  }
  if (missed_in_view > kMaxMissedDotsInView * static_cast<double>(geometry.dots.size())) {
    return Status::Error("dot geometry: " + std::to_string(missed_in_view) + " of " +
                         std::to_string(geometry.dots.size()) + " dots inside the camera's view were not found in " +
                         report->dot_geometry_source +
                         " (too dark or too bright an all-dots frame, or another grid than the scan's); check its "
                         "exposure, or `thinslab calib dots` with other thresholds");
  }
  if (radiances.empty()) {
    // The dots were found only in frames where they saturate; say why the shorter ones failed.
    return Status::Error("dot geometry: every dot is saturated in " + report->dot_geometry_source +
                         ", so L_q cannot be measured");
  }
  std::nth_element(radiances.begin(), radiances.begin() + radiances.size() / 2, radiances.end());
  const double median_radiance = radiances[radiances.size() / 2];
  report->geometry_s = Seconds(t);

  // Sample grid.
  const SampleInfo& sample = session.rig.sample;
  const double pitch = options.pitch_m > 0 ? options.pitch_m : sample.pixel_pitch_m;
  if (!(pitch > 0)) return Status::Error(manifest + ": rig.sample.pixel_pitch_m is 0 and no pitch was given");
  BoardGrid grid;
  grid.grid_min_m = sample.region_min_m;
  grid.pixel_pitch_m = pitch;
  THINSLAB_RETURN_IF_ERROR(CheckedGridSize(sample.region_max_m.x() - sample.region_min_m.x(),
                                           sample.region_max_m.y() - sample.region_min_m.y(), pitch, GridRounding::kFloor,
                                           1, manifest + ": rig.sample (region_min_m, region_max_m) at pitch " +
                                                  std::to_string(pitch) + " m (--pitch-mm or rig.sample.pixel_pitch_m)",
                                           &grid.width_px, &grid.height_px));
  grid.plane_z_m = 0;
  grid.supersample = options.supersample;
  // In memory or streamed (PlanDmfMemory, --max-memory), and refused before the slices are
  // allocated when even that needs more than the machine has.
  // Validation dots (FrameRecord::validation): measured the same way, placed from the fitted
  // monitor geometry with the median L_q (they are not in the all-dots grid), never fitted.
  std::map<std::pair<double, double>, std::vector<const FrameRecord*>> validation_by_dot;
  for (const FrameRecord* f : session.ValidationFrames("dot", sample_state)) {
    if (f->camera_id != camera.id || !f->light.dot_px) continue;
    validation_by_dot[{f->light.dot_px->y(), f->light.dot_px->x()}].push_back(f);
  }
  const std::string grid_text = manifest + ": the " + std::to_string(grid.width_px) + " x " +
                                std::to_string(grid.height_px) + " point grid of " + std::to_string(displayed.size()) +
                                " dots (--pitch-mm or rig.sample.pixel_pitch_m)";
  THINSLAB_RETURN_IF_ERROR(PlanDmfMemory(grid.width_px * grid.height_px, grid.width_px,
                                         static_cast<int>(displayed.size()), static_cast<int>(validation_by_dot.size()),
                                         static_cast<double>(camera.width_px) * camera.height_px, options,
                                         &report->memory)
                               .WithContext(grid_text));
  if (report->memory.streamed && !options.streaming_refused_by.empty()) {
    char need[64];
    std::snprintf(need, sizeof(need), "%.1f", report->memory.in_memory_bytes / double(1u << 30));
    return Status::Error(options.streaming_refused_by + ": not available on a fit streamed from disk (" + grid_text +
                         " needs about " + need + " GiB in memory; --max-memory " + need + " or a coarser --pitch-mm)");
  }
  THINSLAB_RETURN_IF_ERROR(CheckMemoryNeed(
      report->memory.streamed_bytes,
      grid_text + (report->memory.streamed ? "" : " in memory (--max-memory streams it from disk)")));
  // Eq. 12 gives each grid point one lighting direction per dot; averaging a coarse cell
  // (8 mm at 40 mm from the monitor spans +-6 degrees) would blur the lobe by that spread, so
  // the cell is sampled at supersample^2 points instead (docs/models/dual_microfacet_fit.md).
  grid.average_footprint = false;
  const BoardRectifier rectifier(camera, grid);

  slices->width = grid.width_px;
  slices->height = grid.height_px;
  slices->grid_min_m = grid.grid_min_m;
  slices->pitch_m = pitch;
  slices->dots_nx = nx;
  slices->dots_ny = ny;
  slices->dot_positions.clear();
  for (const DotRecord& d : geometry.dots) slices->dot_positions.push_back(d.position_in_sample_m);
  const double step_x = nx > 1 ? (*xs.rbegin() - *xs.begin()) / (nx - 1) : 1;
  const double step_y = ny > 1 ? (*ys.rbegin() - *ys.begin()) / (ny - 1) : 1;
  slices->dot_cell_area_m2 = step_x * step_y * Sqr(monitor.pixel_pitch_m);
  report->cam_from_sample = camera.cam_from_sample;
  const Eigen::Matrix3d r = camera.cam_from_sample.rotation.toRotationMatrix();
  slices->camera_centre = -r.transpose() * camera.cam_from_sample.translation;
  // The slab's thickness moves where each dot's light enters (DmfSliceSet::LightEntryPoint).
  slices->glass_thickness_m =
      options.glass_thickness_m >= 0 ? options.glass_thickness_m : session.rig.sample.glass_thickness_m;
  slices->eta = options.eta > 0 ? options.eta : session.rig.sample.glass_ior;
  report->glass_thickness_m = slices->glass_thickness_m;
  const int np = slices->num_points(), nd = static_cast<int>(displayed.size());
  if (report->memory.streamed) {
    std::unique_ptr<DmfSliceSpill> spill;
    THINSLAB_RETURN_IF_ERROR(DmfSliceSpill::Create(options.spill_dir, np, nd, report->memory.band_points, &spill));
    slices->spill = std::move(spill);
    slices->value.clear();
    slices->sigma.clear();
    report->slice_bytes = slices->spill->BandBytes();
  } else {
    slices->value.assign(static_cast<size_t>(np) * nd, 0.0f);
    slices->sigma.assign(static_cast<size_t>(np) * nd, 0.0f);
    report->slice_bytes = (slices->value.size() + slices->sigma.size()) * sizeof(float);
  }
  slices->train = HoldOutTrainMask(nx, ny, options.hold_out, options.hold_out_pattern);
  slices->point_status.assign(np, static_cast<uint8_t>(DmfStatus::kOk));

  // 2-3. One dot at a time: merge, rectify, Eq. 12.
  t = std::chrono::steady_clock::now();
  const auto darks = session.UsableFrames("dark", sample_state);
  THINSLAB_RETURN_IF_ERROR(ResolveFrameNoise(session_dir, session, camera, &report->noise));
  THINSLAB_RETURN_IF_ERROR(MeasureDarkLevel(session_dir, session, camera, darks, rectifier, report));
  SessionDarks dark_frames;  // Read and averaged once for all the dots' merges.
  THINSLAB_RETURN_IF_ERROR(LoadSessionDarks(session_dir, session, darks, response, &dark_frames));
  // A of Eq. 12 with the dot radius L_q was measured with (L_q A is the dot's intensity).
  const double dot_radius_px = calibrated.present ? calibrated.dot_radius_px : report->dot_radius_px;
  const double dot_area = kPi * Sqr(dot_radius_px * monitor.pixel_pitch_m);
  std::vector<int> saturated_dots(np, 0);
  // Where each point's light enters the slab (the same for every dot).
  std::vector<Eigen::Vector3d> entry_points(np);
  for (int p = 0; p < np; ++p) entry_points[p] = slices->LightEntryPoint(p);
  const int check_stride = std::max(1, nd / kDotsExposureChecked);
  // One dot's bracket: merged, rectified, Eq. 12 with L_q and the dot's position, into a column
  // of each point's R, its sigma and whether every exposure saturated there.
  struct DotJob {
    const std::vector<const FrameRecord*>* frames;
    Eigen::Vector3d position;
    double l_q;
    std::string name;
    bool check;        // Measure the exposures the camera applied (one bracket in kDotsExposureChecked).
    int column;        // Grid dot q, or validation dot (column - nd).
  };
  struct DotColumn {
    std::vector<float> value, sigma;
    std::vector<uint8_t> saturated;
    ExposureCheck check;
    int frames = 0, exposures = 0;
  };
  // --threads reaches the merge too (rows are independent: the same result on any count).
  HdrMergeOptions merge_options;
  merge_options.num_threads = options.num_threads;
  auto measure = [&](const DotJob& job, DotColumn* column) -> Status {
    HdrImage hdr;
    SessionMergeInfo info;
    THINSLAB_RETURN_IF_ERROR(MergeSessionBracket(session_dir, session, camera, *job.frames, dark_frames, response,
                                                 merge_options, 1.0, report->noise, &hdr, &info,
                                                 job.check ? ExposureCheckMode::kCheck : ExposureCheckMode::kNone)
                                 .WithContext(job.name));
    column->check = info.exposure_check;
    column->frames = info.num_frames;
    column->exposures = info.num_exposures;
    const Image radiance = rectifier.Rectify(hdr.radiance);
    const Image variance = rectifier.Rectify(hdr.variance);
    const Image saturated = rectifier.RectifyAny(hdr.all_saturated);
    column->value.assign(np, 0.0f);
    column->sigma.assign(np, 0.0f);
    column->saturated.assign(np, 0);
    ParallelFor(grid.height_px, options.num_threads, [&](int y) {
      for (int x = 0; x < grid.width_px; ++x) {
        const int p = y * grid.width_px + x;
        const Eigen::Vector3d to_dot = job.position - entry_points[p];
        const double dist2 = to_dot.squaredNorm();
        const double cos2 = Sqr(to_dot.z()) / dist2;  // cos_e (z . i_q): monitor parallel to the sample.
        const double scale = dist2 / (job.l_q * dot_area * cos2);
        column->value[p] = static_cast<float>(std::max(0.0f, radiance.at(x, y)) * scale);
        column->sigma[p] = static_cast<float>(std::sqrt(std::max(0.0f, variance.at(x, y))) * scale);
        column->saturated[p] = saturated.at(x, y) > 0;
      }
    });
    return Status::Ok();
  };
  std::vector<DotJob> jobs;
  int q = 0;
  for (const auto& [yx, frames] : by_dot) {
    const DotRecord& dot = geometry.dots[q];
    const double l_q = dot.saturated || !dot.measured() ? median_radiance : dot.radiance_dn_per_us;
    jobs.push_back({&frames, dot.position_in_sample_m, l_q, DotName(displayed[q]), q % check_stride == 0, q});
    ++q;
  }
  // Validation dots (see validation_by_dot above) after the grid's, in the same loop.
  DmfValidationDots& validation = slices->validation;
  const size_t nv = validation_by_dot.size();
  validation.value.assign(static_cast<size_t>(np) * nv, 0.0f);
  validation.sigma.assign(static_cast<size_t>(np) * nv, 0.0f);
  report->slice_bytes += (validation.value.size() + validation.sigma.size()) * sizeof(float);
  for (const auto& [yx, frames] : validation_by_dot) {
    const Eigen::Vector2d dot_px(yx.second, yx.first);
    const Eigen::Vector3d position = geometry.sample_from_monitor * Eigen::Vector3d(dot_px.x() * monitor.pixel_pitch_m,
                                                                                   dot_px.y() * monitor.pixel_pitch_m, 0);
    jobs.push_back({&frames, position, median_radiance, "validation " + DotName(dot_px), false,
                    nd + static_cast<int>(validation.dot_px.size())});
    validation.dot_px.push_back(dot_px);
    validation.positions.push_back(position);
  }
  // Each column stored in dot order on every process, whichever process measured it (issue #29:
  // under mpirun the dots are shared out, up to two per process per round).
  auto store = [&](const DotJob& job, const DotColumn& column) -> Status {
    if (job.check) CombineExposureChecks(column.check, &report->exposure_check);  // One bracket for all dots.
    report->num_frames += column.frames;
    report->num_exposures = std::max(report->num_exposures, column.exposures);
    if (job.column >= nd) {
      const size_t v = job.column - nd;
      for (int p = 0; p < np; ++p) {
        validation.value[static_cast<size_t>(p) * nv + v] = column.value[p];
        validation.sigma[static_cast<size_t>(p) * nv + v] = column.sigma[p];
      }
      return Status::Ok();
    }
    for (int p = 0; p < np; ++p) saturated_dots[p] += column.saturated[p];
    if (slices->spill) return slices->spill->WriteColumn(job.column, column.value.data(), column.sigma.data());
    for (int p = 0; p < np; ++p) {
      slices->value[static_cast<size_t>(p) * nd + job.column] = column.value[p];
      slices->sigma[static_cast<size_t>(p) * nd + job.column] = column.sigma[p];
    }
    return Status::Ok();
  };
  ProcessGroup& group = ProcessGroup::World();
  ProgressTracker progress(options.progress, "fit dmf: dot frames (HDR merge, Eq. 12)", static_cast<int64_t>(nd));
  std::map<int, DotColumn> columns;  // The round's, by job.
  DistributedLoop loop;
  // A process measures kDotBracketsInFlight brackets at once (at most --threads): a bracket's
  // frames are read and decoded on one thread (its merge and Eq. 12 run on all), which left part
  // of the cores idle (the paper's workload: 46 -> 40 s). The columns are stored in dot order
  // (chunk_done), so the slices do not depend on the threads.
  const int in_flight = std::min(kDotBracketsInFlight, options.num_threads);
  loop.compute = [&](int begin, int end) -> Status {
    std::vector<DotColumn*> slots;
    for (int j = begin; j < end; ++j) slots.push_back(&columns[j]);  // No insertion on the threads.
    std::vector<Status> statuses(end - begin);
    ParallelFor(end - begin, in_flight, [&](int k) { statuses[k] = measure(jobs[begin + k], slots[k]); });
    for (const Status& s : statuses) THINSLAB_RETURN_IF_ERROR(s);
    return Status::Ok();
  };
  loop.pack = [&](int j, ByteWriter* out) {
    const DotColumn& c = columns[j];
    out->PutVector(c.value);
    out->PutVector(c.sigma);
    out->PutVector(c.saturated);
    out->PutVector(c.check.reported_us);
    out->PutVector(c.check.measured_over_reported);
    out->PutVector(c.check.pixels);
    out->Put(c.check.max_deviation);
    out->Put(c.check.measured);
    out->Put(c.frames);
    out->Put(c.exposures);
  };
  loop.unpack = [&](int j, ByteReader* in) {
    DotColumn& c = columns[j];
    return in->GetVector(&c.value) && in->GetVector(&c.sigma) && in->GetVector(&c.saturated) &&
           in->GetVector(&c.check.reported_us) && in->GetVector(&c.check.measured_over_reported) &&
           in->GetVector(&c.check.pixels) && in->Get(&c.check.max_deviation) && in->Get(&c.check.measured) &&
           in->Get(&c.frames) && in->Get(&c.exposures) && c.value.size() == static_cast<size_t>(np) &&
           c.sigma.size() == c.value.size() && c.saturated.size() == c.value.size();
  };
  loop.chunk_done = [&](int begin, int end) -> Status {
    for (int j = begin; j < end; ++j) THINSLAB_RETURN_IF_ERROR(store(jobs[j], columns[j]));
    columns.clear();
    if (!progress.Report(std::min(end, nd))) return Status::Error("PrepareDotScanSlices: cancelled");
    return Status::Ok();
  };
  if (!progress.Report(0)) return Status::Error("PrepareDotScanSlices: cancelled");
  THINSLAB_RETURN_IF_ERROR(
      DistributedFor(group, static_cast<int>(jobs.size()), group.size() * in_flight, "fit dmf: dot frames", loop));
  report->merge_s = Seconds(t);
  report->exposure_warning = report->exposure_check.Warning();

  for (int p = 0; p < np; ++p) {
    const int x = p % grid.width_px, y = p / grid.width_px;
    if (rectifier.outside().at(x, y) > 0) {
      slices->point_status[p] = static_cast<uint8_t>(DmfStatus::kOutside);
      ++report->outside_points;
    } else if (saturated_dots[p] > options.max_saturated_dots * nd) {
      slices->point_status[p] = static_cast<uint8_t>(DmfStatus::kSaturated);
      ++report->saturated_points;
    }
  }
  if (report->saturated_points > options.max_saturated_points * np) {
    return Status::Error(session_dir + ": the dot frames saturate in every exposure at " +
                         std::to_string(report->saturated_points) + " of " + std::to_string(np) +
                         " sample points: the bracket needs a shorter exposure");
  }
  report->num_dots = nd;
  report->grid_nx = nx;
  report->grid_ny = ny;
  report->dot_rms_residual_m = geometry.rms_residual_m;
  report->dot_distance_error_m = geometry.distance_error_m;
  report->dot_distance_error_sigma_m = geometry.distance_error_sigma_m;
  report->dot_distance_correction_m = geometry.distance_correction_m;
  report->dot_distance_warning = MonitorDistanceWarning(geometry.distance_error_m, geometry.distance_error_sigma_m);
  report->median_dot_radiance = median_radiance;
  report->sample_from_monitor = geometry.sample_from_monitor;
  report->monitor_pixel_pitch_m = monitor.pixel_pitch_m;
  report->total_s = Seconds(start);
  return Status::Ok();
}

}  // namespace thinslab
