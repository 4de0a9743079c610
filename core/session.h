// SPDX-License-Identifier: Apache-2.0
// The capture-session manifest (session.json): rig geometry and devices, and every frame
// with its file, exposure, light state, timestamp and status. docs/format.md is the
// normative description; this header mirrors it field for field.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "thinslab/core/rigid3.h"

namespace thinslab {

constexpr int kSessionFormatMajor = 1;
// 1.1: stream_statistics, acquisition; 1.2: camera frame ids; 1.3: linear frames, noise fields;
// 1.4: rig.monitor.dot_radius_px, frames[k].validation.
constexpr int kSessionFormatMinor = 4;
constexpr char kSessionManifestName[] = "session.json";
// Largest board distance (sample to board/screen) any rig, fit or simulation accepts: a shadow
// map or laser lobe spreads over millimetres to centimetres; 1e308 m overflowed the projection.
constexpr double kMaxBoardDistanceM = 10;

// OpenCV pinhole camera with distortion (k1, k2, p1, p2[, k3]); pixel centres at
// (x + 0.5, y + 0.5) in thinslab images, so cx, cy are in OpenCV's integer-centre
// convention and a thinslab pixel (x, y) centre projects from (x + 0.5 - 0.5) = x in OpenCV
// terms. docs/conventions.md has the one-line rule.
struct CameraInfo {
  std::string id;          // "cam0"; frames refer to it.
  std::string model;       // "sim", "aravis", "v4l2", or any label.
  std::string serial;      // Optional.
  int width_px = 0;
  int height_px = 0;
  double fx_px = 0, fy_px = 0, cx_px = 0, cy_px = 0;
  std::vector<double> distortion;  // 0, 4 or 5 OpenCV coefficients.
  Rigid3d cam_from_sample;         // Sample frame: sample plane z = 0, +z towards the projector.
  int bit_depth = 0;               // 8, 10, 12, 14 or 16 for integer frames; 32 for float EXR.
  double black_level_dn = 0;       // Subtracted before any radiometry.
  double saturation_dn = 0;        // Values >= this are saturated (raw DN, before black level).
  double gain_e_per_dn = 0;        // Conversion gain; 0 if unknown.
  // "raw" (default): frames hold the sensor's raw DN. "linear": frames hold values already
  // linear in radiance (an HDR tool's merged frames, a renderer's output): float EXR
  // (bit_depth 32), no camera response, saturation_dn optional (absent = +infinity, nothing
  // saturates) and frame exposures optional (default 1 us). Format 1.3.
  std::string frame_values = "raw";
  // RMS noise of a frame value at zero signal (read noise) in the frames' units; absent =
  // unknown (dark frames or the data give it). With gain_e_per_dn it declares the noise model
  // var(v) = read_noise_dn^2 + max(v, 0) / gain_e_per_dn. Format 1.3.
  std::optional<double> read_noise_dn;
  bool linear_frames() const { return frame_values == "linear"; }
  // Optional transport statistics of the capture (name -> count or value), e.g.
  // "completed_buffers", "failed_buffers", "missing_packets", "resent_packets", "timeouts",
  // "packet_size_bytes" from Camera::statistics(); empty for simulated or imported captures.
  std::map<std::string, double> stream_statistics;
};

struct SampleInfo {
  // Region of interest on the sample plane (metres, sample frame) and the pitch of the
  // rectified grid that fits produce over it.
  Eigen::Vector2d region_min_m = Eigen::Vector2d::Zero();
  Eigen::Vector2d region_max_m = Eigen::Vector2d::Zero();
  double pixel_pitch_m = 0;
  double glass_thickness_m = 0;
  double glass_ior = 1.5;
  std::string contaminant_side = "board";  // "board" or "projector".
};

// Lambertian board parallel to the sample at z = -distance_m (shadow maps, laser lobes).
struct BoardInfo {
  bool present = false;
  double distance_m = 0;
  double albedo = 0;  // Unitless, (0, 1].
};

struct ProjectorInfo {
  bool present = false;
  std::string kind = "collimated";  // "collimated" or "pinhole".
  Eigen::Vector3d direction_in_sample = Eigen::Vector3d(0, 0, -1);  // Propagation direction.
};

struct LaserInfo {
  bool present = false;
  Eigen::Vector3d origin_in_sample = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction_in_sample = Eigen::Vector3d(0, 0, -1);
  double beam_radius_m = 0;
  double wavelength_m = 0;
};

struct MonitorInfo {
  bool present = false;
  Rigid3d sample_from_monitor;  // Monitor plane z = 0 in its own frame, pixel (0,0) at origin.
  double pixel_pitch_m = 0;
  int width_px = 0;
  int height_px = 0;
  // Radius of a displayed dot [monitor px] (the disc the pattern window draws); 0 = not given
  // (the fits then assume 2 px and say so). Format 1.4.
  double dot_radius_px = 0;
};

struct RigInfo {
  std::vector<CameraInfo> cameras;
  SampleInfo sample;
  BoardInfo board;
  ProjectorInfo projector;
  LaserInfo laser;
  MonitorInfo monitor;
};

enum class FrameStatus { kOk, kFailed, kRetried };
const char* FrameStatusName(FrameStatus status);

struct LightState {
  std::string projector_pattern;         // "" = projector off; "flat", "gray_code_3", ...
  bool laser_on = false;
  std::optional<Eigen::Vector2d> dot_px;  // CRT/monitor dot position, monitor pixels.
  double dot_radiance = 0;                // Relative radiance of the dot, if known.
};

struct FrameRecord {
  int index = 0;              // Position in the session, contiguous from 0.
  std::string camera_id;      // Must name a rig camera.
  std::string kind;           // "shadow", "reference", "dark", "laser", "dot", ...
  std::string sample_state = "none";  // "contaminated", "clean", "none".
  std::string file;           // Relative to the session folder; "" when status is failed.
  double exposure_time_us = 0;  // Exposure the camera reported applying.
  // Optional per-pixel variance of the frame's values (an EXR of the frame's size, the frame's
  // units squared, before dividing by the exposure); "" = none. Format 1.3.
  std::string variance_file;
  // A validation frame (format 1.4): a measurement outside the fitting set (any dot position or
  // light state), never fitted; fits that know its kind report how well they predict it.
  bool validation = false;
  double gain_db = 0;
  LightState light;
  std::string timestamp_utc;  // ISO 8601.
  // What the camera stamped on the frame, if it says: its frame counter (GigE Vision block id
  // unwrapped, V4L2 sequence) and its timestamp in ns on the device's own clock (camera ticks
  // since power-up, CLOCK_MONOTONIC for V4L2; not UTC). Opaque, for auditing dropped frames
  // and timing; each must be < 2^63.
  std::optional<uint64_t> camera_frame_id;
  std::optional<uint64_t> camera_timestamp_ns;
  FrameStatus status = FrameStatus::kOk;
  std::string error;          // Device message when status != ok.
};

// Bookkeeping written by `thinslab acquire` (docs/format.md, section 2.5): what happened to the
// session, so an interrupted or failed capture can be resumed and audited. Optional; absent in
// simulated and hand-written captures.
struct AcquisitionEvent {
  std::string time_utc;  // ISO 8601.
  std::string event;     // "started", "resumed", "completed", "failed", "interrupted".
  std::string device;    // Device a failure names, e.g. "camera 'cam0' (aravis:10.0.0.2)"; else "".
  std::string message;
  int frames = 0;        // Frame entries in the manifest when the event was recorded.
};

struct AcquisitionInfo {
  bool present = false;
  std::string state;         // "running", "complete", "failed", "interrupted".
  std::string plan;          // Kind and options that fix the frame plan; a resume must match it.
  int planned_frames = 0;    // Usable frames the plan produces.
  int camera_captures = 0;   // Capture calls made on the camera (usable, failed and discarded).
  int discarded_frames = 0;  // Captured but not counted: the displayed change was not seen yet.
  std::vector<AcquisitionEvent> events;
};

struct Session {
  int format_major = kSessionFormatMajor;
  int format_minor = kSessionFormatMinor;
  std::string name;
  std::string kind;  // "shadow_map", "laser_lobe", "dot_scan", "exposure_bracket", "display_gamma".
  std::string created_utc;
  std::string software;  // Program that wrote the capture.
  RigInfo rig;
  std::vector<FrameRecord> frames;
  AcquisitionInfo acquisition;  // Present only in captures written by `thinslab acquire`.

  const CameraInfo* FindCamera(const std::string& id) const;
  // Frames of one kind (and sample state, if non-empty) with status ok or retried, validation
  // frames left out: what the fits and calibrations use.
  std::vector<const FrameRecord*> UsableFrames(const std::string& kind,
                                               const std::string& sample_state = "") const;
  // The validation frames among them (FrameRecord::validation).
  std::vector<const FrameRecord*> ValidationFrames(const std::string& kind,
                                                   const std::string& sample_state = "") const;
};

}  // namespace thinslab
