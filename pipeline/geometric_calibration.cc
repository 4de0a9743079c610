// SPDX-License-Identifier: Apache-2.0
#include "thinslab/pipeline/geometric_calibration.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <sstream>

#include "thinslab/calib/rig_io.h"
#include "thinslab/calib/session_calibration.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/output_guard.h"
#include "thinslab/core/provenance.h"
#include "thinslab/core/session_io.h"
#include "thinslab/drivers/pattern_id.h"
#include "thinslab/pipeline/calibration_summary.h"
#include "thinslab/pipeline/capture_reading.h"

namespace thinslab {
namespace {

constexpr char kRigFile[] = "rig.json";

std::string Fmt(const char* format, double value) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), format, value);
  return buf;
}

bool IsImageFile(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff" || ext == ".bmp" ||
         ext == ".exr" || ext == ".pgm";
}

// The session camera with rig.json's calibration applied (intrinsics from --rig or
// SESSION/calib/rig.json if it has a camera section; pose likewise if `with_pose`).
Status SessionCamera(const std::string& session_dir, const Session& session, const std::string& camera_id,
                     const std::string& rig_path, bool with_pose, CameraInfo* camera, RigCalibration* rig) {
  const CameraInfo* cam = session.FindCamera(camera_id);
  if (cam == nullptr) return Status::Error(session_dir + ": no camera '" + camera_id + "' in rig.cameras");
  *camera = *cam;
  THINSLAB_RETURN_IF_ERROR(ReadRigCalibrationIfExists(rig_path, rig));
  if (!with_pose) rig->pose.present = false;
  return ApplyRigCalibration(*rig, camera).WithContext(rig_path);
}

}  // namespace

