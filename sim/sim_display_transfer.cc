// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/sim_display_transfer.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sstream>

namespace thinslab {

Status SimDisplayTransfer::Check() const {
  if (curve == Curve::kPower && !(exponent > 0 && std::isfinite(exponent))) {
    std::ostringstream msg;
    msg << "SimDisplayTransfer::exponent = " << exponent << ". Violated constraint: > 0";
    return Status::Error(msg.str());
  }
  if (drive_bits < 0 || drive_bits > 16) {
    return Status::Error("SimDisplayTransfer::drive_bits = " + std::to_string(drive_bits) +
                         ". Violated constraint: 0 (none) or in [1, 16]");
  }
  return Status::Ok();
}

double SimDisplayTransfer::Emitted(double drive) const {
  const double d = std::clamp(drive, 0.0, 1.0);
  switch (curve) {
    case Curve::kLinear:
      return d;
    case Curve::kPower:
      return std::pow(d, exponent);
    case Curve::kSrgb:
      // IEC 61966-2-1 decoding (the linear toe keeps the slope finite at black).
      return d <= 0.04045 ? d / 12.92 : std::pow((d + 0.055) / 1.055, 2.4);
  }
  return d;
}

double SimDisplayTransfer::QuantizeDrive(double drive) const {
  const double d = std::clamp(drive, 0.0, 1.0);
  if (drive_bits == 0) return d;
  const double top = std::ldexp(1.0, drive_bits) - 1;
  // Rounded like the PatternWindow's lookup table (std::lround(255 * drive)).
  return std::round(d * top) / top;
}

double SimDisplayTransfer::LightForLevel(double level, const GammaTable& table) const {
  return Emitted(QuantizeDrive(table.DriveForLight(std::clamp(level, 0.0, 1.0))));
}

std::string SimDisplayTransfer::ToString() const {
  std::ostringstream out;
  switch (curve) {
    case Curve::kLinear:
      out << "linear";
      break;
    case Curve::kPower:
      out << "power:" << exponent;
      break;
    case Curve::kSrgb:
      out << "srgb";
      break;
  }
  if (drive_bits > 0) out << "/" << drive_bits << "bit";
  return out.str();
}

Status ParseSimDisplayTransfer(const std::string& text, const std::string& option, SimDisplayTransfer* out) {
  auto bad = [&](const std::string& why) {
    return Status::Error("option --" + option + " = '" + text + "': " + why +
                         " (expected linear, power:<exponent> or srgb, optionally followed by /<n>bit)");
  };
  SimDisplayTransfer t;
  std::string curve = text;
  const size_t slash = text.find('/');
  if (slash != std::string::npos) {
    curve = text.substr(0, slash);
    const std::string bits = text.substr(slash + 1);
    char* end = nullptr;
    const long n = std::strtol(bits.c_str(), &end, 10);
    if (end == bits.c_str() || std::string(end) != "bit") return bad("drive quantisation is not '<n>bit'");
    t.drive_bits = static_cast<int>(n);
  }
  if (curve == "linear") {
    t.curve = SimDisplayTransfer::Curve::kLinear;
  } else if (curve == "srgb") {
    t.curve = SimDisplayTransfer::Curve::kSrgb;
  } else if (curve.rfind("power:", 0) == 0) {
    t.curve = SimDisplayTransfer::Curve::kPower;
    const std::string e = curve.substr(6);
    char* end = nullptr;
    t.exponent = std::strtod(e.c_str(), &end);
    if (e.empty() || *end != '\0') return bad("exponent is not a number");
  } else {
    return bad("unknown curve '" + curve + "'");
  }
  const Status checked = t.Check();
  if (!checked.ok()) return bad(checked.message());
  *out = t;
  return Status::Ok();
}

}  // namespace thinslab
