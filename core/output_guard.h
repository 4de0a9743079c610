// SPDX-License-Identifier: Apache-2.0
// What thinslab may overwrite (docs/format.md, "What thinslab overwrites"). Outputs never
// destroy inputs or the user's own files:
//  - an output is refused when it is, contains or lies inside one of the command's inputs,
//    except inside the input's documented output subfolders (a capture's fit/ or calib/);
//  - an existing folder is replaced only when it is empty or carries thinslab's output stamp
//    (kOutputStampName) of the same command;
//  - an existing file is replaced only when thinslab wrote it (IsThinslabFile).
#pragma once

#include <string>
#include <vector>

#include "thinslab/core/status.h"

namespace thinslab {

// The stamp file every staged output folder carries (core/file.h StagedDirectory).
inline constexpr char kOutputStampName[] = ".thinslab-output";

// One input of a command: a folder (capture, prototype library) or a file (layer, tau map).
struct InputPath {
  std::string path;
  // Folders relative to `path` under which this command may write ("fit", "calib").
  std::vector<std::string> output_subfolders;
};

// Refuses `output` when it is, contains or lies inside any input outside its output
// subfolders. Paths are compared after resolving symlinks and "..".
Status CheckOutputOutsideInputs(const std::string& output, const std::vector<InputPath>& inputs);

// The stamp's text, naming the command that wrote the folder ("fit tau").
std::string OutputStampText(const std::string& command);
// The command recorded in `folder`'s stamp, or "" when there is none.
std::string ReadOutputStamp(const std::string& folder);

// OK when `folder` does not exist, is empty, or carries the stamp of `command`.
Status CheckReplaceableFolder(const std::string& folder, const std::string& command);
// OK when `path` does not exist or is a regular file thinslab wrote.
Status CheckReplaceableFile(const std::string& path);
// Both checks a single-file output needs.
Status CheckOutputFile(const std::string& path, const std::vector<InputPath>& inputs);

// True for a regular file carrying thinslab's mark: JSON with "format": "thinslab-...", an EXR
// with a `thinslab_version` header attribute, a PNG with a "Software: thinslab" text chunk, a
// text file whose first line starts with "# thinslab" or "thinslab ".
bool IsThinslabFile(const std::string& path);

}  // namespace thinslab
