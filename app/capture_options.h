// SPDX-License-Identifier: Apache-2.0
// The --allow-incomplete option of the fit and calibration commands (pipeline/capture_reading.h
// reads the capture).
#pragma once

#include "thinslab/pipeline/capture_reading.h"

namespace thinslab {

class OptionParser;

// --allow-incomplete: process a capture that was killed, failed or interrupted (the frames it
// has), instead of refusing it.
void AddIncompleteCaptureOption(OptionParser* parser, bool* allow_incomplete);

}  // namespace thinslab
