// SPDX-License-Identifier: Apache-2.0
// Prototype library, random placement and layer blending of the synthesis tool (Gu et al.
// 2007, Sec. 5.3).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/synth/layer_synthesis.h"
#include "thinslab/synth/placement.h"
#include "thinslab/synth/prototype_library.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

Image Blob(int w, int h, double sigma, double peak) {
  Image tau(w, h, {"tau"});
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const double d2 = Sqr(x + 0.5 - 0.5 * w) + Sqr(y + 0.5 - 0.5 * h);
      tau.at(x, y) = static_cast<float>(peak * std::exp(-0.5 * d2 / Sqr(sigma)));
    }
  }
  return tau;
}

double Sum(const Image& t, int c = 0) {
  double s = 0;
  for (int y = 0; y < t.height(); ++y) {
    for (int x = 0; x < t.width(); ++x) s += t.at(x, y, c);
  }
  return s;
}

Prototype MakePrototype(const std::string& name, const std::string& category, Image tau) {
  Prototype p;
  p.name = name;
  p.category = category;
  p.tau = std::move(tau);
  CategoryDefaults d;
  EXPECT_TRUE(DefaultsForCategory(category, &d).ok());
  p.g = d.g;
  p.albedo = d.albedo;
  p.n2 = d.n2;
  p.pixel_pitch_m = 1e-4;
  return p;
}

TEST(PlacementTest, CopiesRespectTheirRangesAndConserveTau) {
  // A blob narrow enough that copies near the border lose little; scale >= 1 so bilinear
  // resampling conserves the integral to within 1%.
  const Image blob = Blob(21, 21, 2.5, 1.0);
  PlacementOptions o;
  o.density = 0.5;
  o.scale_min = 1.0;
  o.scale_max = 1.5;
  o.rotation_min_deg = 10;
  o.rotation_max_deg = 20;
  o.x_min = 0.2;
  o.x_max = 0.8;
  o.y_min = 0.25;
  o.y_max = 0.75;
  Image canvas;
  std::vector<PlacedCopy> copies;
  ASSERT_TRUE(PlaceCopies(blob, 256, 256, o, 7, &canvas, &copies).ok());
  ASSERT_GT(copies.size(), 20u);
  double expected = 0;
  for (const auto& c : copies) {
    EXPECT_GE(c.centre_x_px, 0.2 * 256);
    EXPECT_LE(c.centre_x_px, 0.8 * 256);
    EXPECT_GE(c.centre_y_px, 0.25 * 256);
    EXPECT_LE(c.centre_y_px, 0.75 * 256);
    EXPECT_GE(c.scale, 1.0);
    EXPECT_LE(c.scale, 1.5);
    EXPECT_GE(c.rotation_deg, 10);
    EXPECT_LE(c.rotation_deg, 20);
    expected += Sqr(c.scale) * Sum(blob);
  }
  EXPECT_NEAR(Sum(canvas) / expected, 1.0, 0.01);
  // No tau outside the allowed centres plus one copy radius.
  const double reach = 1.5 * 21 * std::sqrt(2.0) / 2 + 1;
  for (int y = 0; y < 256; ++y) {
    for (int x = 0; x < 256; ++x) {
      if (x + 0.5 < 0.2 * 256 - reach || x + 0.5 > 0.8 * 256 + reach || y + 0.5 < 0.25 * 256 - reach ||
          y + 0.5 > 0.75 * 256 + reach) {
        ASSERT_EQ(canvas.at(x, y), 0.0f) << x << "," << y;
      }
    }
  }
}

