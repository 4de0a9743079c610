// SPDX-License-Identifier: Apache-2.0
// Simulated projector that can show a flat field ("flat") or nothing (""), for the rigs whose
// only pattern is a uniform illumination (shadow maps, board flat fields).
#pragma once

#include <functional>
#include <string>
#include <utility>

#include "thinslab/drivers/display.h"

namespace thinslab {

class SimFlatProjector : public Projector {
 public:
  // `set_on` receives true for "flat" and false for "" (off).
  SimFlatProjector(std::string device_name, std::function<void(bool)> set_on)
      : device_name_(std::move(device_name)), set_on_(std::move(set_on)) {}

  Status ShowPattern(const std::string& pattern) override {
    if (!pattern.empty() && pattern != "flat") {
      return Status::Error(device_name_ + " (sim): unknown pattern '" + pattern + "' (known: flat, \"\" for off)");
    }
    set_on_(pattern == "flat");
    return Status::Ok();
  }

 private:
  std::string device_name_;
  std::function<void(bool)> set_on_;
};

}  // namespace thinslab
