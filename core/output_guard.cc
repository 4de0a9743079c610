// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/output_guard.h"

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "thinslab/core/session.h"
#include "thinslab/core/version.h"

namespace thinslab {
namespace fs = std::filesystem;

namespace {

// Absolute, with symlinks of the existing prefix resolved and "." / ".." removed.
fs::path Resolved(const std::string& path) {
  std::error_code ec;
  fs::path p = fs::weakly_canonical(fs::absolute(path, ec), ec);
  if (ec) p = fs::absolute(path).lexically_normal();
  // weakly_canonical keeps a trailing separator ("a/b/"), which would compare unequal to "a/b".
  if (!p.has_filename() && p.has_parent_path() && p != p.root_path()) p = p.parent_path();
  return p;
}

// `inner` equals `outer` or lies below it; `rest` receives inner relative to outer.
bool IsWithin(const fs::path& inner, const fs::path& outer, fs::path* rest) {
  auto i = inner.begin();
  for (auto o = outer.begin(); o != outer.end(); ++o, ++i) {
    if (i == inner.end() || *i != *o) return false;
  }
  fs::path r;
  for (; i != inner.end(); ++i) r /= *i;
  *rest = r;
  return true;
}

std::string ReadPrefix(const std::string& path, size_t max_bytes) {
  std::ifstream in(path, std::ios::binary);
  std::string bytes(max_bytes, '\0');
  in.read(bytes.data(), static_cast<std::streamsize>(max_bytes));
  bytes.resize(static_cast<size_t>(std::max<std::streamsize>(in.gcount(), 0)));
  return bytes;
}

std::string Ext(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext;
}

// Refuses a path inside a capture folder (one holding a manifest) outside the capture's
// output folders fit/ and calib/: a capture's manifest and frames are never outputs, whatever
// the command's declared inputs are.
Status CheckNotInsideCaptureData(const std::string& path) {
  const fs::path p = Resolved(path);
  std::error_code ec;
  for (fs::path dir = p.parent_path(); !dir.empty(); dir = dir.parent_path()) {
    if (fs::is_regular_file(dir / kSessionManifestName, ec)) {
      fs::path rest;
      IsWithin(p, dir, &rest);
      const std::string first = rest.begin()->string();
      if (first != "fit" && first != "calib") {
        return Status::Error(path + ": lies inside the capture " + dir.string() + " (it holds " +
                             kSessionManifestName + "); thinslab writes into a capture only under fit/ and calib/");
      }
      return Status::Ok();
    }
    if (dir == dir.root_path()) break;
  }
  return Status::Ok();
}

}  // namespace

Status CheckOutputOutsideInputs(const std::string& output, const std::vector<InputPath>& inputs) {
  const fs::path out = Resolved(output);
  for (const InputPath& input : inputs) {
    if (input.path.empty()) continue;
    const fs::path in = Resolved(input.path);
    fs::path rest;
    if (out == in) {
      return Status::Error(output + ": the output is the input " + input.path + "; choose another output path");
    }
    if (IsWithin(in, out, &rest)) {
      return Status::Error(output + ": the output folder contains the input " + input.path +
                           " and replacing it would delete it; choose another output path");
    }
    if (IsWithin(out, in, &rest)) {
      const std::string first = rest.begin() == rest.end() ? "" : rest.begin()->string();
      const auto& allowed = input.output_subfolders;
      if (std::find(allowed.begin(), allowed.end(), first) == allowed.end()) {
        std::string where;
        for (const auto& a : allowed) where += (where.empty() ? "" : " or ") + (fs::path(input.path) / a).string() + "/";
        return Status::Error(output + ": the output lies inside the input " + input.path +
                             (where.empty() ? std::string(", which thinslab never writes into")
                                            : ", outside its output folders (" + where + ")"));
      }
    }
  }
  return Status::Ok();
}

std::string OutputStampText(const std::string& command) {
  nlohmann::json j;
  j["format"] = "thinslab-output-stamp";
  j["command"] = command;
  j["thinslab_version"] = THINSLAB_VERSION_STRING;
  return j.dump(2) + "\n";
}

std::string ReadOutputStamp(const std::string& folder) {
  const std::string path = (fs::path(folder) / kOutputStampName).string();
  std::error_code ec;
  if (!fs::is_regular_file(fs::symlink_status(path, ec))) return "";
  try {
    const nlohmann::json j = nlohmann::json::parse(ReadPrefix(path, 1 << 16));
    if (j.value("format", "") != "thinslab-output-stamp") return "";
    return j.value("command", "");
  } catch (const std::exception&) {
    return "";
  }
}

Status CheckReplaceableFolder(const std::string& folder, const std::string& command) {
  THINSLAB_RETURN_IF_ERROR(CheckNotInsideCaptureData(folder));
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(folder, ec);
  if (ec || !fs::exists(st)) return Status::Ok();
  if (fs::is_symlink(st)) {
    return Status::Error(folder + ": the output path is a symbolic link; thinslab does not replace links");
  }
  if (!fs::is_directory(st)) {
    return Status::Error(folder + ": the output folder path exists and is not a folder; thinslab will not replace it");
  }
  if (fs::is_empty(folder, ec) && !ec) return Status::Ok();
  const std::string stamp = ReadOutputStamp(folder);
  if (stamp.empty()) {
    return Status::Error(folder + ": exists, is not empty and was not written by thinslab (no " +
                         kOutputStampName + " stamp); thinslab replaces only its own output folders: "
                         "remove it or choose another output path");
  }
  if (stamp != command) {
    return Status::Error(folder + ": holds the output of 'thinslab " + stamp + "', not of 'thinslab " + command +
                         "'; choose another output path");
  }
  return Status::Ok();
}

bool IsThinslabFile(const std::string& path) {
  std::error_code ec;
  if (!fs::is_regular_file(fs::symlink_status(path, ec))) return false;
  const std::string ext = Ext(path);
  if (ext == ".json") {
    if (fs::file_size(path, ec) > (64u << 20)) return false;
    try {
      std::ifstream in(path);
      const nlohmann::json j = nlohmann::json::parse(in);
      return j.is_object() && j.contains("format") && j["format"].is_string() &&
             j["format"].get<std::string>().rfind("thinslab", 0) == 0;
    } catch (const std::exception&) {
      return false;
    }
  }
  const std::string head = ReadPrefix(path, 1 << 16);
  if (ext == ".exr") {
    static const std::string kAttribute("thinslab_version\0string\0", 24);
    return head.rfind("\x76\x2f\x31\x01", 0) == 0 && head.find(kAttribute) != std::string::npos;
  }
  if (ext == ".png") {
    static const std::string kChunk("tEXtSoftware\0thinslab", 21);
    return head.find(kChunk) != std::string::npos;
  }
  return head.rfind("# thinslab", 0) == 0 || head.rfind("thinslab ", 0) == 0;
}

Status CheckReplaceableFile(const std::string& path) {
  THINSLAB_RETURN_IF_ERROR(CheckNotInsideCaptureData(path));
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(path, ec);
  if (ec || !fs::exists(st)) return Status::Ok();
  if (fs::is_symlink(st)) {
    return Status::Error(path + ": the output path is a symbolic link; thinslab does not replace links");
  }
  if (!fs::is_regular_file(st)) {
    return Status::Error(path + ": the output path exists and is not a regular file; thinslab will not replace it");
  }
  if (!IsThinslabFile(path)) {
    return Status::Error(path + ": exists and was not written by thinslab; thinslab replaces only its own "
                         "files: remove it or choose another output path");
  }
  return Status::Ok();
}

Status CheckOutputFile(const std::string& path, const std::vector<InputPath>& inputs) {
  THINSLAB_RETURN_IF_ERROR(CheckOutputOutsideInputs(path, inputs));
  return CheckReplaceableFile(path);
}

}  // namespace thinslab
