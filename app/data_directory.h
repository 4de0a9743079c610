// SPDX-License-Identifier: Apache-2.0
// Where the CLI finds its bundled data (demo pattern, contamination prototypes): the
// THINSLAB_DATA_DIR environment variable; else, for an installed thinslab, share/thinslab/data
// beside the executable's bin/ (found from /proc/self/exe, so a moved install tree still works);
// else the source tree's data/ the build came from.
#pragma once

#include <string>

namespace thinslab {

std::string DataDirectory();

}  // namespace thinslab
