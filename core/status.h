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

// The status variable is named per expansion, so that a lambda inside `expr` may use the macro too.
#define THINSLAB_RETURN_IF_ERROR(expr) THINSLAB_RETURN_IF_ERROR_IMPL_(expr, THINSLAB_STATUS_NAME_(__COUNTER__))
#define THINSLAB_STATUS_NAME_(n) THINSLAB_STATUS_CONCAT_(status_, n)
#define THINSLAB_STATUS_CONCAT_(a, b) a##b
#define THINSLAB_RETURN_IF_ERROR_IMPL_(expr, name) \
  do {                                             \
    ::thinslab::Status name = (expr);              \
    if (!name.ok()) return name;                   \
  } while (0)

}  // namespace thinslab
