// SPDX-License-Identifier: Apache-2.0
// OpenCV's exception text ("OpenCV(4.6.0) /build/.../loadsave.cpp:77: error: (-215:Assertion
// failed) !_src.empty() in function 'imdecode_'") is not a message for a user: messages carry
// its description only, after thinslab's own words for what failed.
#pragma once

#include <exception>
#include <opencv2/core.hpp>
#include <string>

namespace thinslab {

inline std::string OpenCvErrorText(const std::exception& e) {
  if (const auto* cv_error = dynamic_cast<const cv::Exception*>(&e)) {
    return cv_error->code == cv::Error::StsAssert ? "input rejected by OpenCV" : cv_error->err;
  }
  return e.what();
}

}  // namespace thinslab