Status CalibrateCamera(const CalibCameraRun& run, std::ostream& log, CameraCalibrationResult* result) {
  const CameraCalibrationOptions& options = run.options;
  const std::string &out_dir = run.out_dir, &camera_id = run.camera_id;
  std::vector<std::string> paths = run.images;
  if (!run.images_dir.empty()) {
    if (!paths.empty()) return Status::Error("calib camera: give IMAGES... or --images DIR, not both");
    if (!DirectoryExists(run.images_dir)) return Status::Error(run.images_dir + ": --images: no such folder");
    for (const auto& entry : std::filesystem::directory_iterator(run.images_dir)) {
      if (entry.is_regular_file() && IsImageFile(entry.path().string())) paths.push_back(entry.path().string());
    }
    std::sort(paths.begin(), paths.end());
    if (paths.empty()) return Status::Error(run.images_dir + ": --images: no PNG/JPEG/TIFF/EXR files");
  }
  if (paths.empty()) return Status::Error("calib camera: no images given (IMAGES... or --images DIR)");
  std::vector<NamedImage> images;
  for (const std::string& p : paths) {
    NamedImage named;
    named.name = p;
    THINSLAB_RETURN_IF_ERROR(LoadCalibrationImage(p, &named.image));
    if (named.image.num_channels() != 1) return Status::Error(p + ": expected a single-channel image");
    images.push_back(std::move(named));
  }
  THINSLAB_RETURN_IF_ERROR(CalibrateCameraFromImages(images, options, result));

  THINSLAB_RETURN_IF_ERROR(CreateDirectories(out_dir));
  const std::string rig_path = JoinPath(out_dir, kRigFile);
  RigCalibration rig;
  THINSLAB_RETURN_IF_ERROR(ReadRigCalibrationIfExists(rig_path, &rig));
  RigCameraCalibration& c = rig.camera;
  c.provenance_json =
      ProvenanceJson({"calib camera", run.images_dir.empty() && !paths.empty() ? paths.front() : run.images_dir, "",
                      run.options_ini})
          .dump();
  c.present = true;
  c.camera_id = camera_id;
  c.width_px = result->camera.width_px;
  c.height_px = result->camera.height_px;
  c.fx_px = result->camera.fx_px;
  c.fy_px = result->camera.fy_px;
  c.cx_px = result->camera.cx_px;
  c.cy_px = result->camera.cy_px;
  c.distortion = result->camera.distortion;
  c.fx_std_px = result->fx_std_px;
  c.fy_std_px = result->fy_std_px;
  c.cx_std_px = result->cx_std_px;
  c.cy_std_px = result->cy_std_px;
  c.distortion_std = result->distortion_std;
  c.rms_reprojection_px = result->rms_px;
  c.num_views = result->num_views_used;
  c.board_inner_cols = options.board.inner_cols;
  c.board_inner_rows = options.board.inner_rows;
  c.board_square_m = options.board.square_m;
  // A new camera calibration invalidates a pose estimated with older intrinsics.
  rig.pose = RigPoseCalibration();

  std::ostringstream report, csv;
  report << "thinslab calib camera: " << result->num_views_used << " of " << paths.size() << " views used, board "
         << options.board.inner_cols << "x" << options.board.inner_rows << " inner corners, "
         << options.board.square_m * 1e3 << " mm squares\n"
         << "image " << c.width_px << " x " << c.height_px << " px\n"
         << "fx = " << Fmt("%.4f", c.fx_px) << " +- " << Fmt("%.4f", c.fx_std_px) << " px\n"
         << "fy = " << Fmt("%.4f", c.fy_px) << " +- " << Fmt("%.4f", c.fy_std_px) << " px\n"
         << "cx = " << Fmt("%.4f", c.cx_px) << " +- " << Fmt("%.4f", c.cx_std_px) << " px (OpenCV convention)\n"
         << "cy = " << Fmt("%.4f", c.cy_px) << " +- " << Fmt("%.4f", c.cy_std_px) << " px (OpenCV convention)\n";
  const char* names[] = {"k1", "k2", "p1", "p2", "k3"};
  for (size_t k = 0; k < c.distortion.size(); ++k) {
    report << names[k] << " = " << Fmt("%.6g", c.distortion[k]) << " +- " << Fmt("%.3g", c.distortion_std[k]) << "\n";
  }
  report << "RMS reprojection error = " << Fmt("%.4f", c.rms_reprojection_px) << " px\n\nper view:\n";
  csv << "# thinslab calib camera: per-view reprojection\nview,detected,rms_px,max_px,error\n";
  for (const CalibrationViewReport& v : result->views) {
    if (v.detected) {
      report << "  " << v.name << ": rms " << Fmt("%.4f", v.rms_px) << " px, max " << Fmt("%.4f", v.max_px) << " px\n";
      csv << v.name << ",1," << Fmt("%.6f", v.rms_px) << "," << Fmt("%.6f", v.max_px) << ",\n";
    } else {
      report << "  " << v.name << ": skipped: " << v.error << "\n";
      csv << v.name << ",0,,,\"" << v.error << "\"\n";
    }
  }
  std::vector<InputPath> inputs;
  for (const std::string& p : paths) inputs.push_back({p, {}});
  for (const std::string& file : {rig_path, JoinPath(out_dir, "camera_calibration.txt"), JoinPath(out_dir, "camera_views.csv")}) {
    THINSLAB_RETURN_IF_ERROR(CheckOutputFile(file, inputs));
  }
  THINSLAB_RETURN_IF_ERROR(WriteRigCalibration(rig_path, rig));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out_dir, "camera_calibration.txt"), report.str()));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out_dir, "camera_views.csv"), csv.str()));
  log << report.str() << "wrote " << rig_path << "\n";
  return Status::Ok();
}

