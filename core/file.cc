// SPDX-License-Identifier: Apache-2.0
#include "thinslab/core/file.h"

#include <cstdio>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

namespace thinslab {
namespace fs = std::filesystem;

namespace {
std::string Errno() { return std::strerror(errno); }

std::string ParentOf(const std::string& path) {
  const std::string parent = fs::path(path).parent_path().string();
  return parent.empty() ? "." : parent;
}

// A process id that no longer runs (its staging folders are left-overs of a kill).
bool ProcessIsGone(long pid) { return pid > 0 && ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH; }

// The pid in "<stem><marker><pid>", or -1 when `name` is not of that form.
long PidSuffix(const std::string& name, const std::string& stem, const std::string& marker) {
  const std::string prefix = stem + marker;
  if (name.size() <= prefix.size() || name.compare(0, prefix.size(), prefix) != 0) return -1;
  const std::string digits = name.substr(prefix.size());
  if (digits.size() > 9 || digits.find_first_not_of("0123456789") != std::string::npos) return -1;
  return std::stol(digits);
}
}  // namespace

Status SyncDirectory(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) return Status::Error(dir + ": cannot open folder to flush it: " + Errno());
  const int rc = ::fsync(fd);
  const int fsync_errno = errno;
  ::close(fd);
  // Some file systems cannot fsync a folder (EINVAL): nothing more can be done there.
  if (rc != 0 && fsync_errno != EINVAL) {
    return Status::Error(dir + ": cannot flush folder: " + std::strerror(fsync_errno));
  }
  return Status::Ok();
}

Status WriteFileAtomically(const std::string& path, const std::string& bytes) {
  const std::string tmp = path + ".tmp-" + std::to_string(::getpid());
  const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return Status::Error(path + ": cannot create temporary file: " + Errno());
  size_t written = 0;
  while (written < bytes.size()) {
    const ssize_t n = ::write(fd, bytes.data() + written, bytes.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::string err = Errno();
      ::close(fd);
      ::unlink(tmp.c_str());
      return Status::Error(path + ": write failed: " + err);
    }
    written += static_cast<size_t>(n);
  }
  if (::fsync(fd) != 0 || ::close(fd) != 0) {
    const std::string err = Errno();
    ::unlink(tmp.c_str());
    return Status::Error(path + ": flush failed: " + err);
  }
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string err = Errno();
    ::unlink(tmp.c_str());
    return Status::Error(path + ": rename failed: " + err);
  }
  return SyncDirectory(ParentOf(path)).WithContext(path);
}

Status ReadFileToString(const std::string& path, std::string* bytes) {
  const std::string unreadable = UnreadableFileReason(path);
  if (unreadable == "does not exist") return Status::Error(path + ": file not found");
  if (!unreadable.empty()) return Status::Error(path + ": " + unreadable);
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::Error(path + ": cannot open for reading");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return Status::Error(path + ": read failed");
  *bytes = ss.str();
  return Status::Ok();
}

std::string UnreadableFileReason(const std::string& path) {
  std::error_code ec;
  const fs::file_status st = fs::status(path, ec);
  if (!fs::exists(st)) {
    return fs::is_symlink(fs::symlink_status(path, ec)) ? "is a broken symbolic link" : "does not exist";
  }
  if (fs::is_directory(st)) return "is a folder, not a file";
  if (fs::is_fifo(st)) return "is a FIFO, not a regular file";
  if (fs::is_block_file(st) || fs::is_character_file(st)) return "is a device, not a regular file";
  if (fs::is_socket(st)) return "is a socket, not a regular file";
  if (!fs::is_regular_file(st)) return "is not a regular file";
  if (::access(path.c_str(), R_OK) != 0) return "cannot be read: " + Errno();
  return "";
}

bool FileExists(const std::string& path) {
  std::error_code ec;
  return fs::is_regular_file(path, ec);
}

bool DirectoryExists(const std::string& path) {
  std::error_code ec;
  return fs::is_directory(path, ec);
}

Status CreateDirectories(const std::string& path) {
  std::error_code ec;
  fs::create_directories(path, ec);
  if (ec) return Status::Error(path + ": cannot create directory: " + ec.message());
  return Status::Ok();
}

std::string JoinPath(const std::string& a, const std::string& b) {
  return (fs::path(a) / fs::path(b)).string();
}

NewFolderGuard::NewFolderGuard(std::string dir) : dir_(std::move(dir)) {
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(dir_, ec);
  if (!fs::exists(st)) {
    ours_ = !dir_.empty();
  } else if (fs::is_directory(st) && fs::is_empty(dir_, ec) && !ec) {
    ours_ = existed_empty_ = true;
  }
}

NewFolderGuard::~NewFolderGuard() {
  if (keep_ || !ours_) return;
  std::error_code ec;
  fs::remove_all(dir_, ec);
  if (existed_empty_) fs::create_directory(dir_, ec);
}

