// SPDX-License-Identifier: Apache-2.0
// Status: the error type that crosses library boundaries (no exceptions do).
// Messages name the file:field, Struct::field or device that is wrong.
#pragma once

#include <string>
#include <utility>

namespace thinslab {

class Status {
 public:
  Status() = default;
  static Status Ok() { return Status(); }
  static Status Error(std::string message) { return Status(std::move(message)); }

  bool ok() const { return !failed_; }
  const std::string& message() const { return message_; }

  // Prefixes context, e.g. the file a nested reader was reading.
  Status WithContext(const std::string& context) const {
    if (ok()) return *this;
    return Status(context + ": " + message_);
  }

 private:
  explicit Status(std::string message) : failed_(true), message_(std::move(message)) {}
  bool failed_ = false;
  std::string message_;
};

#define THINSLAB_RETURN_IF_ERROR(expr)      \
  do {                                      \
    ::thinslab::Status status_ = (expr);    \
    if (!status_.ok()) return status_;      \
  } while (0)

}  // namespace thinslab
