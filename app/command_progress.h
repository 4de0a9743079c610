// SPDX-License-Identifier: Apache-2.0
// The progress callback the commands hand to the library's long operations (core/progress.h):
// the one SetCommandProgress installed (the Python module's), else, when stderr is a terminal,
// one that redraws "<stage>: done/total (percent), elapsed, ETA" on stderr; else none (logs and
// tests see no progress lines).
#pragma once

#include "thinslab/core/progress.h"

namespace thinslab {

ProgressCallback CommandProgress();

// Installs `callback` for the commands run next; an empty one restores the default.
void SetCommandProgress(ProgressCallback callback);

}  // namespace thinslab
