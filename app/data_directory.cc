// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/data_directory.h"

#include <cstdlib>
#include <filesystem>
#include <system_error>

#ifndef THINSLAB_SOURCE_DATA_DIR
#define THINSLAB_SOURCE_DATA_DIR "data"
#endif

namespace thinslab {

std::string DataDirectory() {
  if (const char* env = std::getenv("THINSLAB_DATA_DIR"); env != nullptr && *env != '\0') return env;
  std::error_code error;
  const std::filesystem::path exe = std::filesystem::read_symlink("/proc/self/exe", error);
  if (!error) {
    const std::filesystem::path installed = exe.parent_path().parent_path() / "share" / "thinslab" / "data";
    if (std::filesystem::is_directory(installed, error)) return installed.string();
  }
  return THINSLAB_SOURCE_DATA_DIR;
}

}  // namespace thinslab
