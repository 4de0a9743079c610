// SPDX-License-Identifier: Apache-2.0
// Placeholder until `thinslab synth` lands (issue #9).
#include <iostream>

#include "app/commands.h"

namespace thinslab {

int RunSynth(int, char**) {
  std::cerr << "thinslab synth: not implemented yet\n";
  return 2;
}

}  // namespace thinslab
