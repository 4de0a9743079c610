// SPDX-License-Identifier: Apache-2.0
// report.html of an output folder (issue #26 item 5): one self-contained page a person opens in
// any browser, made from the folder's own files: the result and message, the warnings, the key
// figures of summary.json, every picture (maps with their legends, charts with the CSV beside
// them), the provenance with the command that made the folder and the one that repeats it, and
// options.ini. Images are embedded (data: URIs), so the page can be mailed or archived alone.
#pragma once

#include <string>

#include "thinslab/core/status.h"

namespace thinslab {

// `folder`: where the files are now (a staging folder); `final_folder`: where they will be (the
// paths the page shows). Writes folder/report.html atomically.
Status WriteFolderReport(const std::string& folder, const std::string& final_folder, const std::string& title);

}  // namespace thinslab
