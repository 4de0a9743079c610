// SPDX-License-Identifier: Apache-2.0
// Placeholder until `thinslab acquire` lands (issue #7).
#include <iostream>

#include "app/commands.h"

namespace thinslab {

int RunAcquire(int, char**) {
  std::cerr << "thinslab acquire: not implemented yet\n";
  return 2;
}

}  // namespace thinslab
