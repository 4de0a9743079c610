// SPDX-License-Identifier: Apache-2.0
// Image quilting (Efros and Freeman 2001, "Image Quilting for Texture Synthesis and
// Transfer", SIGGRAPH), which Gu et al. 2007 (Sec. 5.3) use to synthesize dust layers from a
// measured dust tau map. Square patches are laid in raster order with an overlap; each patch
// is chosen among source positions whose sum of squared differences (SSD) over the overlap
// is within a tolerance of the best, and is joined to its neighbours along the minimum-error
// boundary cut, found by dynamic programming over the squared-difference surface. Not in the
// paper: by default the draw among the qualifying candidates is tilted to keep the amount of
// dust (QuiltingSelection::kMassMatched; docs/models/contamination_synthesis.md, Sec. 2).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

// How a patch is chosen among the candidates whose overlap SSD is within tolerance.
enum class QuiltingSelection {
  kSsd,          // Efros-Freeman: uniformly. Biased toward low-dust overlaps on sparse textures.
  kMassMatched,  // Not in Efros-Freeman: tilted so the expected added tau mass is the source's.
};

struct QuiltingOptions {
  int patch_px = 32;    // Patch side [px]; Efros-Freeman: larger than the texture's features.
  int overlap_px = 10;  // Overlap between neighbouring patches [px], in [1, patch_px / 2].
  // A candidate qualifies when its overlap SSD <= (1 + tolerance) * best SSD (Efros-Freeman
  // use 0.1); one qualifying candidate is drawn uniformly.
  double tolerance = 0.1;
  // Not in Efros-Freeman: an absolute floor on the qualifying error, this share of the source
  // variance per overlap pixel. Without it a sparse texture (dust on clean glass) degenerates:
  // the best overlap error is 0 wherever the overlap is clean, only clean-bordered patches
  // qualify, and the output loses specks (measured: -20% mean tau). [0, 10].
  double variance_tolerance = 0.05;
  // Candidate source positions examined per patch: all of them when the source has at most
  // this many, else this many drawn uniformly (seeded). 0 = always all. Bounds the cost of
  // large outputs (bench/synth_bench.cc).
  int max_candidates = 1024;
  // Not in Efros-Freeman: afterwards, give the output the source's value histogram
  // (SpecifyHistogram below: every output value is a source value, the spatial order is kept
  // and clean pixels, tau = 0, stay exactly 0). Even with the mass-matched selection one raw
  // output's mean tau is off by up to 6% and its KS distance up to 0.07 (measured,
  // docs/models/contamination_synthesis.md, Sec. 4); the remap brings both to 0.05% and 0.03.
  bool match_histogram = true;
  // kMassMatched (docs/models/contamination_synthesis.md, Sec. 2): the qualifying candidates
  // are drawn with weights e^{lambda u} (u: the tau mass a candidate adds after its boundary
  // cut, minus the target, over its spread in the qualifying set), lambda chosen so the
  // expected u is 0: the distribution closest to Efros-Freeman's uniform draw (in KL
  // divergence) that adds, on average, the source's mean tau per new pixel. kSsd loses 11% of
  // the dust on average (measured, Sec. 4).
  QuiltingSelection selection = QuiltingSelection::kMassMatched;
  // kMassMatched: |lambda| limit, per unit of spread, (0, 20]. Larger matches the mass more
  // closely but concentrates the draw on few heavy patches (autocorrelation; measured, Sec. 4).
  double max_tilt = 3;
  // kMassMatched: share of the canvas's running mass deficit (source mean times pixels
  // written, minus the tau written) added to each patch's target, [0, 10]. 0 makes each
  // draw unbiased on its own; 1 also steers the sum, so one output's mean tau stays near the
  // source's (without it, 256^2 outputs scatter by +-15%).
  double mass_feedback = 1;
  uint64_t seed = 1;

  bool Check(std::string* error) const;
};

struct QuiltingSummary {
  int patches = 0;
  int64_t candidates_evaluated = 0;
  // Shares of exact zeros (clean pixels) in the source and in the quilted output before
  // QuiltingOptions::match_histogram. An output cleaner than its source keeps its extra clean
  // area (SpecifyHistogram), so its histogram and mean tau cannot match the source's exactly.
  double source_zero_fraction = 0, quilted_zero_fraction = 0;
  // kMassMatched: patches whose tilt reached QuiltingOptions::max_tilt (no qualifying
  // candidate mix could reach the target mass).
  int tilt_capped_patches = 0;
  double total_s = 0;
};

// Quilts channel 0 of `source` into a width x height single-channel image named "tau".
// If `patch_index` is non-null it receives a same-size image "patch_index" holding, per
// output pixel, the raster index of the patch it came from (exact in float below 2^24);
// neighbouring pixels with different indices straddle a boundary cut, which is how tests
// measure seam visibility.
// Errors: invalid options, a source smaller than one patch or with non-finite values, an
// output size outside [1, 65536] per side. Same inputs and seed give bit-identical output.
// Exact histogram specification (not in Efros-Freeman; after Heeger and Bergen 1995): gives
// `values` the value histogram of `source` while keeping their order. Equal values form one
// group, which takes the source value at the group's mid-rank quantile, so every result is a
// source value. Exception: exact zeros stay 0 (clean glass never gets a haze), so when
// `values` holds a larger share of zeros than `source`, the result keeps that share and its
// positive values are the source's upper quantiles; when it holds a smaller share, its
// faintest values become 0 until the source's share is reached.
void SpecifyHistogram(const std::vector<float>& source, std::vector<float>* values);

Status QuiltTexture(const Image& source, int width, int height, const QuiltingOptions& options, Image* output,
                    Image* patch_index = nullptr, QuiltingSummary* summary = nullptr);

}  // namespace thinslab