Status CalibratePose(const CalibPoseRun& run, std::ostream& log) {
  const ChessboardSpec& board = run.board;
  const Rigid3d& sample_from_board = run.sample_from_board;
  const std::string &session_dir = run.session_dir, &kind = run.kind;
  std::string rig_path = run.rig_path;
  Session session;
  THINSLAB_RETURN_IF_ERROR(ReadCaptureForCommand(session_dir, run.allow_incomplete_capture, &session));
  const std::vector<const FrameRecord*> frames = session.UsableFrames(kind);
  if (frames.empty()) {
    return Status::Error(JoinPath(session_dir, kSessionManifestName) + ": frames: no usable frame of kind '" + kind +
                         "' (a chessboard lying on the sample plane)");
  }
  const std::string calib_dir = JoinPath(session_dir, "calib");
  const std::string out_rig = JoinPath(calib_dir, kRigFile);
  if (!rig_path.empty() && !FileExists(rig_path)) return Status::Error(rig_path + ": --rig: no such file");
  if (rig_path.empty()) rig_path = out_rig;
  CameraInfo camera;
  RigCalibration rig;
  THINSLAB_RETURN_IF_ERROR(SessionCamera(session_dir, session, frames[0]->camera_id, rig_path, false, &camera, &rig));
  // The first usable target frame gives the pose; further ones are reported for consistency.
  std::ostringstream report;
  PlanePoseResult first;
  for (size_t k = 0; k < frames.size(); ++k) {
    Image image;
    THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *frames[k], &image));
    PlanePoseResult pose;
    THINSLAB_RETURN_IF_ERROR(EstimateSamplePoseFromChessboard(camera, image, board, sample_from_board, &pose)
                                 .WithContext(JoinPath(session_dir, frames[k]->file)));
    const Eigen::Vector3d eye = pose.cam_from_plane.Inverse().translation;
    report << frames[k]->file << ": rms " << Fmt("%.4f", pose.rms_px) << " px, max " << Fmt("%.4f", pose.max_px)
           << " px, camera centre in sample (" << Fmt("%.5f", eye.x()) << ", " << Fmt("%.5f", eye.y()) << ", "
           << Fmt("%.5f", eye.z()) << ") m, rotation std " << Fmt("%.4f", pose.rotation_std_rad.norm() * 180 / kPi)
           << " deg, translation std " << Fmt("%.4f", pose.translation_std_m.norm() * 1e3) << " mm\n";
    if (k == 0) first = pose;
  }
  RigCalibration out;
  THINSLAB_RETURN_IF_ERROR(ReadRigCalibrationIfExists(out_rig, &out));
  if (rig.camera.present) out.camera = rig.camera;  // Intrinsics the pose was computed with.
  out.pose.present = true;
  out.pose.provenance_json = ProvenanceJson({"calib pose", session_dir, "", run.options_ini}).dump();
  out.pose.cam_from_sample = first.cam_from_plane;
  out.pose.rms_reprojection_px = first.rms_px;
  out.pose.max_reprojection_px = first.max_px;
  out.pose.num_points = first.num_points;
  out.pose.rotation_std_rad = first.rotation_std_rad;
  out.pose.translation_std_m = first.translation_std_m;
  for (const std::string& file : {out_rig, JoinPath(calib_dir, "pose_report.txt")}) {
    THINSLAB_RETURN_IF_ERROR(CheckOutputFile(file, {{session_dir, {"calib"}}}));
  }
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(calib_dir));
  THINSLAB_RETURN_IF_ERROR(WriteRigCalibration(out_rig, out));
  const std::string text = std::string("thinslab calib pose: intrinsics from ") +
                           (rig.camera.present ? rig_path : std::string("the manifest")) + "\n" + report.str();
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(calib_dir, "pose_report.txt"), text));
  log << text << "wrote " << out_rig << "\n";
  return Status::Ok();
}

