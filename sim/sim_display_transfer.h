// SPDX-License-Identifier: Apache-2.0
// The emission curve of a simulated display (docs/drivers.md, "Gamma"): what a real monitor or
// projector does between the drive level the computer sends and the light that leaves the
// screen, so that measuring the display gamma in simulation is not measuring an identity.
//   drive    = Q(T^-1(level))   T the gamma table the driver applies (identity by default),
//                               Q the quantisation of the drive to drive_bits (8 for the
//                               PatternWindow's 8-bit texture; 0 = none)
//   emitted  = C(drive)         C the display's own curve, normalised C(0) = 0, C(1) = 1
// Light at drive 0 (an LCD's leakage, a CRT's black level) is not part of C: it is the
// simulated monitor's black_radiance, which every pixel emits on top.
#pragma once

#include <string>

#include "thinslab/core/status.h"
#include "thinslab/drivers/display_gamma.h"

namespace thinslab {

struct SimDisplayTransfer {
  enum class Curve {
    kLinear,  // C(d) = d.
    kPower,   // C(d) = d^exponent (a monitor set to "gamma 2.2").
    kSrgb,    // IEC 61966-2-1: d / 12.92 for d <= 0.04045, else ((d + 0.055) / 1.055)^2.4.
  };
  Curve curve = Curve::kLinear;
  double exponent = 2.2;  // kPower only; > 0.
  int drive_bits = 0;     // Drive quantisation: 0 (none) or 1..16 bits.

  // Errors name SimDisplayTransfer::<field>.
  Status Check() const;
  // C(drive), drive clamped to [0, 1].
  double Emitted(double drive) const;
  // Q(drive).
  double QuantizeDrive(double drive) const;
  // The light a pixel asked to show `level` emits, through `table`: C(Q(T^-1(level))).
  double LightForLevel(double level, const GammaTable& table) const;
  // True if LightForLevel is the identity for every table-free level (linear, unquantised).
  bool IsIdentity() const { return curve == Curve::kLinear && drive_bits == 0; }
  // "linear", "power:2.2", "srgb", with "/8bit" when quantised: the inverse of Parse.
  std::string ToString() const;
};

// Parses "linear", "power:<exponent>" or "srgb", optionally followed by "/<n>bit" (drive
// quantisation), e.g. "power:2.2/8bit". Errors name `option` and the text.
Status ParseSimDisplayTransfer(const std::string& text, const std::string& option, SimDisplayTransfer* out);

}  // namespace thinslab
