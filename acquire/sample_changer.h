// SPDX-License-Identifier: Apache-2.0
#pragma once

#include <functional>
#include <string>

#include "thinslab/core/status.h"

namespace thinslab {

// Moves the sample between "clean", "contaminated" and "none" (an operator prompt at the rig,
// a state switch in the simulator).
using SampleChanger = std::function<Status(const std::string& sample_state)>;

}  // namespace thinslab
