// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/provenance.h"

#include <Eigen/Core>

#include "thinslab/core/file.h"
#include "thinslab/core/version.h"

namespace thinslab {

namespace {
std::string& CommandLineStorage() {
  static std::string command_line;
  return command_line;
}
}  // namespace

void SetCommandLine(const std::string& command_line) { CommandLineStorage() = command_line; }
const std::string& CommandLine() { return CommandLineStorage(); }

std::string OptionsDigest(const std::string& options_ini) {
  // Comment lines (the header naming the command, diagnostic options) are not options.
  std::string settings;
  size_t start = 0;
  while (start < options_ini.size()) {
    size_t end = options_ini.find('\n', start);
    if (end == std::string::npos) end = options_ini.size() - 1;
    const size_t first = options_ini.find_first_not_of(" \t", start);
    if (first > end || options_ini[first] != '#') settings.append(options_ini, start, end + 1 - start);
    start = end + 1;
  }
  return "fnv1a64:" + Digest(settings);
}

void StampProvenance(const Provenance& provenance, Image* image) {
  auto& a = image->attributes();
  a["format_version"] = kOutputFormatVersion;
  a["thinslab_version"] = THINSLAB_VERSION_STRING;
  a["git_hash"] = THINSLAB_GIT_HASH;
  a["software"] = std::string("thinslab ") + THINSLAB_VERSION_STRING + " (" + THINSLAB_GIT_HASH + ")";
  a["thinslab_command"] = provenance.command;
  a["options_digest"] = OptionsDigest(provenance.options_ini);
  a["source_session"] = provenance.source;
  if (!provenance.source_fit.empty()) a["source_fit"] = provenance.source_fit;
  // OpenEXR's standard free-text attribute (OpenImageIO shows it as ImageDescription).
  a["comments"] = "thinslab " + provenance.command + " output; channels and attributes: docs/format.md";
}

nlohmann::json ProvenanceJson(const Provenance& provenance) {
  nlohmann::json j = {{"format_version", kOutputFormatVersion},
                      {"thinslab_version", THINSLAB_VERSION_STRING},
                      {"git_hash", THINSLAB_GIT_HASH},
                      {"command", provenance.command},
                      {"options_digest", OptionsDigest(provenance.options_ini)},
                      {"source_session", provenance.source}};
  if (!provenance.source_fit.empty()) j["source_fit"] = provenance.source_fit;
  if (!CommandLine().empty()) j["command_line"] = CommandLine();
  return j;
}

void SetWorldToCamera(const Rigid3d& cam_from_sample, Image* image) {
  const Eigen::Matrix3d r = cam_from_sample.rotation.normalized().toRotationMatrix();
  std::vector<double> m(16, 0.0);
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) m[4 * i + j] = r(j, i);  // Row-vector convention: the transpose.
    m[12 + i] = cam_from_sample.translation[i];
  }
  m[15] = 1;
  image->numeric_attributes()["worldToCamera"] = m;
}

bool GetWorldToCamera(const Image& image, Rigid3d* cam_from_sample) {
  const std::vector<double>* m = image.NumericAttribute("worldToCamera", 16);
  if (m == nullptr) return false;
  Eigen::Matrix3d r;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) r(j, i) = (*m)[4 * i + j];
    cam_from_sample->translation[i] = (*m)[12 + i];
  }
  cam_from_sample->rotation = Eigen::Quaterniond(r).normalized();
  return true;
}

}  // namespace thinslab
