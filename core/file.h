// SPDX-License-Identifier: Apache-2.0
// Atomic output. Every thinslab output goes through these helpers: a file is written to a
// temporary sibling, flushed and renamed over its target, so a crash or an error never
// leaves a partial file. A folder of outputs is built in a staging sibling and renamed
// into place on Commit(); if Commit() is never reached the staging folder is removed.
#pragma once

#include <string>

#include "core/status.h"

namespace thinslab {

Status WriteFileAtomically(const std::string& path, const std::string& bytes);
Status ReadFileToString(const std::string& path, std::string* bytes);
bool FileExists(const std::string& path);
bool DirectoryExists(const std::string& path);
Status CreateDirectories(const std::string& path);
std::string JoinPath(const std::string& a, const std::string& b);

class StagedDirectory {
 public:
  // `final_dir` is created (replacing an older one) only on Commit().
  explicit StagedDirectory(std::string final_dir);
  ~StagedDirectory();
  StagedDirectory(const StagedDirectory&) = delete;
  StagedDirectory& operator=(const StagedDirectory&) = delete;

  Status Init();
  // Where to write the outputs before Commit().
  const std::string& path() const { return staging_dir_; }
  const std::string& final_path() const { return final_dir_; }
  Status Commit();

 private:
  std::string final_dir_;
  std::string staging_dir_;
  bool committed_ = false;
};

}  // namespace thinslab
