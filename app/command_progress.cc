// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/command_progress.h"

#include <unistd.h>

#include <cstdio>
#include <memory>
#include <string>
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

}  // namespace

// --verbose into a log file: a line every few seconds instead of a rewritten terminal line. The
// interval is kept per stage (each stage's elapsed time starts at 0): a new stage name, or the
// same stage started again, starts over.
ProgressCallback ProgressLines(std::FILE* out, double interval_s) {
  struct Last {
    std::string stage;
    double elapsed_s = -1e300;
  };
  auto last = std::make_shared<Last>();
  return [last, out, interval_s](const ProgressUpdate& u) {
    if (u.stage != last->stage || u.elapsed_s < last->elapsed_s) *last = Last{u.stage, -1e300};
    if (u.done < u.total && u.elapsed_s - last->elapsed_s < interval_s) return true;
    last->elapsed_s = u.elapsed_s;
    std::fprintf(out, "%s: %lld/%lld, %.0f s", u.stage.c_str(), static_cast<long long>(u.done),
                 static_cast<long long>(u.total), u.elapsed_s);
    if (u.eta_s >= 0 && u.done < u.total) std::fprintf(out, ", ETA %.0f s", u.eta_s);
    std::fprintf(out, "\n");
    return true;
  };
}

ProgressCallback CommandProgress() {
  if (Override()) return Override();
  if (QuietRun()) return {};
  if (isatty(STDERR_FILENO)) return PrintToTerminal;
  if (VerboseRun()) return ProgressLines(stderr);
  return {};
}

void SetCommandProgress(ProgressCallback callback) { Override() = std::move(callback); }

}  // namespace thinslab
