// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/command_progress.h"

#include <unistd.h>

#include <cstdio>
#include <memory>
#include <utility>

#include "thinslab/app/verbosity.h"

namespace thinslab {
namespace {

ProgressCallback& Override() {
  static ProgressCallback callback;
  return callback;
}

bool PrintToTerminal(const ProgressUpdate& u) {
  const double percent = u.total > 0 ? 100.0 * static_cast<double>(u.done) / static_cast<double>(u.total) : 0;
  std::fprintf(stderr, "\r%s: %lld/%lld (%.0f %%), %.0f s", u.stage.c_str(), static_cast<long long>(u.done),
               static_cast<long long>(u.total), percent, u.elapsed_s);
  if (u.eta_s >= 0 && u.done < u.total) std::fprintf(stderr, ", ETA %.0f s", u.eta_s);
  std::fprintf(stderr, "\033[K%s", u.done >= u.total ? "\n" : "");
  std::fflush(stderr);
  return true;
}

// --verbose into a log file: a line every few seconds instead of a rewritten terminal line.
ProgressCallback PrintLines() {
  auto last_s = std::make_shared<double>(-1e9);
  return [last_s](const ProgressUpdate& u) {
    if (u.done < u.total && u.elapsed_s - *last_s < 5) return true;
    *last_s = u.elapsed_s;
    std::fprintf(stderr, "%s: %lld/%lld, %.0f s", u.stage.c_str(), static_cast<long long>(u.done),
                 static_cast<long long>(u.total), u.elapsed_s);
    if (u.eta_s >= 0 && u.done < u.total) std::fprintf(stderr, ", ETA %.0f s", u.eta_s);
    std::fprintf(stderr, "\n");
    return true;
  };
}

}  // namespace

ProgressCallback CommandProgress() {
  if (Override()) return Override();
  if (QuietRun()) return {};
  if (isatty(STDERR_FILENO)) return PrintToTerminal;
  if (VerboseRun()) return PrintLines();
  return {};
}

void SetCommandProgress(ProgressCallback callback) { Override() = std::move(callback); }

}  // namespace thinslab
