// SPDX-License-Identifier: Apache-2.0
// Atomic output. Every thinslab output goes through these helpers: a file is written to a
// temporary sibling, flushed, renamed over its target and the rename flushed to the parent
// folder, so a crash, a power cut or an error never leaves a partial file or loses one that
// was reported written. A folder of outputs is built in a staging sibling and swapped into
// place on Commit(); if Commit() is never reached the staging folder is removed.
// What may be replaced at all is core/output_guard.h's rule.
#pragma once

#include <string>
#include <vector>

#include "thinslab/core/output_guard.h"
#include "thinslab/core/status.h"

namespace thinslab {

Status WriteFileAtomically(const std::string& path, const std::string& bytes);
Status ReadFileToString(const std::string& path, std::string* bytes);
bool FileExists(const std::string& path);
// "" when `path` is a regular file this process can read; otherwise why not, in words ("does
// not exist", "is a folder, not a file", "is a FIFO, not a regular file", "cannot be read:
// Permission denied").
std::string UnreadableFileReason(const std::string& path);
bool DirectoryExists(const std::string& path);
Status CreateDirectories(const std::string& path);
std::string JoinPath(const std::string& a, const std::string& b);

// A simulation's new output folder: unless Keep() is called, the destructor removes what was
// written there (a failed simulation leaves no partial capture), restoring the folder as it
// was (absent, or empty). A folder that held files before is never touched.
class NewFolderGuard {
 public:
  explicit NewFolderGuard(std::string dir);
  ~NewFolderGuard();
  NewFolderGuard(const NewFolderGuard&) = delete;
  NewFolderGuard& operator=(const NewFolderGuard&) = delete;
  void Keep() { keep_ = true; }

 private:
  std::string dir_;
  bool existed_empty_ = false;
  bool ours_ = false;
  bool keep_ = false;
};

// Flushes a folder's entries (a rename or a new file in it) to disk.
Status SyncDirectory(const std::string& dir);

class StagedDirectory {
 public:
  // `final_dir` is created (replacing an older output of the same `command`) only on Commit().
  // `inputs` are the command's inputs, which the output must stay out of (output_guard.h).
  StagedDirectory(std::string final_dir, std::string command, std::vector<InputPath> inputs = {});
  ~StagedDirectory();
  StagedDirectory(const StagedDirectory&) = delete;
  StagedDirectory& operator=(const StagedDirectory&) = delete;

  // Checks that final_dir may be replaced (before the work, so a refusal costs nothing),
  // removes staging folders that killed runs left beside it and creates the staging folder
  // with its output stamp.
  Status Init();
  // Where to write the outputs before Commit().
  const std::string& path() const { return staging_dir_; }
  const std::string& final_path() const { return final_dir_; }
  Status Commit();

 private:
  std::string final_dir_;
  std::string command_;
  std::vector<InputPath> inputs_;
  std::string staging_dir_;
  std::string first_created_parent_;  // The outermost folder Init() created, "" if none.
  bool committed_ = false;
};

// FNV-1a 64-bit hash as 16 hex digits (the provenance digest of options.ini in every output).
std::string Digest(const std::string& text);

}  // namespace thinslab
