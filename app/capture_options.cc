// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/capture_options.h"

#include "thinslab/app/option_parser.h"

namespace thinslab {

void AddIncompleteCaptureOption(OptionParser* parser, bool* allow_incomplete) {
  parser->AddBool("allow-incomplete", allow_incomplete,
                  "process a capture whose acquisition did not complete (killed, failed or interrupted)");
}

}  // namespace thinslab
