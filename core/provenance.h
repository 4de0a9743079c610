// SPDX-License-Identifier: Apache-2.0
// Who made an output and from what. Every EXR header and summary.json a command writes goes
// through these helpers, so each output can be traced to the thinslab build, the command, its
// effective options (options.ini, by digest) and its inputs (docs/format.md "Provenance").
#pragma once

#include <nlohmann/json.hpp>
#include <string>

#include "thinslab/core/image.h"
#include "thinslab/core/rigid3.h"

namespace thinslab {

// Version of the output files' layout (channel names, attributes; docs/format.md "Output maps").
// 1.0: flat channel names, JSON text attributes. 2.0: layer.channel names, typed attributes.
inline constexpr char kOutputFormatVersion[] = "2.0";

struct Provenance {
  std::string command;      // The command that wrote the output, e.g. "fit tau".
  std::string source;       // Its input: a capture folder, or a fit folder for export-like commands.
  std::string source_fit;   // A second input (a fit folder), "" if none.
  std::string options_ini;  // The effective options as written to options.ini ("" if the command has none).
};

// The command line of this process's command (main and Python's run_command set it; "" if
// none), recorded as provenance "command_line" and shown in report.html.
void SetCommandLine(const std::string& command_line);
const std::string& CommandLine();

// "fnv1a64:<16 hex digits>" of the lines of options.ini that are not comments (header,
// diagnostic options): equal digests, equal options.
std::string OptionsDigest(const std::string& options_ini);

// Header attributes of an output EXR: format_version, thinslab_version, git_hash,
// thinslab_command, options_digest, source_session (and source_fit), software and the standard
// OpenEXR `comments`.
void StampProvenance(const Provenance& provenance, Image* image);

// The same fields for summary.json, as its "provenance" object.
nlohmann::json ProvenanceJson(const Provenance& provenance);

// The camera pose as OpenEXR's standard `worldToCamera` attribute: the sample frame is the
// world, the camera frame OpenCV's (x right, y down, z forward), and the matrix is in Imath's
// row-vector convention (p_camera = p_sample * M), so M is the transpose of [R t; 0 1].
void SetWorldToCamera(const Rigid3d& cam_from_sample, Image* image);
// The pose back from an image read by ReadExr; false when it has no `worldToCamera`.
bool GetWorldToCamera(const Image& image, Rigid3d* cam_from_sample);

}  // namespace thinslab