TEST(PlacementTest, RotationTurnsTheCopy) {
  // A horizontal bar rotated by 90 deg becomes vertical: its second moments swap.
  Image bar(31, 5, {"tau"}, 1.0f);
  PlacementOptions o;
  o.density = 0.001;
  o.scale_min = o.scale_max = 1;
  o.rotation_min_deg = o.rotation_max_deg = 90;
  o.x_min = o.x_max = 0.5;
  o.y_min = o.y_max = 0.5;
  Image canvas;
  std::vector<PlacedCopy> copies;
  // density 0.001 of a 64x64 canvas rounds to 0 copies: use enough density for exactly 1.
  o.density = 31.0 * 5 / (64 * 64);
  ASSERT_TRUE(PlaceCopies(bar, 64, 64, o, 1, &canvas, &copies).ok());
  ASSERT_EQ(copies.size(), 1u);
  double sxx = 0, syy = 0, m = 0;
  for (int y = 0; y < 64; ++y) {
    for (int x = 0; x < 64; ++x) {
      const double v = canvas.at(x, y);
      m += v;
      sxx += v * Sqr(x + 0.5 - 32);
      syy += v * Sqr(y + 0.5 - 32);
    }
  }
  EXPECT_GT(syy / m, 10 * sxx / m);
}

TEST(PlacementTest, DirtIsBiasedToTheTop) {
  const Image blob = Blob(9, 15, 2.0, 0.5);
  PlacementOptions o = DefaultPlacementForCategory("dirt");
  o.density = 2;
  std::vector<PlacedCopy> copies;
  Image canvas;
  ASSERT_TRUE(PlaceCopies(blob, 256, 256, o, 3, &canvas, &copies).ok());
  ASSERT_GT(copies.size(), 100u);
  double mean_y = 0;
  for (const auto& c : copies) {
    EXPECT_LE(c.centre_y_px, o.y_max * 256);
    EXPECT_GE(c.rotation_deg, -10);
    EXPECT_LE(c.rotation_deg, 10);
    mean_y += c.centre_y_px;
  }
  mean_y /= copies.size();
  // y = y_max * u^2 has mean y_max / 3 (uniform would give y_max / 2).
  EXPECT_NEAR(mean_y / (o.y_max * 256), 1.0 / 3, 0.05);
}

TEST(PlacementTest, BadRangesGiveClearErrors) {
  const Image blob = Blob(9, 9, 2.0, 0.5);
  Image canvas;
  PlacementOptions o;
  o.scale_min = 2;
  o.scale_max = 1;
  Status s = PlaceCopies(blob, 64, 64, o, 1, &canvas, nullptr);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("PlacementOptions::scale"), std::string::npos) << s.message();
  o = PlacementOptions();
  o.y_max = 1.5;
  s = PlaceCopies(blob, 64, 64, o, 1, &canvas, nullptr);
  EXPECT_NE(s.message().find("PlacementOptions::y"), std::string::npos) << s.message();
  o = PlacementOptions();
  canvas = Image();
  s = PlaceCopies(blob, -3, 64, o, 1, &canvas, nullptr);
  EXPECT_NE(s.message().find("impossible"), std::string::npos) << s.message();
}

TEST(BlendTest, TauAddsAndParametersFollowCoverage) {
  Image a(4, 1, {"tau"}), b(4, 1, {"tau"});
  a.at(1, 0) = 0.5f;  // a only
  b.at(2, 0) = 0.2f;  // b only
  a.at(3, 0) = 0.5f;  // both
  b.at(3, 0) = 1.0f;
  const Image out = BlendLayers({{&a, 0.6, 0.5, 1.0}, {&b, 0.9, 0.8, 1.5}});
  ASSERT_EQ(out.channel_names(), (std::vector<std::string>{"tau", "g", "albedo", "n2"}));
  // Clean pixel: no layer.
  EXPECT_EQ(out.at(0, 0, 0), 0.0f);
  EXPECT_EQ(out.at(0, 0, 1), 0.0f);
  EXPECT_EQ(out.at(0, 0, 2), 0.0f);
  EXPECT_EQ(out.at(0, 0, 3), 1.0f);
  EXPECT_FLOAT_EQ(out.at(1, 0, 1), 0.6f);
  EXPECT_FLOAT_EQ(out.at(2, 0, 3), 1.5f);
  // Overlap: tau adds; b (top, alpha_b = 1 - e^-1) over a (alpha_a = 1 - e^-0.5).
  EXPECT_FLOAT_EQ(out.at(3, 0, 0), 1.5f);
  const double aa = 1 - std::exp(-0.5), ab = 1 - std::exp(-1.0);
  const double wa = aa * (1 - ab), wb = ab;
  EXPECT_NEAR(out.at(3, 0, 1), (wa * 0.6 + wb * 0.9) / (wa + wb), 1e-6);
  EXPECT_NEAR(wa + wb, 1 - std::exp(-1.5), 1e-12);  // Coverage of the sum of tau.
}

