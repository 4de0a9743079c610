// SPDX-License-Identifier: Apache-2.0
// The session check (issue #28, item 3): a quick assessment of a capture before the sample leaves
// the rig, so the operator can re-take what will not fit. `thinslab check CAPTURE` runs it, and
// `thinslab acquire` at the end of every session. docs/acquisition.md, "Session check", lists
// the rules and their thresholds.
//
// What is assessed, per light state (camera, kind, sample state, pattern, laser, dot):
//  - saturation in the state's shortest exposure (clipped there, clipped in every exposure; hot
//    pixels, saturated in the dark frame too, are left out);
//  - exposure: the peak (3 x 3 mean) signal in the longest exposure, in noise sigmas and as a
//    fraction of the range; dark frames that fill the range (a display's black glow, stray light);
//  - frames that differ from their neighbours: each frame against the next of the same state
//    (repeats and bracket neighbours, calib/frame_consistency.h): many pixels beyond the noise
//    = something moved; a brightness ratio off the one the other states show = a flicker;
//  - geometry: the laser spot standing out, on the board region the fit uses, and where the
//    manifest puts the beam; the dots of the all-dots frame
//    where the monitor geometry puts them; the board region the fits use lit by the projector;
//  - completeness: an acquisition that did not finish, failed frames.
// Each finding is a note, a warning (the fits run, with a weakness to know) or a reason to
// re-take; the verdict is "good", "usable" or "retake".
#pragma once

#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "thinslab/calib/frame_consistency.h"
#include "thinslab/core/status.h"

namespace thinslab {

struct CaptureCheckOptions {
  // Camera response: "" = SESSION/calib/response.json if present (as the fits), "linear", or a file.
  std::string response_path;
  // A state whose shortest exposure has more than this fraction of a frame's pixels saturated
  // lost them in every exposure: re-take. Fewer (but some): a warning.
  double max_saturated_fraction = 1e-4;
  // A lit state whose peak in its longest exposure is below this many noise sigmas shows nothing.
  double min_peak_sigmas = 20;
  // The brightest state of a kind peaks below this fraction of the range in its longest exposure:
  // a longer exposure would have gained signal (warning).
  double min_range_fraction = 0.1;
  // Dark frames whose 99th percentile exceeds this fraction of the range (warning; as `fit dmf`).
  double max_dark_fraction = 0.2;
  // Two frames of one state differ in more than this fraction of the compared pixels: re-take.
  double max_moved_fraction = 0.01;
  // A frame pair's brightness ratio off the other states' (or 1 for repeats) by more than this
  // (and 5 standard errors): re-take.
  double max_brightness_change = 0.03;
  // The laser spot further than this (or two camera pixels' footprint, if more) from where the
  // manifest's laser meets the board: warning [mm on the board].
  double max_spot_offset_mm = 1;
  // Fewer than this fraction of the dots in the camera's view found in the all-dots frame: warning.
  double min_dots_found_fraction = 0.9;
  // Less than this fraction of the fitted board region lit in the reference / flat frame: re-take.
  double min_lit_fraction = 0.5;
  int max_examples = 4;  // Frames or states named per finding.
  FramePairOptions pair;
  bool Check(std::string* error) const;
};

enum class CheckSeverity { kNote, kWarning, kRetake };
const char* CheckSeverityName(CheckSeverity severity);  // "note", "warning", "retake".

struct CheckFinding {
  CheckSeverity severity = CheckSeverity::kNote;
  // "incomplete", "failed_frames", "saturation", "exposure", "dark", "moved", "flicker",
  // "exposure_times", "beam", "dots", "board", "noise".
  std::string topic;
  std::string message;      // One sentence naming states, frames and numbers.
  std::vector<int> frames;  // Indices of example frames (up to max_examples).
};

// What was measured for the states of one kind (e.g. "dot, contaminated").
struct CheckedKind {
  std::string label;
  int states = 0, frames = 0, exposures = 0;
  double shortest_us = 0, longest_us = 0;
  int saturated_states = 0;  // Some pixel clipped in the shortest exposure.
  double worst_saturated_fraction = 0;
  int lit = 0;                    // States expected to show light (not dark).
  int underexposed_states = 0;    // Lit states peaking below min_peak_sigmas.
  double median_peak_sigmas = 0;  // Over lit states, in the longest exposure.
  double max_range_fraction = 0;  // Brightest state's peak / range in its longest exposure.
  int frame_pairs = 0;            // Pairs compared (measured).
  double worst_moved_fraction = 0;
  double worst_brightness_change = 0;  // |ratio / reference - 1|.
};

struct CaptureCheck {
  std::string capture;       // The folder.
  std::string session_kind;  // session.json "kind".
  int frames = 0;            // Frame records, failed included.
  std::string noise;         // FrameNoiseModel::Describe() of the first camera.
  std::string response;      // response.json used, "" = linear.
  std::vector<CheckedKind> kinds;
  // What the geometry checks measured, one line each ("board: ...", "beam: ...", "dots: ...").
  std::vector<std::string> geometry;
  std::vector<CheckFinding> findings;
  std::string verdict() const;   // "good" (no warning or re-take), "usable" (warnings), "retake".
  std::string Describe() const;  // For people: one line per kind, one per finding, the verdict.
  nlohmann::ordered_json ToJson() const;
};

// Reads the capture through its journal (a running or killed capture is checked as far as it
// got). Errors: the capture or a frame cannot be read, options invalid; what the frames show is
// in findings, never an error.
Status CheckCapture(const std::string& session_dir, const CaptureCheckOptions& options, CaptureCheck* check);

}  // namespace thinslab
