// SPDX-License-Identifier: Apache-2.0
// Peak resident memory of this process, for summaries and benchmarks (Linux /proc), and the
// check that refuses a job before it allocates more than the machine has (issue #22).
#pragma once

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <string>

#include "thinslab/core/status.h"

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

// The memory this process may use, in bytes: the machine's (MemTotal) or, where lower, the
// cgroup limit of its container; 0 where neither can be read.
inline double UsableMemoryBytes() {
  double total = 0;
  std::ifstream meminfo("/proc/meminfo");
  std::string line;
  while (std::getline(meminfo, line)) {
    if (line.rfind("MemTotal:", 0) == 0) total = std::atof(line.c_str() + 9) * 1024.0;
  }
  std::ifstream cgroup("/sys/fs/cgroup/memory.max");
  std::string limit;
  if (cgroup >> limit && limit != "max") {
    const double bytes = std::atof(limit.c_str());
    if (bytes > 0) total = total > 0 ? std::min(total, bytes) : bytes;
  }
  return total;
}

// Refuses `bytes` of memory for `what` when it exceeds what the machine has, with the need
// and the limit in the message; an allocation that could never succeed is an error up
// front, not std::bad_alloc after minutes (or the kernel's OOM killer).
inline Status CheckMemoryNeed(double bytes, const std::string& what) {
  const double usable = UsableMemoryBytes();
  if (usable <= 0 || bytes <= usable) return Status::Ok();
  char text[160];
  std::snprintf(text, sizeof(text), " needs %.1f GiB of memory; this machine has %.1f GiB", bytes / (1u << 30),
                usable / (1u << 30));
  return Status::Error(what + text);
}

}  // namespace thinslab
