// SPDX-License-Identifier: Apache-2.0
// The pane preview shows the contrast reversal of Gu et al. 2007, Sec. 4 / Fig. 8: against
// a bright daylight scene contaminated glass is darker than clean glass (attenuation, Eq. 5),
// at night and under a collimated side beam it is brighter (scattering, Eqs. 3, 4, 6).
#include "thinslab/synth/pane_preview.h"

#include <gtest/gtest.h>

#include <cmath>

#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/synth/layer_synthesis.h"
#include "thinslab/synth/prototype_library.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

// Three vertical bands of the Fig. 2 categories (category defaults, tau 0.3 / 0.8 / 0.3),
// each spanning sky and ground; the left quarter is clean.
Image BandLayer(int w, int h) {
  Image tau[3] = {Image(w, h, {"tau"}), Image(w, h, {"tau"}), Image(w, h, {"tau"})};
  const double band_tau[3] = {0.3, 0.8, 0.3};
  for (int y = 0; y < h; ++y) {
    for (int x = w / 4; x < w; ++x) {
      const int k = std::min(2, (x - w / 4) * 3 / (w - w / 4));
      tau[k].at(x, y) = static_cast<float>(band_tau[k]);
    }
  }
  std::vector<BlendInput> inputs;
  const char* names[3] = {"dust", "dirt", "lipid"};
  for (int k = 0; k < 3; ++k) {
    CategoryDefaults d;
    EXPECT_TRUE(DefaultsForCategory(names[k], &d).ok());
    inputs.push_back({&tau[k], d.g, d.albedo, d.n2});
  }
  return BlendLayers(inputs);
}

TEST(PanePreviewTest, ContrastReversesBetweenCanonicalScenes) {
  const int w = 120, h = 80;
  const Image layer = BandLayer(w, h);
  const Image background = ProceduralBackground(w, h);
  const auto scenes = CanonicalPaneScenes();
  ASSERT_EQ(scenes.size(), 3u);
  PanePreviewOptions options;
  for (const auto& scene : scenes) {
    Image lit, clean;
    ASSERT_TRUE(RenderPaneView(layer, background, scene, options, &lit, &clean).ok());
    ASSERT_EQ(lit.width(), w);
    for (int band = 0; band < 3; ++band) {
      // Sky row (bright background) and ground row (dark background) in the band's middle.
      const int x = w / 4 + (2 * band + 1) * (w - w / 4) / 6;
      const int y_sky = h / 8, y_ground = 7 * h / 8;
      ASSERT_GT(background.at(x, y_sky), 0.5f);
      ASSERT_LT(background.at(x, y_ground), 0.2f);
      const double sky = lit.at(x, y_sky) / clean.at(x, y_sky);
      const double ground = lit.at(x, y_ground) / clean.at(x, y_ground);
      // The clean quarter renders exactly like the clean pane.
      EXPECT_FLOAT_EQ(lit.at(2, y_sky), clean.at(2, y_sky));
      if (scene.name == "daylight_window") {
        // Fig. 8 row 1: darker against the sky for every category.
        EXPECT_LT(sky, 0.95) << "band " << band;
        // Dust and lipids brighter against the ground (scattered sky light); dirt "behaves
        // almost completely like an attenuator".
        if (band != 1) {
          EXPECT_GT(ground, 1.05) << "band " << band;
        }
      } else {
        // Fig. 8 rows 2 and 5: brighter than clean glass everywhere.
        EXPECT_GT(sky, 1.05) << scene.name << " band " << band;
        EXPECT_GT(ground, 1.05) << scene.name << " band " << band;
      }
    }
  }
}

TEST(PanePreviewTest, WritesThreePanelPngWithContrasts) {
  TempDir dir;
  const Image layer = BandLayer(64, 48);
  std::vector<PanePreviewPanel> panels;
  PanePreviewOptions options;
  ASSERT_TRUE(WritePanePreview(dir / "pane.png", layer, Image(), options, &panels).ok());
  EXPECT_TRUE(FileExists(dir / "pane.png"));
  ASSERT_EQ(panels.size(), 3u);
  EXPECT_LT(panels[0].contrast_bright_background, 1.0);
  EXPECT_GT(panels[1].contrast_bright_background, 1.0);
  EXPECT_GT(panels[2].contrast_dark_background, 1.0);
}

TEST(PanePreviewTest, BadLayersAndBackgroundsGiveClearErrors) {
  TempDir dir;
  Image layer = BandLayer(32, 32);
  Image no_g(32, 32, {"tau", "albedo", "n2"});
  Image out, clean;
  const PaneScene scene = CanonicalPaneScenes()[0];
  Status s = RenderPaneView(no_g, ProceduralBackground(32, 32), scene, PanePreviewOptions(), &out, &clean);
  EXPECT_NE(s.message().find("missing channel 'g'"), std::string::npos) << s.message();
  layer.at(3, 3, 1) = 1.5f;  // g out of range.
  s = RenderPaneView(layer, ProceduralBackground(32, 32), scene, PanePreviewOptions(), &out, &clean);
  EXPECT_NE(s.message().find("pixel (3, 3)"), std::string::npos) << s.message();
  Image bg;
  s = ReadBackgroundImage(dir / "none.png", &bg);
  EXPECT_NE(s.message().find("does not exist"), std::string::npos) << s.message();
  ASSERT_TRUE(WriteFileAtomically(dir / "junk.png", "not a png").ok());
  s = ReadBackgroundImage(dir / "junk.png", &bg);
  EXPECT_NE(s.message().find("cannot decode"), std::string::npos) << s.message();
}

}  // namespace
}  // namespace thinslab
