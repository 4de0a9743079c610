// SPDX-License-Identifier: Apache-2.0
// Peak resident memory of this process, for summaries and benchmarks (Linux /proc).
#pragma once

#include <cstdlib>
#include <fstream>
#include <string>

namespace thinslab {

// VmHWM of /proc/self/status in MiB; 0 where it cannot be read.
inline double PeakResidentMemoryMiB() {
  std::ifstream status("/proc/self/status");
  std::string line;
  while (std::getline(status, line)) {
    if (line.rfind("VmHWM:", 0) == 0) return std::atof(line.c_str() + 6) / 1024.0;
  }
  return 0;
}

}  // namespace thinslab