Status CalibrateDots(const CalibDotsRun& run, std::ostream& log) {
  const std::string &session_dir = run.session_dir, &kind = run.kind, &response_path = run.response_path;
  std::string rig_path = run.rig_path;
  DotGeometryOptions options = run.options;
  Session session;
  THINSLAB_RETURN_IF_ERROR(ReadCaptureForCommand(session_dir, run.allow_incomplete_capture, &session));
  const std::string manifest = JoinPath(session_dir, kSessionManifestName);
  if (!session.rig.monitor.present) return Status::Error(manifest + ": rig.monitor: missing (the dot monitor geometry)");
  std::string dot_radius_source;
  options.dot_radius_px = ResolveDotRadiusPx(run.dot_radius_px, session.rig.monitor, &dot_radius_source);
  std::vector<const FrameRecord*> frames = session.UsableFrames(kind, "none");
  if (frames.empty()) {
    return Status::Error(manifest + ": frames: no usable frame of kind '" + kind +
                         "' with sample_state \"none\" (all dots shown, no sample)");
  }
  const std::string calib_dir = JoinPath(session_dir, "calib");
  const std::string out_rig = JoinPath(calib_dir, kRigFile);
  if (!rig_path.empty() && !FileExists(rig_path)) return Status::Error(rig_path + ": --rig: no such file");
  if (rig_path.empty()) rig_path = out_rig;
  CameraInfo camera;
  RigCalibration rig;
  THINSLAB_RETURN_IF_ERROR(SessionCamera(session_dir, session, frames[0]->camera_id, rig_path, true, &camera, &rig));
  // Of a bracket of all-dots frames, the longest exposure without saturated pixels gives the
  // best signal; if all saturate, the shortest (positions stay usable, radiances are flagged).
  std::sort(frames.begin(), frames.end(),
            [](const FrameRecord* a, const FrameRecord* b) { return a->exposure_time_us > b->exposure_time_us; });
  const double saturation = camera.saturation_dn > 0 ? camera.saturation_dn - camera.black_level_dn : 0;
  const FrameRecord* chosen = nullptr;
  Image image;
  for (const FrameRecord* f : frames) {
    if (f->camera_id != camera.id) continue;
    THINSLAB_RETURN_IF_ERROR(LoadFrame(session_dir, session, *f, &image));
    const float peak = *std::max_element(image.data().begin(), image.data().end());
    chosen = f;
    if (saturation <= 0 || peak < saturation) break;
  }
  PatternSpec spec;
  THINSLAB_RETURN_IF_ERROR(ParsePatternId(chosen->light.projector_pattern, &spec)
                               .WithContext(manifest + ": frames[" + std::to_string(chosen->index) +
                                            "].light.projector_pattern"));
  if (spec.kind != PatternSpec::Kind::kDots || spec.dots.size() < 4) {
    return Status::Error(manifest + ": frames[" + std::to_string(chosen->index) +
                         "].light.projector_pattern: expected a \"dots:...\" grid of at least 4 dots, got '" +
                         chosen->light.projector_pattern + "'");
  }
  std::vector<Eigen::Vector2d> displayed;
  for (const PatternSpec::Dot& d : spec.dots) displayed.emplace_back(d.x_px, d.y_px);
  // L_q in linear DN per microsecond, as the fits' HDR merges of the dot frames.
  CameraResponse response;
  std::string response_file;
  THINSLAB_RETURN_IF_ERROR(LoadCameraResponse(session_dir, response_path, camera, &response, &response_file));
  const CameraResponse* linearise = response_file.empty() ? nullptr : &response;
  LinearizeFrame(linearise, &image);
  const double linear_saturation = linearise != nullptr && saturation > 0 ? response.Linearize(saturation) : saturation;
  DotGeometryResult result;
  THINSLAB_RETURN_IF_ERROR(CalibrateDotGeometry(image, chosen->exposure_time_us, linear_saturation, camera,
                                                session.rig.monitor, displayed, options, &result)
                               .WithContext(JoinPath(session_dir, chosen->file)));
  RigCalibration out;
  THINSLAB_RETURN_IF_ERROR(ReadRigCalibrationIfExists(out_rig, &out));
  if (rig.camera.present) out.camera = rig.camera;
  if (rig.pose.present) out.pose = rig.pose;
  RigMonitorCalibration& m = out.monitor;
  m.present = true;
  m.provenance_json = ProvenanceJson({"calib dots", session_dir, "", run.options_ini}).dump();
  m.sample_from_monitor = result.sample_from_monitor;
  m.pixel_pitch_m = session.rig.monitor.pixel_pitch_m;
  m.width_px = session.rig.monitor.width_px;
  m.height_px = session.rig.monitor.height_px;
  m.dot_radius_px = options.dot_radius_px;
  m.rms_residual_m = result.rms_residual_m;
  m.max_residual_m = result.max_residual_m;
  m.homography_rms_px = result.homography_rms_px;
  m.grid_scale = result.grid_scale;
  m.distance_error_m = result.distance_error_m;
  m.distance_error_sigma_m = result.distance_error_sigma_m;
  m.distance_correction_m = result.distance_correction_m;
  m.dots = result.dots;
  int saturated = 0, placed = 0;
  std::ostringstream csv;
  csv << "# thinslab calib dots: detected dots\n";
  csv << "dot_x_px,dot_y_px,detected,centroid_x_px,centroid_y_px,x_m,y_m,z_m,radiance_dn_per_us,saturated,residual_m,clipped,placed_from_geometry\n";
  for (const DotRecord& d : result.dots) {
    saturated += d.saturated ? 1 : 0;
    placed += d.placed_from_geometry ? 1 : 0;
    csv << d.dot_px.x() << "," << d.dot_px.y() << "," << (d.detected ? 1 : 0) << "," << Fmt("%.4f", d.centroid_px.x())
        << "," << Fmt("%.4f", d.centroid_px.y()) << "," << Fmt("%.7f", d.position_in_sample_m.x()) << ","
        << Fmt("%.7f", d.position_in_sample_m.y()) << "," << Fmt("%.7f", d.position_in_sample_m.z()) << ","
        << Fmt("%.6g", d.radiance_dn_per_us) << "," << (d.saturated ? 1 : 0) << "," << Fmt("%.3e", d.residual_m)
        << "," << (d.clipped ? 1 : 0) << "," << (d.placed_from_geometry ? 1 : 0) << "\n";
  }
  std::ostringstream report;
  report << "thinslab calib dots: frame " << chosen->file << " (exposure " << chosen->exposure_time_us << " us)\n"
         << "intrinsics/pose from " << (rig.camera.present || rig.pose.present ? rig_path : "the manifest") << "\n"
         << "dot radius " << options.dot_radius_px << " monitor px (" << dot_radius_source << ")\n"
         << "displayed dots " << displayed.size() << ", blobs " << result.num_blobs << ", matched "
         << result.num_matched << " (" << result.num_found_by_grid_prior << " of them measured where the grid puts "
         << "them), unmatched blobs " << result.num_unmatched_blobs << ", saturated " << saturated
         << ", cut by the image border " << result.num_clipped << ", placed from the monitor geometry " << placed
         << " (outside the view, not found or cut: they enter no estimate)\n"
         << "local background (median) " << Fmt("%.5g", result.background_dn_per_us) << " DN/us, noise "
         << Fmt("%.3g", result.noise_dn_per_us) << " DN/us\n"
         << "grid homography rms " << Fmt("%.4f", result.homography_rms_px) << " px\n"
         << "residual to the displayed grid on the monitor plane: rms " << Fmt("%.4f", result.rms_residual_m * 1e3)
         << " mm, max " << Fmt("%.4f", result.max_residual_m * 1e3) << " mm\n"
         << "in-plane correction of the manifest monitor pose: " << Fmt("%.3f", result.in_plane_correction_m * 1e3)
         << " mm, " << Fmt("%.4f", result.in_plane_correction_rad * 180 / kPi) << " deg\n";
  // docs/models/geometric_calibration.md 3.7: the grid's scale measures d.
  if (options.refine_distance) {
    report << "monitor distance from the grid's scale: plane moved " << Fmt("%.3f", result.distance_correction_m * 1e3)
           << " mm towards the camera (d " << (result.distance_correction_m >= 0 ? "was too large" : "was too small")
           << "); remaining " << Fmt("%.4f", result.distance_error_m * 1e3) << " mm\n";
  } else {
    report << "monitor distance from the grid's scale (scale " << Fmt("%.6f", result.grid_scale)
           << "): the manifest's plane is " << Fmt("%.3f", result.distance_error_m * 1e3) << " +- "
           << Fmt("%.3f", result.distance_error_sigma_m * 1e3)
           << " mm further from the camera than the grid says (not applied; --refine-distance applies it)\n";
  }
  const std::string distance_warning =
      options.refine_distance ? "" : MonitorDistanceWarning(result.distance_error_m, result.distance_error_sigma_m);
  for (const std::string& file : {out_rig, JoinPath(calib_dir, "dots.csv"), JoinPath(calib_dir, "dots_report.txt")}) {
    THINSLAB_RETURN_IF_ERROR(CheckOutputFile(file, {{session_dir, {"calib"}}}));
  }
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(calib_dir));
  THINSLAB_RETURN_IF_ERROR(WriteRigCalibration(out_rig, out));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(calib_dir, "dots.csv"), csv.str()));
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(calib_dir, "dots_report.txt"), report.str()));
  log << report.str() << "wrote " << out_rig << "\n";
  if (dot_radius_source == "default") std::cerr << "warning: " << AssumedDotRadiusWarning(manifest) << "\n";
  if (!distance_warning.empty()) std::cerr << "warning: " << JoinPath(session_dir, chosen->file) << ": " << distance_warning << "\n";
  return Status::Ok();
}

}  // namespace thinslab
