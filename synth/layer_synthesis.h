// SPDX-License-Identifier: Apache-2.0
// `thinslab synth layer`: the contamination synthesis tool of Gu et al. 2007, Sec. 5.3. One
// layer per selected prototype (dust: image quilting; lipid: random scaled/rotated copies;
// dirt: random copies with limited rotation and translation, biased to the top), then all
// layers alpha-blended into one texture whose channels are the model's parameters: tau, g,
// albedo, n2 (Sec. 3.1, "4 input parameters").
//
// Blending (docs/models/contamination_synthesis.md): a layer's coverage (alpha) at a pixel is
// 1 - e^{-tau}, the share of light it interacts with (Eq. 5 at normal incidence). Layers are
// composited "over" in the listed order (first = bottom). The composite coverage
// 1 - prod(1 - alpha_k) = 1 - e^{-sum tau_k}, so the blended tau is exactly the sum of the
// layers' tau; g, albedo and n2 are the over-composited values divided by the total coverage
// (un-premultiplied). Clean pixels (tau = 0) get g = 0, albedo = 0, n2 = 1 (no layer).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"
#include "thinslab/synth/placement.h"
#include "thinslab/synth/prototype_library.h"
#include "thinslab/synth/quilting.h"

namespace thinslab {

struct SynthLayerSpec {
  std::string prototype;  // Prototype name in the library.
  // Dust: tau multiplier (tau is proportional to particle number density, so this scales the
  // amount of dust). Lipid/dirt: PlacementOptions::density. Negative = category default
  // (1 for dust).
  double density = -1;
  bool has_placement = false;  // Use `placement` instead of the category's defaults.
  PlacementOptions placement;  // Lipid/dirt; pitch_ratio is set from the pitches.
  QuiltingOptions quilting;    // Dust; seed is set per layer.
};

inline constexpr int kMaxSynthesisSidePx = 16384;
inline constexpr int64_t kMaxSynthesisPixels = int64_t{1} << 26;

struct SynthesisOptions {
  int width_px = 1024;  // Output size, each side in [1, kMaxSynthesisSidePx]; width * height <= 2^26.
  int height_px = 1024;
  uint64_t seed = 1;  // Fixes every random choice; same seed, same bits.
  // Pitch of the output [m]; 0 = the first layer's prototype pitch. Prototypes of another
  // pitch are resampled.
  double pixel_pitch_m = 0;
  std::vector<SynthLayerSpec> layers;  // Bottom first.

  bool Check(std::string* error) const;
};

// Reads a spec JSON file (docs/format.md, "Synthesis spec") into `options`.
Status ReadSynthesisSpec(const std::string& path, SynthesisOptions* options);

struct SynthesizedLayerInfo {
  std::string prototype, category, method;  // method: "quilting" or "placement".
  double density = 0;
  std::vector<PlacedCopy> copies;
  QuiltingSummary quilting;
  double seconds = 0;
};

struct SynthesisSummary {
  std::vector<SynthesizedLayerInfo> layers;
  double pixel_pitch_m = 0;
  double covered_fraction = 0;  // Pixels with tau > 0.
  double mean_tau = 0, max_tau = 0;
  double total_s = 0;
  std::string ToJson() const;
};

// The blended texture: channels tau, g, albedo, n2 (in this order), no attributes.
Status SynthesizeContamination(const std::vector<Prototype>& library, const SynthesisOptions& options, Image* layer,
                               SynthesisSummary* summary);

// Alpha-over blend of single-layer tau maps with constant parameters (bottom first); exposed
// for tests. Every map must have the size of the first.
struct BlendInput {
  const Image* tau;
  double g, albedo, n2;
};
Image BlendLayers(const std::vector<BlendInput>& inputs);

// Checks a synthesized layer read from disk: channels tau, g, albedo, n2 present, finite and
// in range. `where` names the file in errors.
Status CheckContaminationLayer(const Image& layer, const std::string& where);

}  // namespace thinslab