TEST(PrototypeLibraryTest, WriteReadRoundTripAndErrors) {
  TempDir dir;
  Prototype p = MakePrototype("blob_a", "lipid", Blob(16, 12, 3, 0.4));
  ASSERT_TRUE(WritePrototype(dir.path(), p, false).ok());
  Status s = WritePrototype(dir.path(), p, false);
  EXPECT_NE(s.message().find("already exists"), std::string::npos) << s.message();
  std::vector<Prototype> lib;
  ASSERT_TRUE(ReadPrototypeLibrary(dir.path(), &lib).ok());
  ASSERT_EQ(lib.size(), 1u);
  EXPECT_EQ(lib[0].name, "blob_a");
  EXPECT_EQ(lib[0].category, "lipid");
  EXPECT_DOUBLE_EQ(lib[0].n2, p.n2);
  EXPECT_EQ(lib[0].tau.data(), p.tau.data());

  // Bad prototypes are refused with the file and the field.
  Prototype bad = p;
  bad.name = "Bad Name";
  EXPECT_FALSE(WritePrototype(dir.path(), bad, false).ok());
  bad = p;
  bad.category = "soot";
  s = WritePrototype(dir.path(), bad, true);
  EXPECT_NE(s.message().find("dust, dirt, lipid"), std::string::npos) << s.message();
  bad = p;
  bad.tau = Image(4, 4, {"tau"}, 1.0f);
  s = WritePrototype(dir.path(), bad, true);
  EXPECT_NE(s.message().find("at least 8x8"), std::string::npos) << s.message();
  bad = p;
  bad.tau = Image(16, 16, {"tau"}, 0.0f);
  s = WritePrototype(dir.path(), bad, true);
  EXPECT_NE(s.message().find("zero everywhere"), std::string::npos) << s.message();
  // A hand-edited manifest with g out of range names the file and field.
  const std::string manifest = JoinPath(JoinPath(dir.path(), "blob_a"), kPrototypeManifestName);
  std::string text;
  ASSERT_TRUE(ReadFileToString(manifest, &text).ok());
  auto j = nlohmann::json::parse(text);
  j["g"] = 1.5;
  ASSERT_TRUE(WriteFileAtomically(manifest, j.dump()).ok());
  s = ReadPrototypeLibrary(dir.path(), &lib);
  EXPECT_FALSE(s.ok());
  EXPECT_NE(s.message().find("prototype.json"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("g = 1.5"), std::string::npos) << s.message();
  // NaN in the tau map.
  j["g"] = 0.8;
  ASSERT_TRUE(WriteFileAtomically(manifest, j.dump()).ok());
  Image nan_tau = p.tau;
  nan_tau.at(2, 3) = -1.0f;
  ASSERT_TRUE(WriteExr(JoinPath(JoinPath(dir.path(), "blob_a"), kPrototypeTauName), nan_tau).ok());
  s = ReadPrototypeLibrary(dir.path(), &lib);
  EXPECT_NE(s.message().find("(2, 3)"), std::string::npos) << s.message();
  // Empty library.
  TempDir empty;
  s = ReadPrototypeLibrary(empty.path(), &lib);
  EXPECT_NE(s.message().find("no prototype"), std::string::npos) << s.message();
}

// A `thinslab fit tau` output folder and a `fit phase` summary (docs/format.md 9.2-9.4).
void WriteFakeFits(const std::string& root, bool tau_success, float masked_share) {
  const std::string tau_dir = JoinPath(root, "tau"), phase_dir = JoinPath(root, "phase");
  ASSERT_TRUE(CreateDirectories(tau_dir).ok());
  ASSERT_TRUE(CreateDirectories(phase_dir).ok());
  Image map(40, 30, {"tau", "status", "tau_eq7"});
  for (int y = 0; y < 30; ++y) {
    for (int x = 0; x < 40; ++x) {
      map.at(x, y, 0) = static_cast<float>(0.6 * std::exp(-0.5 * (Sqr(x - 20.0) + Sqr(y - 15.0)) / 16) + 0.005);
      map.at(x, y, 1) = (x + 40 * y) < masked_share * 1200 ? 3.0f : 0.0f;
    }
  }
  map.attributes()["pixel_pitch_m"] = "8.0000000000000007e-05";
  map.attributes()["source_session"] = "fake_session";
  ASSERT_TRUE(WriteExr(JoinPath(tau_dir, "tau.exr"), map).ok());
  ASSERT_TRUE(WriteFileAtomically(JoinPath(tau_dir, "summary.json"),
                                  std::string("{\"format\":\"thinslab-fit-summary\",\"result\":\"") +
                                      (tau_success ? "success" : "failure") + "\"}")
                  .ok());
  ASSERT_TRUE(
      WriteFileAtomically(JoinPath(phase_dir, "summary.json"),
                          "{\"format\":\"thinslab-fit-summary\",\"model\":\"gu2007_eq8\",\"result\":\"success\","
                          "\"g\":0.83,\"sigma_g\":0.02,\"categories\":[\"lipid\",\"dust\"]}")
          .ok());
}

TEST(PrototypeLibraryTest, FromFitOutputs) {
  TempDir dir;
  WriteFakeFits(dir.path(), true, 0.0f);
  PrototypeFromFitOptions o;
  o.fit_tau_dir = dir / "tau";
  o.fit_phase_dir = dir / "phase";
  o.name = "print_a";
  o.crop_x = 5;
  o.crop_y = 3;
  o.crop_width = 30;
  o.crop_height = 24;
  Prototype p;
  ASSERT_TRUE(PrototypeFromFit(o, &p).ok());
  EXPECT_EQ(p.category, "lipid");
  EXPECT_DOUBLE_EQ(p.g, 0.83);
  EXPECT_EQ(p.g_source, "fit_phase");
  EXPECT_EQ(p.albedo_source, "category_default");
  EXPECT_NEAR(p.pixel_pitch_m, 8e-5, 1e-15);
  ASSERT_EQ(p.tau.width(), 30);
  EXPECT_FLOAT_EQ(p.tau.at(15, 12), static_cast<float>(0.6 + 0.005));  // Map pixel (20, 15).
  EXPECT_EQ(p.tau.at(0, 0), 0.0f);                                     // Below tau_floor: exactly clean.
  // Explicit values override the phase fit.
  o.category = "dirt";
  o.g = 0.3;
  o.n2 = 1.4;
  ASSERT_TRUE(PrototypeFromFit(o, &p).ok());
  EXPECT_EQ(p.category, "dirt");
  EXPECT_DOUBLE_EQ(p.g, 0.3);
  EXPECT_DOUBLE_EQ(p.n2, 1.4);
  // Errors: crop outside the map, no category, failed fit, masked crop, out-of-range g.
  o.crop_x = 20;
  Status s = PrototypeFromFit(o, &p);
  EXPECT_NE(s.message().find("outside the 40x30 map"), std::string::npos) << s.message();
  o.crop_x = 5;
  o.g = 1.2;
  s = PrototypeFromFit(o, &p);
  EXPECT_NE(s.message().find("PrototypeFromFitOptions::g"), std::string::npos) << s.message();
  o.g = -2;
  o.category.clear();
  o.fit_phase_dir.clear();
  s = PrototypeFromFit(o, &p);
  EXPECT_NE(s.message().find("category"), std::string::npos) << s.message();
  TempDir failed;
  WriteFakeFits(failed.path(), false, 0.0f);
  o.fit_tau_dir = failed / "tau";
  o.category = "dust";
  s = PrototypeFromFit(o, &p);
  EXPECT_NE(s.message().find("result is 'failure'"), std::string::npos) << s.message();
  TempDir masked;
  WriteFakeFits(masked.path(), true, 0.5f);
  o.fit_tau_dir = masked / "tau";
  s = PrototypeFromFit(o, &p);
  EXPECT_NE(s.message().find("masked"), std::string::npos) << s.message();
  o.fit_tau_dir = dir / "missing";
  s = PrototypeFromFit(o, &p);
  EXPECT_NE(s.message().find("missing"), std::string::npos) << s.message();
}

std::vector<Prototype> SmallLibrary() {
  std::vector<Prototype> lib;
  // Dust source: specks on a 96x96 map.
  Image dust(96, 96, {"tau"});
  for (int k = 0; k < 40; ++k) {
    const int cx = (k * 37) % 96, cy = (k * 53 + 11) % 96;
    for (int y = std::max(0, cy - 6); y < std::min(96, cy + 7); ++y) {
      for (int x = std::max(0, cx - 6); x < std::min(96, cx + 7); ++x) {
        dust.at(x, y) += static_cast<float>(0.8 * std::exp(-0.5 * (Sqr(x - cx) + Sqr(y - cy)) / 4.0));
      }
    }
  }
  lib.push_back(MakePrototype("dust_a", "dust", dust));
  lib.push_back(MakePrototype("streak_a", "dirt", Blob(10, 40, 4, 0.5)));
  lib.push_back(MakePrototype("print_a", "lipid", Blob(30, 36, 8, 0.4)));
  return lib;
}

TEST(SynthesisTest, LayerChannelsSizeAndDeterminism) {
  const std::vector<Prototype> lib = SmallLibrary();
  SynthesisOptions o;
  o.width_px = 256;
  o.height_px = 192;
  o.seed = 5;
  for (const char* name : {"dust_a", "streak_a", "print_a"}) {
    SynthLayerSpec s;
    s.prototype = name;
    o.layers.push_back(s);
  }
  Image a, b, c;
  SynthesisSummary summary;
  ASSERT_TRUE(SynthesizeContamination(lib, o, &a, &summary).ok());
  ASSERT_EQ(a.width(), 256);
  ASSERT_EQ(a.height(), 192);
  ASSERT_EQ(a.channel_names(), (std::vector<std::string>{"tau", "g", "albedo", "n2"}));
  EXPECT_TRUE(CheckContaminationLayer(a, "a").ok());
  ASSERT_EQ(summary.layers.size(), 3u);
  EXPECT_EQ(summary.layers[0].method, "quilting");
  EXPECT_EQ(summary.layers[1].method, "placement");
  EXPECT_GT(summary.layers[2].copies.size(), 0u);
  EXPECT_GT(summary.covered_fraction, 0.1);
  // Dirt copies obey the dirt defaults (top half, +-10 deg).
  for (const auto& copy : summary.layers[1].copies) {
    EXPECT_LE(copy.centre_y_px, 0.5 * 192);
    EXPECT_LE(std::abs(copy.rotation_deg), 10);
  }
  ASSERT_TRUE(SynthesizeContamination(lib, o, &b, &summary).ok());
  EXPECT_EQ(a.data(), b.data());
  o.seed = 6;
  ASSERT_TRUE(SynthesizeContamination(lib, o, &c, &summary).ok());
  EXPECT_NE(a.data(), c.data());
  // The EXR round trip keeps the bits.
  TempDir dir;
  ASSERT_TRUE(WriteExr(dir / "layer.exr", a).ok());
  Image read;
  ASSERT_TRUE(ReadExr(dir / "layer.exr", &read).ok());
  EXPECT_TRUE(CheckContaminationLayer(read, "layer.exr").ok());
  EXPECT_EQ(read.at(100, 50, read.ChannelIndex("tau")), a.at(100, 50, 0));
}

TEST(SynthesisTest, ImpossibleSizesAndUnknownPrototypesGiveClearErrors) {
  const std::vector<Prototype> lib = SmallLibrary();
  SynthesisOptions o;
  SynthLayerSpec s;
  s.prototype = "dust_a";
  o.layers.push_back(s);
  Image out;
  SynthesisSummary summary;
  o.width_px = 0;
  Status st = SynthesizeContamination(lib, o, &out, &summary);
  EXPECT_NE(st.message().find("impossible"), std::string::npos) << st.message();
  o.width_px = 16384;
  o.height_px = 16384;
  st = SynthesizeContamination(lib, o, &out, &summary);
  EXPECT_NE(st.message().find("2^26"), std::string::npos) << st.message();
  o.width_px = o.height_px = 64;
  o.layers[0].prototype = "nope";
  st = SynthesizeContamination(lib, o, &out, &summary);
  EXPECT_NE(st.message().find("'nope' is not in the library"), std::string::npos) << st.message();
  o.layers.clear();
  st = SynthesizeContamination(lib, o, &out, &summary);
  EXPECT_NE(st.message().find("layers is empty"), std::string::npos) << st.message();
}

TEST(SynthesisTest, SpecFileAndErrors) {
  TempDir dir;
  ASSERT_TRUE(WriteFileAtomically(dir / "spec.json", R"({"format": "thinslab-synth-spec", "format_version": "1.0",
    "width_px": 128, "height_px": 96, "seed": 9,
    "layers": [{"prototype": "dust_a", "density": 0.5, "patch_px": 24, "overlap_px": 6},
               {"prototype": "print_a", "density": 0.2, "scale": [0.9, 1.1], "rotation_deg": [-5, 5], "y": [0, 0.3]}]})")
                  .ok());
  SynthesisOptions o;
  ASSERT_TRUE(ReadSynthesisSpec(dir / "spec.json", &o).ok());
  EXPECT_EQ(o.width_px, 128);
  EXPECT_EQ(o.seed, 9u);
  ASSERT_EQ(o.layers.size(), 2u);
  EXPECT_EQ(o.layers[0].quilting.patch_px, 24);
  EXPECT_TRUE(o.layers[1].has_placement);
  EXPECT_DOUBLE_EQ(o.layers[1].placement.y_max, 0.3);
  Image out;
  SynthesisSummary summary;
  ASSERT_TRUE(SynthesizeContamination(SmallLibrary(), o, &out, &summary).ok());
  for (const auto& c : summary.layers[1].copies) EXPECT_LE(c.centre_y_px, 0.3 * 96);
  ASSERT_TRUE(WriteFileAtomically(dir / "bad.json", R"({"format": "thinslab-synth-spec", "format_version": "1.0",
    "layers": [{"prototype": "print_a", "scale": [1]}]})")
                  .ok());
  Status s = ReadSynthesisSpec(dir / "bad.json", &o);
  EXPECT_NE(s.message().find("layers[0].scale must be [min, max]"), std::string::npos) << s.message();
}

