// SPDX-License-Identifier: Apache-2.0
// Display gamma tables (docs/drivers.md, "Gamma"; file format in docs/format.md): the measured
// relation between the drive level a display is given and the light it emits. PatternWindow
// applies the inverse table on the way to the screen; the simulated monitor (sim/) uses it the
// same way; `thinslab calib gamma` fits one from a "display_gamma" session. No device library
// here, so sim/ and calib/ use it without SDL.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include "thinslab/core/status.h"

namespace thinslab {

// Display gamma: monotonic table of (drive level, relative emitted light) pairs, both in [0, 1],
// first (0, 0), last (1, 1). Emitted(drive) is the piecewise-linear interpolation.
struct GammaTable {
  std::vector<std::pair<double, double>> drive_to_light;
  // Drive level in [0, 1] that emits `light` in [0, 1] (inverse interpolation).
  double DriveForLight(double light) const;
  double LightForDrive(double drive) const;
};

// Identity table {(0,0), (1,1)}.
GammaTable IdentityGammaTable();
// File format (docs/drivers.md): text, '#' comments, one "drive light" pair per line.
Status ReadGammaTable(const std::string& path, GammaTable* table);
// Atomic (core/file.h). `comment` (provenance: who measured it, from what) becomes '#' lines.
Status WriteGammaTable(const std::string& path, const GammaTable& table, const std::string& comment = "");

// Fits a gamma table from measured (drive level, camera signal) pairs taken by showing
// "flat:<level>" patterns (GammaMeasurementPatterns) and recording a black-subtracted camera
// mean. Model: signal = offset + scale * L(drive) with L monotonic, L(0) = 0, L(1) = 1. Repeated
// levels are averaged, the result is made monotonic by isotonic regression (pool adjacent
// violators) and normalised by its end points. Errors: fewer than 3 distinct levels, levels
// outside [0, 1], no 0 or no 1 level, non-finite values, signal(1) <= signal(0).
Status FitGammaTable(const std::vector<std::pair<double, double>>& level_signal, GammaTable* table);
// The flat-level pattern ids of a gamma measurement: "flat:0", ..., "flat:1" with `steps`+1
// evenly spaced drive levels.
std::vector<std::string> GammaMeasurementPatterns(int steps);

// Compact one-line form "d:l,d:l,..." (6 significant digits) for plans and manifests.
std::string GammaTableCompactText(const GammaTable& table);

}  // namespace thinslab
