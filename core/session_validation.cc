// SPDX-License-Identifier: Apache-2.0
// Semantic checks of a parsed session and its human summary.
#include "thinslab/core/session_validation.h"

#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <utility>
#include <vector>

#include "thinslab/core/file.h"
#include "thinslab/core/session_format.h"

namespace thinslab {

using namespace session_format;  // NOLINT: the format's shared vocabulary.

Status ValidateSession(const Session& session, const std::string& session_dir) {
  const std::string file = ManifestPath(session_dir);
  auto error = [&file](const std::string& path, const std::string& message) {
    return Status::Error(file + ": " + path + ": " + message);
  };

  if (session.format_major != kSessionFormatMajor) {
    return Status::Error(file + ": format_version " + std::to_string(session.format_major) + "." +
                         std::to_string(session.format_minor) +
                         " is not supported by this reader (supports " +
                         std::to_string(kSessionFormatMajor) + ".x)");
  }

  // Cameras.
  const RigInfo& rig = session.rig;
  if (rig.cameras.empty()) return error("rig.cameras", "at least one camera is required");
  std::map<std::string, size_t> camera_index;
  for (size_t i = 0; i < rig.cameras.size(); ++i) {
    const CameraInfo& c = rig.cameras[i];
    const std::string p = Element("rig.cameras", i);
    if (c.id.empty()) return error(p + ".id", "must be a non-empty string");
    if (!camera_index.emplace(c.id, i).second) {
      return error(p + ".id", "duplicate camera id " + Quote(c.id) + " (also " +
                                  Element("rig.cameras", camera_index[c.id]) + ")");
    }
    if (c.width_px <= 0)
      return error(p + ".width_px", "must be > 0, got " + std::to_string(c.width_px));
    if (c.height_px <= 0)
      return error(p + ".height_px", "must be > 0, got " + std::to_string(c.height_px));
    if (!(c.fx_px > 0)) return error(p + ".fx_px", "must be > 0, got " + Num(c.fx_px));
    if (!(c.fy_px > 0)) return error(p + ".fy_px", "must be > 0, got " + Num(c.fy_px));
    if (!std::isfinite(c.cx_px)) return error(p + ".cx_px", "must be finite");
    if (!std::isfinite(c.cy_px)) return error(p + ".cy_px", "must be finite");
    const size_t nd = c.distortion.size();
    if (nd != 0 && nd != 4 && nd != 5) {
      return error(p + ".distortion",
                   "must have 0, 4 (k1, k2, p1, p2) or 5 (k1, k2, p1, p2, k3) "
                   "coefficients, got " +
                       std::to_string(nd));
    }
    for (size_t k = 0; k < nd; ++k) {
      if (!std::isfinite(c.distortion[k]))
        return error(Element(p + ".distortion", k), "must be finite");
    }
    const double qn = c.cam_from_sample.rotation.norm();
    if (!(qn > 1e-12) || !std::isfinite(qn)) {
      return error(p + ".cam_from_sample.rotation_wxyz", "quaternion must be non-zero");
    }
    if (!c.cam_from_sample.translation.allFinite()) {
      return error(p + ".cam_from_sample.translation_m", "must be finite");
    }
    const auto& depths = BitDepths();
    if (std::find(depths.begin(), depths.end(), c.bit_depth) == depths.end()) {
      return error(p + ".bit_depth",
                   "must be 8, 10, 12, 14, 16 (integer frames) or 32 (float "
                   "EXR frames), got " +
                       std::to_string(c.bit_depth));
    }
    if (IsIntegerDepth(c.bit_depth)) {
      const double full_scale = std::ldexp(1.0, c.bit_depth);
      if (!(c.black_level_dn >= 0)) {
        return error(p + ".black_level_dn", "must be >= 0, got " + Num(c.black_level_dn));
      }
      if (!(c.saturation_dn > c.black_level_dn)) {
        return error(p + ".saturation_dn", "must be > black_level_dn (" + Num(c.black_level_dn) +
                                               "), got " + Num(c.saturation_dn));
      }
      if (c.saturation_dn > full_scale) {
        return error(p + ".saturation_dn", "must be <= 2^bit_depth = " + Num(full_scale) + " for " +
                                               std::to_string(c.bit_depth) +
                                               "-bit frames (DN are stored in the low "
                                               "bits), got " +
                                               Num(c.saturation_dn));
      }
    } else {
      if (!std::isfinite(c.black_level_dn)) return error(p + ".black_level_dn", "must be finite");
      // Linear frames without a saturation level hold +infinity (nothing saturates).
      if (!std::isfinite(c.saturation_dn) && !(c.linear_frames() && c.saturation_dn > 0)) {
        return error(p + ".saturation_dn", "must be finite");
      }
    }
    if (!Contains(FrameValueKinds(), c.frame_values)) {
      return error(p + ".frame_values", "must be " + OneOf(FrameValueKinds()) + ", got " + Quote(c.frame_values));
    }
    if (c.linear_frames() && c.bit_depth != 32) {
      return error(p + ".frame_values", "\"linear\" frames are float EXR frames and need bit_depth 32, got " +
                                            std::to_string(c.bit_depth));
    }
    if (c.linear_frames() && !(c.saturation_dn > c.black_level_dn)) {
      return error(p + ".saturation_dn", "must be > black_level_dn (" + Num(c.black_level_dn) + "), got " +
                                             Num(c.saturation_dn));
    }
    if (!(c.gain_e_per_dn >= 0) || !std::isfinite(c.gain_e_per_dn)) {
      return error(p + ".gain_e_per_dn", "must be >= 0 (0 = unknown), got " + Num(c.gain_e_per_dn));
    }
    if (c.read_noise_dn.has_value() && !(*c.read_noise_dn >= 0 && std::isfinite(*c.read_noise_dn))) {
      return error(p + ".read_noise_dn", "must be >= 0 (absent = unknown), got " + Num(*c.read_noise_dn));
    }
  }

  // Sample.
  const SampleInfo& s = rig.sample;
  if (!s.region_min_m.allFinite()) return error("rig.sample.region_min_m", "must be finite");
  if (!s.region_max_m.allFinite()) return error("rig.sample.region_max_m", "must be finite");
  for (int k = 0; k < 2; ++k) {
    if (!(s.region_max_m[k] > s.region_min_m[k])) {
      return error(Element("rig.sample.region_max_m", k),
                   "must be > region_min_m[" + std::to_string(k) + "] (" + Num(s.region_min_m[k]) +
                       "), got " + Num(s.region_max_m[k]));
    }
  }
  if (!(s.pixel_pitch_m > 0) || !std::isfinite(s.pixel_pitch_m)) {
    return error("rig.sample.pixel_pitch_m", "must be > 0, got " + Num(s.pixel_pitch_m));
  }
  if (!(s.glass_thickness_m >= 0) || !std::isfinite(s.glass_thickness_m)) {
    return error("rig.sample.glass_thickness_m", "must be >= 0, got " + Num(s.glass_thickness_m));
  }
  if (!(s.glass_ior >= 1) || !std::isfinite(s.glass_ior)) {
    return error("rig.sample.glass_ior", "must be >= 1, got " + Num(s.glass_ior));
  }
  if (!Contains(ContaminantSides(), s.contaminant_side)) {
    return error("rig.sample.contaminant_side",
                 "must be " + OneOf(ContaminantSides()) + ", got " + Quote(s.contaminant_side));
  }

  // Optional devices.
  if (rig.board.present) {
    if (!(rig.board.distance_m > 0 && rig.board.distance_m <= kMaxBoardDistanceM)) {
      return error("rig.board.distance_m", "must be in (0, " + Num(kMaxBoardDistanceM) + "] m, got " +
                                               Num(rig.board.distance_m));
    }
    if (!(rig.board.albedo > 0 && rig.board.albedo <= 1)) {
      return error("rig.board.albedo", "must be in (0, 1], got " + Num(rig.board.albedo));
    }
  }
  if (rig.projector.present) {
    if (!Contains(ProjectorKinds(), rig.projector.kind)) {
      return error("rig.projector.kind",
                   "must be " + OneOf(ProjectorKinds()) + ", got " + Quote(rig.projector.kind));
    }
    const double n = rig.projector.direction_in_sample.norm();
    if (!(n > 0) || !std::isfinite(n)) {
      return error("rig.projector.direction_in_sample", "must be a non-zero finite vector");
    }
    // The light must cross the sample towards the board: a direction in (or near) the sample
    // plane casts no shadow map (a fit would "succeed" on nothing).
    if (!(rig.projector.direction_in_sample.z() / n < -kMinProjectorCosine)) {
      return error("rig.projector.direction_in_sample",
                   "must point through the sample towards the board (z < 0, at most " +
                       Num(std::acos(kMinProjectorCosine) * 180 / 3.14159265358979323846) +
                       " degrees from the normal), got " + Array3Text(rig.projector.direction_in_sample));
    }
  }
  if (rig.laser.present) {
    if (!rig.laser.origin_in_sample.allFinite()) {
      return error("rig.laser.origin_in_sample", "must be finite");
    }
    const double n = rig.laser.direction_in_sample.norm();
    if (!(n > 0) || !std::isfinite(n)) {
      return error("rig.laser.direction_in_sample", "must be a non-zero finite vector");
    }
    if (!(rig.laser.beam_radius_m >= 0) || !std::isfinite(rig.laser.beam_radius_m)) {
      return error("rig.laser.beam_radius_m",
                   "must be >= 0 (0 = unknown), got " + Num(rig.laser.beam_radius_m));
    }
    if (!(rig.laser.wavelength_m >= 0) || !std::isfinite(rig.laser.wavelength_m)) {
      return error("rig.laser.wavelength_m",
                   "must be >= 0 (0 = unknown), got " + Num(rig.laser.wavelength_m));
    }
  }
  if (rig.monitor.present) {
    const MonitorInfo& m = rig.monitor;
    const double qn = m.sample_from_monitor.rotation.norm();
    if (!(qn > 1e-12) || !std::isfinite(qn)) {
      return error("rig.monitor.sample_from_monitor.rotation_wxyz", "quaternion must be non-zero");
    }
    if (!m.sample_from_monitor.translation.allFinite()) {
      return error("rig.monitor.sample_from_monitor.translation_m", "must be finite");
    }
    if (!(m.pixel_pitch_m > 0) || !std::isfinite(m.pixel_pitch_m)) {
      return error("rig.monitor.pixel_pitch_m", "must be > 0, got " + Num(m.pixel_pitch_m));
    }
    if (m.width_px <= 0)
      return error("rig.monitor.width_px", "must be > 0, got " + std::to_string(m.width_px));
    if (m.height_px <= 0)
      return error("rig.monitor.height_px", "must be > 0, got " + std::to_string(m.height_px));
    if (!(m.dot_radius_px >= 0 && m.dot_radius_px <= 1000)) {
      return error("rig.monitor.dot_radius_px", "must be in [0, 1000] monitor px (0 = not given), got " +
                                                    Num(m.dot_radius_px));
    }
  }

  // Frames.
  const int num_frames = static_cast<int>(session.frames.size());
  std::vector<int> position_of_index(session.frames.size(), -1);
  for (int i = 0; i < num_frames; ++i) {
    const FrameRecord& f = session.frames[i];
    const std::string p = Element("frames", i);
    if (f.index < 0 || f.index >= num_frames) {
      return error(p + ".index", std::to_string(f.index) + " is outside [0, " +
                                     std::to_string(num_frames) +
                                     "): frame indices must be contiguous from 0");
    }
    if (position_of_index[f.index] >= 0) {
      return error(p + ".index", "duplicate index " + std::to_string(f.index) + " (also " +
                                     Element("frames", position_of_index[f.index]) + ")");
    }
    position_of_index[f.index] = i;
    if (camera_index.count(f.camera_id) == 0) {
      std::string known;
      for (const auto& c : rig.cameras) known += (known.empty() ? "" : ", ") + c.id;
      return error(p + ".camera",
                   "unknown camera id " + Quote(f.camera_id) + " (rig.cameras has: " + known + ")");
    }
    if (f.kind.empty()) return error(p + ".kind", "must be a non-empty string");
    if (!Contains(SampleStates(), f.sample_state)) {
      return error(p + ".sample_state",
                   "must be " + OneOf(SampleStates()) + ", got " + Quote(f.sample_state));
    }
    if (!std::isfinite(f.gain_db)) return error(p + ".gain_db", "must be finite");
    if (f.light.dot_px.has_value() && !f.light.dot_px->allFinite()) {
      return error(p + ".light.dot_px", "must be finite");
    }
    if (!std::isfinite(f.light.dot_radiance))
      return error(p + ".light.dot_radiance", "must be finite");
    constexpr uint64_t kCounterLimit = uint64_t(1) << 63;
    if (f.camera_frame_id.value_or(0) >= kCounterLimit) {
      return error(p + ".camera_frame_id", "must be < 2^63, got " + std::to_string(*f.camera_frame_id));
    }
    if (f.camera_timestamp_ns.value_or(0) >= kCounterLimit) {
      return error(p + ".camera_timestamp_ns", "must be < 2^63, got " + std::to_string(*f.camera_timestamp_ns));
    }
    if (f.status == FrameStatus::kFailed) continue;
    if (!(f.exposure_time_us > 0) || !std::isfinite(f.exposure_time_us)) {
      return error(p + ".exposure_time_us", "must be > 0, got " + Num(f.exposure_time_us));
    }
    std::string resolved;
    const std::string reason = ResolveFrameFile(session_dir, f.file, &resolved);
    if (!reason.empty()) return error(p + ".file", reason + " (status " + FrameStatusName(f.status) + ")");
    if (!f.variance_file.empty()) {
      if (Lowercase(fs::path(f.variance_file).extension().string()) != ".exr") {
        return error(p + ".variance_file", "must be an .exr file, got " + Quote(f.variance_file));
      }
      const std::string variance_reason = ResolveFrameFile(session_dir, f.variance_file, &resolved);
      if (!variance_reason.empty()) return error(p + ".variance_file", variance_reason);
    }
  }
  if (session.acquisition.present) {
    const AcquisitionInfo& acq = session.acquisition;
    if (!Contains(AcquisitionStates(), acq.state)) {
      return error("acquisition.state", "must be " + OneOf(AcquisitionStates()) + ", got " + Quote(acq.state));
    }
    if (acq.planned_frames < 0) {
      return error("acquisition.planned_frames", "must be >= 0, got " + std::to_string(acq.planned_frames));
    }
    if (acq.camera_captures < 0 || acq.discarded_frames < 0) {
      return error("acquisition", "camera_captures and discarded_frames must be >= 0");
    }
  }
  return Status::Ok();
}

std::string SummarizeSession(const Session& session) {
  std::ostringstream out;
  out << "Session " << Quote(session.name) << " (kind " << session.kind << ", format_version "
      << session.format_major << "." << session.format_minor << ")\n";
  out << "  created " << (session.created_utc.empty() ? "?" : session.created_utc);
  if (!session.software.empty()) out << " by " << session.software;
  out << "\n";

  const RigInfo& rig = session.rig;
  out << "Cameras: " << rig.cameras.size() << "\n";
  for (const CameraInfo& c : rig.cameras) {
    out << "  " << c.id << ": " << c.width_px << "x" << c.height_px << " px, "
        << (c.bit_depth == 32 ? std::string("float") : std::to_string(c.bit_depth) + "-bit")
        << ", fx " << Num(c.fx_px) << " px, fy " << Num(c.fy_px) << " px, model " << c.model;
    if (!c.serial.empty()) out << ", serial " << c.serial;
    if (c.linear_frames()) out << ", linear frames";
    out << ", black " << Num(c.black_level_dn) << " DN, saturation "
        << (std::isfinite(c.saturation_dn) ? Num(c.saturation_dn) + " DN" : std::string("none"));
    out << ", gain " << (c.gain_e_per_dn > 0 ? Num(c.gain_e_per_dn) + " e/DN" : std::string("unknown"));
    if (c.read_noise_dn.has_value()) out << ", read noise " << Num(*c.read_noise_dn) << " DN";
    out << "\n";
  }
  const SampleInfo& s = rig.sample;
  out << "Sample region: [" << Num(s.region_min_m.x()) << ", " << Num(s.region_max_m.x()) << "] x ["
      << Num(s.region_min_m.y()) << ", " << Num(s.region_max_m.y()) << "] m, pitch "
      << Num(s.pixel_pitch_m) << " m, contaminant on the " << s.contaminant_side << " side\n";
  out << "Board: ";
  if (rig.board.present) {
    out << "present (distance " << Num(rig.board.distance_m) << " m, albedo "
        << Num(rig.board.albedo) << ")\n";
  } else {
    out << "absent\n";
  }
  out << "Projector: ";
  if (rig.projector.present) {
    const Eigen::Vector3d& d = rig.projector.direction_in_sample;
    out << "present (" << rig.projector.kind << ", direction (" << Num(d.x()) << ", " << Num(d.y())
        << ", " << Num(d.z()) << "))\n";
  } else {
    out << "absent\n";
  }
  out << "Laser: ";
  if (rig.laser.present) {
    out << "present (beam radius " << Num(rig.laser.beam_radius_m) << " m, wavelength "
        << Num(rig.laser.wavelength_m) << " m)\n";
  } else {
    out << "absent\n";
  }
  out << "Monitor: ";
  if (rig.monitor.present) {
    out << "present (" << rig.monitor.width_px << "x" << rig.monitor.height_px << " px, pitch "
        << Num(rig.monitor.pixel_pitch_m) << " m)\n";
  } else {
    out << "absent\n";
  }

  std::map<std::pair<std::string, std::string>, int> counts;
  int failed = 0, retried = 0, usable = 0;
  double min_exposure = std::numeric_limits<double>::infinity();
  double max_exposure = -std::numeric_limits<double>::infinity();
  for (const FrameRecord& f : session.frames) {
    if (f.status == FrameStatus::kFailed) {
      ++failed;
      continue;
    }
    if (f.status == FrameStatus::kRetried) ++retried;
    ++usable;
    ++counts[{f.kind, f.sample_state}];
    min_exposure = std::min(min_exposure, f.exposure_time_us);
    max_exposure = std::max(max_exposure, f.exposure_time_us);
  }
  out << "Frames: " << session.frames.size() << " (" << usable << " usable, " << failed
      << " failed, " << retried << " retried)\n";
  for (const auto& [key, n] : counts) {
    out << "  " << key.first << " / " << key.second << ": " << n << "\n";
  }
  if (usable > 0) {
    out << "Exposure: " << Num(min_exposure) << " .. " << Num(max_exposure) << " us\n";
  }
  if (session.acquisition.present) {
    const AcquisitionInfo& acq = session.acquisition;
    out << "Acquisition: " << acq.state << ", " << usable << " of " << acq.planned_frames
        << " planned frames, " << acq.camera_captures << " captures (" << acq.discarded_frames
        << " discarded before the display change was seen)\n";
    for (const AcquisitionEvent& e : acq.events) {
      out << "  " << e.time_utc << " " << e.event << " at " << e.frames << " frames";
      if (!e.device.empty()) out << ": " << e.device;
      if (!e.message.empty()) out << ": " << e.message;
      out << "\n";
    }
  }
  return out.str();
}

}  // namespace thinslab
