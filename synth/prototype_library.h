// SPDX-License-Identifier: Apache-2.0
// The prototype library of the contamination synthesis tool (Gu, Ramamoorthi, Belhumeur and
// Nayar 2007, "Dirty Glass", Sec. 5.3): measured tau maps, each with its contaminant category
// (Fig. 2: dust, dirt, lipid), HG g, single-scattering albedo and refractive index n2.
//
// On disk (docs/format.md, "Prototype library"): a library is a folder; every sub-folder that
// holds a prototype.json is one prototype, with its tau map in tau.exr next to it. Adding a
// prototype writes one new sub-folder atomically and touches nothing else, so there is no
// shared index to corrupt.
#pragma once

#include <string>
#include <vector>

#include "thinslab/core/image.h"
#include "thinslab/core/status.h"

namespace thinslab {

inline constexpr const char* kPrototypeManifestName = "prototype.json";
inline constexpr const char* kPrototypeTauName = "tau.exr";

struct Prototype {
  std::string name;             // Folder name: [a-z0-9_-], 1..64 characters.
  std::string category;         // "dust", "dirt" or "lipid" (Gu et al. 2007, Fig. 2).
  Image tau;                    // One channel "tau": optical thickness, unitless, finite, >= 0.
  double g = 0.8;               // HG mean cosine, unitless (-1, 1).
  double sigma_g = 0;           // Standard error of g (0: not measured).
  double albedo = 0.5;          // Single-scattering albedo omega0, unitless [0, 1].
  double n2 = 1.0;              // Refractive index of the contaminant, [1, 3].
  double pixel_pitch_m = 1e-4;  // Size of one tau pixel on the glass [m], > 0.
  // Where each parameter came from: "fit_phase", "option", "category_default".
  std::string g_source = "option", albedo_source = "option", n2_source = "option";
  std::string provenance;  // Free text: which capture/fit produced the tau map.

  // Checks every field; errors name `where` (a file or "Prototype") and the field.
  Status Check(const std::string& where) const;
};

// Typical parameters of a category for the fields thinslab cannot measure (albedo, n2), and g
// when no `fit phase` result is given. Not measured values: docs/models/contamination_synthesis.md.
struct CategoryDefaults {
  double g, albedo, n2;
};
Status DefaultsForCategory(const std::string& category, CategoryDefaults* defaults);
bool IsValidPrototypeName(const std::string& name);

// Reads <dir>/prototype.json and <dir>/tau.exr and checks them.
Status ReadPrototype(const std::string& dir, Prototype* prototype);
// Every sub-folder of `library_dir` holding a prototype.json, sorted by name. An unreadable or
// invalid prototype is an error naming its file; an empty library is an error.
Status ReadPrototypeLibrary(const std::string& library_dir, std::vector<Prototype>* prototypes);
// Writes <library_dir>/<name>/ atomically (staged folder). Refuses to replace an existing
// prototype unless `overwrite`.
Status WritePrototype(const std::string& library_dir, const Prototype& prototype, bool overwrite);

// `thinslab synth add-prototype`: builds a prototype from a `thinslab fit tau` output folder
// (tau.exr with channels tau and status, summary.json) and optionally a `thinslab fit phase`
// folder (summary.json with g, sigma_g, categories). Explicit values override the fits.
struct PrototypeFromFitOptions {
  std::string fit_tau_dir;    // Required.
  std::string fit_phase_dir;  // Optional.
  std::string name;           // Required.
  std::string category;       // "" = from the phase fit (its first category).
  double g = -2;              // Outside (-1, 1) = from the phase fit, else the category default.
  double albedo = -1;         // < 0 = category default.
  double n2 = 0;              // < 1 = category default.
  // Crop of the tau map in map pixels (x, y, width, height); width 0 = the whole map.
  int crop_x = 0, crop_y = 0, crop_width = 0, crop_height = 0;
  // Fitted tau below this is set to 0 (the fit's noise floor; prototypes then have exactly
  // clean surroundings, so n2 and g stay undefined there), unitless >= 0.
  double tau_floor = 0.02;
  // Largest share of masked pixels (status 1-3, set to tau 0) allowed in the crop.
  double max_masked_fraction = 0.02;

  bool Check(std::string* error) const;
};
Status PrototypeFromFit(const PrototypeFromFitOptions& options, Prototype* prototype);

}  // namespace thinslab
