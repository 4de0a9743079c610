// SPDX-License-Identifier: Apache-2.0
// Shared vocabulary of the capture format's reader, writer, validator and frame loader
// (docs/format.md): field paths for messages, the enumerations the format allows, relative
// frame paths resolved inside the capture. Internal to core/ (namespace session_format).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iomanip>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "thinslab/core/file.h"
#include "thinslab/core/session.h"

namespace thinslab {
namespace session_format {

namespace fs = std::filesystem;
using Json = nlohmann::json;
// Writing keeps the field order of docs/format.md, which makes manifests easy to read.
using OrderedJson = nlohmann::ordered_json;

inline constexpr char kFormatName[] = "thinslab-session";

inline std::string ManifestPath(const std::string& session_dir) {
  return JoinPath(session_dir, kSessionManifestName);
}

inline std::string Num(double value) {
  std::ostringstream ss;
  ss << std::setprecision(10) << value;
  return ss.str();
}

inline std::string Quote(const std::string& s) { return "\"" + s + "\""; }

inline std::string Child(const std::string& path, const std::string& key) {
  return path.empty() ? key : path + "." + key;
}

inline std::string Element(const std::string& path, size_t i) {
  return path + "[" + std::to_string(i) + "]";
}

// "a", "a or b", "a, b or c".
inline std::string OneOf(const std::vector<std::string>& values) {
  std::string out;
  for (size_t i = 0; i < values.size(); ++i) {
    if (i > 0) out += (i + 1 == values.size()) ? " or " : ", ";
    out += Quote(values[i]);
  }
  return out;
}

inline bool Contains(const std::vector<std::string>& values, const std::string& v) {
  return std::find(values.begin(), values.end(), v) != values.end();
}

inline const std::vector<std::string>& FrameStatusNames() {
  static const std::vector<std::string> names = {"ok", "failed", "retried"};
  return names;
}
inline const std::vector<std::string>& SampleStates() {
  static const std::vector<std::string> names = {"contaminated", "clean", "none"};
  return names;
}
inline const std::vector<std::string>& AcquisitionStates() {
  static const std::vector<std::string> names = {"running", "complete", "failed", "interrupted"};
  return names;
}
inline const std::vector<std::string>& ContaminantSides() {
  static const std::vector<std::string> names = {"board", "projector"};
  return names;
}
inline const std::vector<std::string>& FrameValueKinds() {
  static const std::vector<std::string> names = {"raw", "linear"};
  return names;
}
// A frame's exposure_time_us while parsing, before ReadSession knows its camera.
inline constexpr double kExposureAbsent = std::numeric_limits<double>::quiet_NaN();
inline const std::vector<std::string>& ProjectorKinds() {
  static const std::vector<std::string> names = {"collimated", "pinhole"};
  return names;
}
inline const std::vector<int>& BitDepths() {
  static const std::vector<int> depths = {8, 10, 12, 14, 16, 32};
  return depths;
}
inline bool IsIntegerDepth(int bit_depth) { return bit_depth >= 1 && bit_depth <= 16; }

// "<major>.<minor>" with decimal digits only.
inline bool ParseVersion(const std::string& s, int* major, int* minor) {
  const size_t dot = s.find('.');
  if (dot == std::string::npos || dot == 0 || dot + 1 == s.size()) return false;
  if (dot > 6 || s.size() - dot - 1 > 6) return false;
  for (size_t i = 0; i < s.size(); ++i) {
    if (i != dot && !std::isdigit(static_cast<unsigned char>(s[i]))) return false;
  }
  *major = std::stoi(s.substr(0, dot));
  *minor = std::stoi(s.substr(dot + 1));
  return true;
}

// Empty if `file` is a relative path that stays inside the session folder, otherwise the
// reason it is not.
inline std::string CheckRelativeFile(const std::string& file) {
  if (file.empty()) return "must name the frame file, got an empty string";
  const fs::path p(file);
  if (p.is_absolute() || p.has_root_name() || p.has_root_directory()) {
    return "must be relative to the session folder, got the absolute path " + Quote(file);
  }
  for (const auto& part : p) {
    if (part == "..") {
      return "must stay inside the session folder (no \"..\" components), got " + Quote(file);
    }
  }
  return "";
}

// Where a frame's file is, resolved through symlinks; "" and *resolved set when it is a
// readable regular file inside the session folder, else why not. Frames are read by this
// resolved path, so that a symlink pointing out of the capture is refused (issue #22).
inline std::string ResolveFrameFile(const std::string& session_dir, const std::string& file, std::string* resolved) {
  const std::string relative = CheckRelativeFile(file);
  if (!relative.empty()) return relative;
  const std::string path = JoinPath(session_dir, file);
  const std::string unreadable = UnreadableFileReason(path);
  if (!unreadable.empty()) return "frame file " + Quote(file) + " " + unreadable;
  std::error_code ec;
  const fs::path real = fs::canonical(path, ec);
  const fs::path root = fs::canonical(session_dir, ec);
  if (ec) return "frame file " + Quote(file) + ": cannot resolve its path: " + ec.message();
  auto r = real.begin();
  for (auto s = root.begin(); s != root.end(); ++s, ++r) {
    if (r == real.end() || *r != *s) {
      return "frame file " + Quote(file) + " is a symbolic link to " + Quote(real.string()) +
             ", outside the session folder";
    }
  }
  *resolved = real.string();
  return "";
}

// The projector's light within acos(0.1) = 84.3 degrees of the sample normal.
inline constexpr double kMinProjectorCosine = 0.1;

inline std::string Array3Text(const Eigen::Vector3d& v) {
  std::ostringstream out;
  out << "[" << v.x() << ", " << v.y() << ", " << v.z() << "]";
  return out.str();
}

// Normalises a quaternion unless it already is unit length to rounding, so that writing
// and reading a session reproduces it bit for bit.
inline void NormalizeIfNeeded(Eigen::Quaterniond* q) {
  const double norm = q->norm();
  if (norm > 0 && std::abs(norm - 1.0) > 4 * std::numeric_limits<double>::epsilon()) {
    q->normalize();
  }
}
inline void NormalizeIfNeeded(Eigen::Vector3d* v) {
  const double norm = v->norm();
  if (norm > 0 && std::isfinite(norm) &&
      std::abs(norm - 1.0) > 4 * std::numeric_limits<double>::epsilon()) {
    v->normalize();
  }
}

inline std::string Lowercase(std::string s) {
  for (char& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}

}  // namespace session_format
}  // namespace thinslab
