// SPDX-License-Identifier: Apache-2.0
// ByteWriter / ByteReader: values packed into a byte string and read back in the same order, for
// results one process of a group sends to the others (core/process_group.h). Native byte order:
// the processes of one run are the same binary on the same kind of machine.
#pragma once

#include <cstdint>
#include <cstring>
#include <string>
#include <type_traits>
#include <vector>

namespace thinslab {

class ByteWriter {
 public:
  template <typename T>
  void Put(const T& value) {
    static_assert(std::is_trivially_copyable_v<T>, "ByteWriter::Put takes plain values");
    bytes_.append(reinterpret_cast<const char*>(&value), sizeof(T));
  }
  template <typename T>
  void PutVector(const std::vector<T>& values) {
    static_assert(std::is_trivially_copyable_v<T>, "ByteWriter::PutVector takes vectors of plain values");
    Put<uint64_t>(values.size());
    if (!values.empty()) bytes_.append(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(T));
  }
  void PutString(const std::string& s) {
    Put<uint64_t>(s.size());
    bytes_.append(s);
  }
  const std::string& bytes() const { return bytes_; }
  std::string Release() { return std::move(bytes_); }

 private:
  std::string bytes_;
};

// Every Get returns false (and leaves the value alone) once the bytes run out: a message cut
// short or read with another layout.
class ByteReader {
 public:
  explicit ByteReader(const std::string& bytes) : bytes_(bytes) {}
  template <typename T>
  bool Get(T* value) {
    static_assert(std::is_trivially_copyable_v<T>, "ByteReader::Get takes plain values");
    if (bytes_.size() - pos_ < sizeof(T)) return false;
    std::memcpy(value, bytes_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return true;
  }
  template <typename T>
  bool GetVector(std::vector<T>* values) {
    uint64_t n = 0;
    if (!Get(&n) || n > (bytes_.size() - pos_) / sizeof(T)) return false;
    values->resize(n);
    if (n > 0) std::memcpy(values->data(), bytes_.data() + pos_, n * sizeof(T));  // data() may be null when empty.
    pos_ += n * sizeof(T);
    return true;
  }
  bool GetString(std::string* s) {
    uint64_t n = 0;
    if (!Get(&n) || n > bytes_.size() - pos_) return false;
    s->assign(bytes_, pos_, n);
    pos_ += n;
    return true;
  }
  bool at_end() const { return pos_ == bytes_.size(); }

 private:
  const std::string& bytes_;
  size_t pos_ = 0;
};

}  // namespace thinslab