StagedDirectory::StagedDirectory(std::string final_dir, std::string command, std::vector<InputPath> inputs)
    : final_dir_(std::move(final_dir)), command_(std::move(command)), inputs_(std::move(inputs)) {
  while (final_dir_.size() > 1 && final_dir_.back() == '/') final_dir_.pop_back();
  staging_dir_ = final_dir_ + ".partial-" + std::to_string(::getpid());
}

StagedDirectory::~StagedDirectory() {
  if (committed_) return;
  std::error_code ec;
  fs::remove_all(staging_dir_, ec);
  // A refused or failed command leaves no trace: the parents Init() created go too, if empty
  // (fs::remove removes only empty folders).
  if (first_created_parent_.empty()) return;
  for (fs::path dir = fs::path(staging_dir_).parent_path(); !dir.empty(); dir = dir.parent_path()) {
    if (!fs::remove(dir, ec) || dir == fs::path(first_created_parent_)) break;
  }
}

Status StagedDirectory::Init() {
  THINSLAB_RETURN_IF_ERROR(CheckOutputOutsideInputs(final_dir_, inputs_));
  THINSLAB_RETURN_IF_ERROR(CheckReplaceableFolder(final_dir_, command_));
  // Left-overs of killed runs beside final_dir: staging folders (never complete) are removed;
  // an older output moved aside by the fallback commit below is put back if final_dir is gone.
  const std::string parent = ParentOf(final_dir_);
  const std::string stem = fs::path(final_dir_).filename().string();
  std::error_code ec;
  if (fs::is_directory(parent, ec)) {
    for (const auto& entry : fs::directory_iterator(parent, ec)) {
      const std::string name = entry.path().filename().string();
      const long partial_pid = PidSuffix(name, stem, ".partial-");
      const long old_pid = PidSuffix(name, stem, ".old-");
      std::error_code ec2;
      if (ProcessIsGone(partial_pid)) fs::remove_all(entry.path(), ec2);
      if (ProcessIsGone(old_pid)) {
        if (fs::exists(final_dir_, ec2)) {
          fs::remove_all(entry.path(), ec2);
        } else {
          fs::rename(entry.path(), final_dir_, ec2);
        }
      }
    }
  }
  fs::remove_all(staging_dir_, ec);
  for (fs::path dir = fs::path(staging_dir_).parent_path(); !dir.empty() && !fs::exists(dir, ec);
       dir = dir.parent_path()) {
    first_created_parent_ = dir.string();
  }
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(staging_dir_));
  return WriteFileAtomically(JoinPath(staging_dir_, kOutputStampName), OutputStampText(command_));
}

Status StagedDirectory::Commit() {
  // Something may have appeared at final_dir while the command ran.
  THINSLAB_RETURN_IF_ERROR(CheckReplaceableFolder(final_dir_, command_));
  THINSLAB_RETURN_IF_ERROR(SyncDirectory(staging_dir_));
  std::error_code ec;
  const bool had_old = fs::exists(fs::symlink_status(final_dir_, ec));
  // One atomic step where the file system allows it: swap the new folder with the old one (or
  // move it into a free name), so that at every instant the complete old or new output is there.
  const unsigned flags = had_old ? RENAME_EXCHANGE : RENAME_NOREPLACE;
  if (::renameat2(AT_FDCWD, staging_dir_.c_str(), AT_FDCWD, final_dir_.c_str(), flags) == 0) {
    if (had_old) fs::remove_all(staging_dir_, ec);  // Now holds the old output.
  } else if (errno == EINVAL || errno == ENOSYS) {
    // No renameat2 flags on this file system: move the old folder aside first.
    const std::string old_dir = final_dir_ + ".old-" + std::to_string(::getpid());
    if (had_old) {
      fs::rename(final_dir_, old_dir, ec);
      if (ec) return Status::Error(final_dir_ + ": cannot move old output aside: " + ec.message());
    }
    fs::rename(staging_dir_, final_dir_, ec);
    if (ec) {
      std::error_code ignored;
      if (had_old) fs::rename(old_dir, final_dir_, ignored);
      return Status::Error(final_dir_ + ": cannot move staged output into place: " + ec.message());
    }
    if (had_old) fs::remove_all(old_dir, ec);
  } else {
    return Status::Error(final_dir_ + ": cannot move staged output into place: " + Errno());
  }
  committed_ = true;
  return SyncDirectory(ParentOf(final_dir_)).WithContext(final_dir_);
}

std::string Digest(const std::string& text) {
  uint64_t hash = 14695981039346656037ULL;  // FNV-1a 64-bit offset basis.
  for (unsigned char c : text) {
    hash ^= c;
    hash *= 1099511628211ULL;
  }
  char buf[17];
  std::snprintf(buf, sizeof(buf), "%016llx", static_cast<unsigned long long>(hash));
  return buf;
}

}  // namespace thinslab
