// SPDX-License-Identifier: Apache-2.0
// The slice matrix of a dot scan on disk, for captures whose matrix does not fit the memory
// budget (issue #29, `fit dmf --max-memory`). The image processing produces one dot's column at a
// time (every point of the grid, fit/dmf_processing.h) and the fit reads bands of consecutive
// points; the file is dot-major, so a column is one sequential write and a band one read per
// dot. The band in memory is point-major like DmfSliceSet::value, so a streamed fit runs the
// same per-point code on the same numbers.
//
// The file is created unlinked (O_TMPFILE): nothing is left on disk whatever ends the process.
#pragma once

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

#include "thinslab/core/status.h"

namespace thinslab {

// Floats in an unlinked file (O_TMPFILE, else a named file unlinked at once), read and written
// at float offsets.
class SpillFile {
 public:
  // Room for `num_floats` floats in a new unlinked file in `dir`; `what` names it in errors.
  static Status Create(const std::string& dir, size_t num_floats, const std::string& what,
                       std::unique_ptr<SpillFile>* out);
  ~SpillFile();
  SpillFile(const SpillFile&) = delete;
  SpillFile& operator=(const SpillFile&) = delete;
  Status Read(size_t offset_floats, size_t count, float* out) const;
  Status Write(size_t offset_floats, size_t count, const float* in);

 private:
  SpillFile() = default;
  int fd_ = -1;
  std::string dir_, what_;
};

class DmfSliceSpill {
 public:
  // An empty matrix of num_points x num_dots (value and sigma) in an unlinked file in `dir`,
  // read back in bands of at most `band_points` points.
  static Status Create(const std::string& dir, int num_points, int num_dots, int band_points,
                       std::unique_ptr<DmfSliceSpill>* out);
  ~DmfSliceSpill();
  DmfSliceSpill(const DmfSliceSpill&) = delete;
  DmfSliceSpill& operator=(const DmfSliceSpill&) = delete;

  // Dot `dot`'s values and sigmas at every point (num_points floats each).
  Status WriteColumn(int dot, const float* value, const float* sigma);
  // Points [first, first + count) into memory, point-major; count <= band_points().
  Status LoadBand(int first, int count);

  int num_points() const { return num_points_; }
  int num_dots() const { return num_dots_; }
  int band_points() const { return band_points_; }
  int band_first() const { return band_first_; }
  int band_count() const { return band_count_; }
  bool Loaded(int p) const { return p >= band_first_ && p < band_first_ + band_count_; }
  // The loaded point p's num_dots values / sigmas (CHECKs that p is loaded).
  const float* Values(int p) const;
  const float* Sigmas(int p) const;
  // Bytes of the band in memory (value and sigma, and the column buffer of LoadBand).
  size_t BandBytes() const;
  const std::string& dir() const { return dir_; }

 private:
  DmfSliceSpill() = default;

  std::unique_ptr<SpillFile> file_;
  std::string dir_;
  int num_points_ = 0, num_dots_ = 0, band_points_ = 0;
  int band_first_ = 0, band_count_ = 0;
  std::vector<float> value_, sigma_, column_;
};

}  // namespace thinslab
