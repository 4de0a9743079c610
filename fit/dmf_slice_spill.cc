// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/dmf_slice_spill.h"

#include <fcntl.h>
#include <glog/logging.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace thinslab {
namespace {

std::string Errno() { return std::strerror(errno); }

}  // namespace

Status SpillFile::Create(const std::string& dir, size_t num_floats, const std::string& what,
                         std::unique_ptr<SpillFile>* out) {
  std::unique_ptr<SpillFile> file(new SpillFile());
  file->dir_ = dir;
  file->what_ = what;
  file->fd_ = open(dir.c_str(), O_TMPFILE | O_RDWR | O_CLOEXEC, 0600);
  if (file->fd_ < 0 && (errno == EOPNOTSUPP || errno == EISDIR || errno == EINVAL)) {
    // File systems without O_TMPFILE: a named file, unlinked at once.
    std::string path = dir + "/.thinslab_spill_XXXXXX";
    file->fd_ = mkstemp(path.data());
    if (file->fd_ >= 0) unlink(path.c_str());
  }
  if (file->fd_ < 0) return Status::Error(dir + ": cannot create the " + what + " file: " + Errno());
  const off_t bytes = static_cast<off_t>(num_floats * sizeof(float));
  const int rc = bytes > 0 ? posix_fallocate(file->fd_, 0, bytes) : 0;
  if (rc != 0) {
    char size[64];
    std::snprintf(size, sizeof(size), "%.2f GiB", bytes / double(1u << 30));
    return Status::Error(dir + ": cannot reserve " + size + " for the " + what +
                         " file (--spill-dir): " + std::strerror(rc));
  }
  *out = std::move(file);
  return Status::Ok();
}

SpillFile::~SpillFile() {
  if (fd_ >= 0) close(fd_);
}

Status SpillFile::Read(size_t offset_floats, size_t count, float* out) const {
  char* dst = reinterpret_cast<char*>(out);
  size_t left = count * sizeof(float);
  off_t at = static_cast<off_t>(offset_floats * sizeof(float));
  while (left > 0) {
    const ssize_t n = pread(fd_, dst, left, at);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return Status::Error(dir_ + ": reading the " + what_ + " file: " + (n < 0 ? Errno() : "short read"));
    dst += n;
    at += n;
    left -= static_cast<size_t>(n);
  }
  return Status::Ok();
}

Status SpillFile::Write(size_t offset_floats, size_t count, const float* in) {
  const char* src = reinterpret_cast<const char*>(in);
  size_t left = count * sizeof(float);
  off_t at = static_cast<off_t>(offset_floats * sizeof(float));
  while (left > 0) {
    const ssize_t n = pwrite(fd_, src, left, at);
    if (n < 0 && errno == EINTR) continue;
    if (n <= 0) return Status::Error(dir_ + ": writing the " + what_ + " file: " + (n < 0 ? Errno() : "no space"));
    src += n;
    at += n;
    left -= static_cast<size_t>(n);
  }
  return Status::Ok();
}

Status DmfSliceSpill::Create(const std::string& dir, int num_points, int num_dots, int band_points,
                             std::unique_ptr<DmfSliceSpill>* out) {
  if (num_points < 1 || num_dots < 1 || band_points < 1) {
    return Status::Error("slice spill: needs points, dots and a band size >= 1");
  }
  std::unique_ptr<DmfSliceSpill> spill(new DmfSliceSpill());
  spill->dir_ = dir;
  spill->num_points_ = num_points;
  spill->num_dots_ = num_dots;
  spill->band_points_ = std::min(band_points, num_points);
  THINSLAB_RETURN_IF_ERROR(
      SpillFile::Create(dir, static_cast<size_t>(2) * num_points * num_dots, "slice spill", &spill->file_));
  *out = std::move(spill);
  return Status::Ok();
}

DmfSliceSpill::~DmfSliceSpill() = default;

Status DmfSliceSpill::WriteColumn(int dot, const float* value, const float* sigma) {
  CHECK(dot >= 0 && dot < num_dots_);
  const size_t column = static_cast<size_t>(dot) * num_points_;
  const size_t sigma_start = static_cast<size_t>(num_points_) * num_dots_;
  THINSLAB_RETURN_IF_ERROR(file_->Write(column, num_points_, value));
  return file_->Write(sigma_start + column, num_points_, sigma);
}

Status DmfSliceSpill::LoadBand(int first, int count) {
  CHECK(first >= 0 && count >= 0 && count <= band_points_ && first + count <= num_points_);
  if (first == band_first_ && count == band_count_ && !value_.empty()) return Status::Ok();
  band_first_ = first;
  band_count_ = 0;  // Not loaded until the reads succeed.
  const size_t nd = num_dots_;
  value_.resize(static_cast<size_t>(count) * nd);
  sigma_.resize(value_.size());
  // kColumns dots' columns at a time, so that each point's run of them is one cache line written.
  constexpr size_t kColumns = 16;
  column_.resize(kColumns * count);
  const size_t sigma_start = static_cast<size_t>(num_points_) * num_dots_;
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<float>& band = pass == 0 ? value_ : sigma_;
    for (size_t q0 = 0; q0 < nd; q0 += kColumns) {
      const size_t columns = std::min(kColumns, nd - q0);
      for (size_t c = 0; c < columns; ++c) {
        THINSLAB_RETURN_IF_ERROR(file_->Read((pass == 0 ? 0 : sigma_start) + (q0 + c) * num_points_ + first, count,
                                             column_.data() + c * count));
      }
      for (int k = 0; k < count; ++k) {
        float* row = band.data() + k * nd + q0;
        for (size_t c = 0; c < columns; ++c) row[c] = column_[c * count + k];
      }
    }
  }
  band_count_ = count;
  return Status::Ok();
}

const float* DmfSliceSpill::Values(int p) const {
  CHECK(Loaded(p)) << "slice spill: point " << p << " is not in the loaded band [" << band_first_ << ", "
                   << band_first_ + band_count_ << ")";
  return value_.data() + static_cast<size_t>(p - band_first_) * num_dots_;
}

const float* DmfSliceSpill::Sigmas(int p) const {
  CHECK(Loaded(p)) << "slice spill: point " << p << " is not in the loaded band";
  return sigma_.data() + static_cast<size_t>(p - band_first_) * num_dots_;
}

size_t DmfSliceSpill::BandBytes() const {
  return (2 * static_cast<size_t>(band_points_) * num_dots_ + 16 * static_cast<size_t>(band_points_)) * sizeof(float);
}

}  // namespace thinslab
