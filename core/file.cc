// SPDX-License-Identifier: Apache-2.0
#include "core/file.h"

#include <fcntl.h>
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
}  // namespace

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
  return Status::Ok();
}

Status ReadFileToString(const std::string& path, std::string* bytes) {
  std::error_code ec;
  if (!fs::is_regular_file(path, ec)) return Status::Error(path + ": file not found");
  std::ifstream in(path, std::ios::binary);
  if (!in) return Status::Error(path + ": cannot open for reading");
  std::ostringstream ss;
  ss << in.rdbuf();
  if (in.bad()) return Status::Error(path + ": read failed");
  *bytes = ss.str();
  return Status::Ok();
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

StagedDirectory::StagedDirectory(std::string final_dir) : final_dir_(std::move(final_dir)) {
  while (final_dir_.size() > 1 && final_dir_.back() == '/') final_dir_.pop_back();
  staging_dir_ = final_dir_ + ".partial-" + std::to_string(::getpid());
}

StagedDirectory::~StagedDirectory() {
  if (!committed_) {
    std::error_code ec;
    fs::remove_all(staging_dir_, ec);
  }
}

Status StagedDirectory::Init() {
  std::error_code ec;
  fs::remove_all(staging_dir_, ec);
  return CreateDirectories(staging_dir_);
}

Status StagedDirectory::Commit() {
  std::error_code ec;
  // rename() cannot replace a non-empty directory: move the old one aside first, so that
  // at every instant either the old or the new complete folder exists.
  const std::string old_dir = final_dir_ + ".old-" + std::to_string(::getpid());
  const bool had_old = fs::exists(final_dir_, ec);
  if (had_old) {
    fs::rename(final_dir_, old_dir, ec);
    if (ec) return Status::Error(final_dir_ + ": cannot move old output aside: " + ec.message());
  }
  fs::rename(staging_dir_, final_dir_, ec);
  if (ec) {
    if (had_old) fs::rename(old_dir, final_dir_, ec);
    return Status::Error(final_dir_ + ": cannot move staged output into place: " + ec.message());
  }
  if (had_old) fs::remove_all(old_dir, ec);
  committed_ = true;
  return Status::Ok();
}

}  // namespace thinslab
