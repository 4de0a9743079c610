// SPDX-License-Identifier: Apache-2.0
// camera_options ADDRESS: checks the Aravis camera options a capture script would use (links
// thinslab::devices; opens no device).
#include <iostream>

#include "thinslab/drivers/aravis_camera.h"

int main(int argc, char** argv) {
  thinslab::AravisCameraOptions options;
  options.address = argc > 1 ? argv[1] : "";
  std::string error;
  if (!options.Check(&error)) {
    std::cerr << "error: " << error << "\n";
    return 1;
  }
  std::cout << "camera " << options.address << ": options ok\n";
  return 0;
}