TEST(SynthesisTest, SpecFileSetsTheQuiltingSelection) {
  TempDir dir;
  const auto spec = [&](const std::string& name, const std::string& layer) {
    const std::string path = dir / name;
    EXPECT_TRUE(WriteFileAtomically(path, R"({"format": "thinslab-synth-spec", "format_version": "1.0",
      "width_px": 96, "height_px": 80, "seed": 4, "layers": [)" + layer + "]}")
                    .ok());
    return path;
  };
  SynthesisOptions o;
  ASSERT_TRUE(ReadSynthesisSpec(spec("ssd.json", R"({"prototype": "dust_a", "selection": "ssd", "max_tilt": 1.5,
      "mass_feedback": 0.25, "match_histogram": false})"),
                                &o)
                  .ok());
  ASSERT_EQ(o.layers.size(), 1u);
  EXPECT_EQ(o.layers[0].quilting.selection, QuiltingSelection::kSsd);
  EXPECT_DOUBLE_EQ(o.layers[0].quilting.max_tilt, 1.5);
  EXPECT_DOUBLE_EQ(o.layers[0].quilting.mass_feedback, 0.25);
  EXPECT_FALSE(o.layers[0].quilting.match_histogram);
  // The options reach the quilting: the same seed with the default selection gives another layer.
  SynthesisOptions defaults;
  ASSERT_TRUE(ReadSynthesisSpec(spec("default.json", R"({"prototype": "dust_a", "match_histogram": false})"), &defaults)
                  .ok());
  EXPECT_EQ(defaults.layers[0].quilting.selection, QuiltingSelection::kMassMatched);
  Image ssd_layer, default_layer;
  SynthesisSummary summary;
  ASSERT_TRUE(SynthesizeContamination(SmallLibrary(), o, &ssd_layer, &summary).ok());
  ASSERT_TRUE(SynthesizeContamination(SmallLibrary(), defaults, &default_layer, &summary).ok());
  EXPECT_NE(ssd_layer.data(), default_layer.data());

  Status s = ReadSynthesisSpec(spec("bad_selection.json", R"({"prototype": "dust_a", "selection": "uniform"})"), &o);
  EXPECT_NE(s.message().find(R"(layers[0].selection = "uniform": must be "mass_matched" or "ssd")"), std::string::npos)
      << s.message();
  s = ReadSynthesisSpec(spec("bad_bool.json", R"({"prototype": "dust_a", "match_histogram": 1})"), &o);
  EXPECT_NE(s.message().find("layers[0].match_histogram must be true or false"), std::string::npos) << s.message();
  s = ReadSynthesisSpec(spec("typo.json", R"({"prototype": "dust_a", "max_tlit": 2})"), &o);
  EXPECT_NE(s.message().find("layers[0]: unknown field 'max_tlit'"), std::string::npos) << s.message();
  // An out-of-range value is refused by the quilting, naming the layer.
  ASSERT_TRUE(ReadSynthesisSpec(spec("tilt0.json", R"({"prototype": "dust_a", "max_tilt": 0})"), &o).ok());
  s = SynthesizeContamination(SmallLibrary(), o, &ssd_layer, &summary);
  EXPECT_NE(s.message().find("max_tilt"), std::string::npos) << s.message();
  EXPECT_NE(s.message().find("dust_a"), std::string::npos) << s.message();
}

