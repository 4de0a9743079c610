// SPDX-License-Identifier: Apache-2.0
// An exposure or duration in microseconds as people read it: "850 us", "11.77 ms", "9.412 s".
#pragma once

#include <iomanip>
#include <sstream>
#include <string>

namespace thinslab {

inline std::string DurationText(double us) {
  std::ostringstream s;
  s << std::setprecision(4);
  if (us >= 1e6) {
    s << us / 1e6 << " s";
  } else if (us >= 1e3) {
    s << us / 1e3 << " ms";
  } else {
    s << us << " us";
  }
  return s.str();
}

}  // namespace thinslab
