// SPDX-License-Identifier: Apache-2.0
// The progress callback the commands hand to the library's long operations (core/progress.h):
// the one SetCommandProgress installed (the Python module's), else, when stderr is a terminal,
// one that redraws "<stage>: done/total (percent), elapsed, ETA" on stderr; with --verbose into
// a log, ProgressLines on stderr; else none (logs and tests see no progress lines).
#pragma once

#include <cstdio>

#include "thinslab/core/progress.h"

namespace thinslab {

ProgressCallback CommandProgress();

// "<stage>: done/total, elapsed[, ETA]" lines on `out`: each stage's first and last report and
// one every `interval_s` of the stage's elapsed time in between.
ProgressCallback ProgressLines(std::FILE* out, double interval_s = 5);

// Installs `callback` for the commands run next; an empty one restores the default.
void SetCommandProgress(ProgressCallback callback);

}  // namespace thinslab