TEST(SynthesisTest, BundledLibraryLoadsAndSynthesizes) {
  const char* source_dir = std::getenv("THINSLAB_SOURCE_DIR");
  ASSERT_NE(source_dir, nullptr) << "run through ctest (THINSLAB_SOURCE_DIR)";
  std::vector<Prototype> lib;
  const Status s = ReadPrototypeLibrary(std::string(source_dir) + "/data/prototypes", &lib);
  ASSERT_TRUE(s.ok()) << s.message();
  bool categories[3] = {false, false, false};
  for (const auto& p : lib) {
    categories[0] |= p.category == "dust";
    categories[1] |= p.category == "dirt";
    categories[2] |= p.category == "lipid";
  }
  EXPECT_TRUE(categories[0] && categories[1] && categories[2]) << "one prototype per Fig. 2 category";
  SynthesisOptions o;
  o.width_px = o.height_px = 256;
  for (const auto& p : lib) {
    SynthLayerSpec spec;
    spec.prototype = p.name;
    o.layers.push_back(spec);
  }
  Image out;
  SynthesisSummary summary;
  ASSERT_TRUE(SynthesizeContamination(lib, o, &out, &summary).ok());
  EXPECT_TRUE(CheckContaminationLayer(out, "bundled").ok());
  EXPECT_GT(summary.covered_fraction, 0.05);
}

}  // namespace
}  // namespace thinslab
