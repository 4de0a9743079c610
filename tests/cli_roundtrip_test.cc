// SPDX-License-Identifier: Apache-2.0
// Issue #27 item 3, through the binary: a simulated shadow-map capture (Monte Carlo layer, sensor
// noise, quantisation: a more complete forward model than the fitted one) is fitted with `fit
// tau`, and `thinslab roundtrip` renders the fitted layer with Blender (Cycles, Debian's blender)
// under the capture's own rig and camera. The render must reproduce the captured shadow within
// what the noise of the capture and of the render and the map's own error allow, and agree with
// `thinslab predict`. The check can fail: the same render of a map with tau doubled reads far
// worse, and so does the clean board (no layer at all).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "tests/testing/json_file.h"
#include "tests/testing/run_ok.h"
#include "tests/testing/temp_dir.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"

namespace thinslab {
namespace {

// sqrt(sum (a - b)^2 / sum b^2) over the valid pixels of roundtrip.exr.
double RelativeRms(const Image& images, const std::string& a, const std::string& b) {
  const int ai = images.ChannelIndex(a), bi = images.ChannelIndex(b), valid = images.ChannelIndex("valid");
  double err = 0, norm = 0;
  for (int y = 0; y < images.height(); ++y) {
    for (int x = 0; x < images.width(); ++x) {
      if (images.at(x, y, valid) == 0) continue;
      err += std::pow(images.at(x, y, ai) - images.at(x, y, bi), 2);
      norm += std::pow(images.at(x, y, bi), 2);
    }
  }
  return norm > 0 ? std::sqrt(err / norm) : -1;
}

const nlohmann::json& Band(const nlohmann::json& bands, const std::string& name) {
  for (const nlohmann::json& band : bands) {
    if (band["band"] == name) return band;
  }
  ADD_FAILURE() << "no band " << name << " in " << bands.dump();
  return bands;
}

// A copy of FIT with tau (and tau_eq7) multiplied by `factor`.
void ScaledFit(const std::string& fit, const std::string& out, double factor) {
  ASSERT_TRUE(CreateDirectories(out).ok());
  std::string summary;
  ASSERT_TRUE(ReadFileToString(fit + "/summary.json", &summary).ok());
  ASSERT_TRUE(WriteFileAtomically(out + "/summary.json", summary).ok());
  Image tau;
  ASSERT_TRUE(ReadExr(fit + "/tau.exr", &tau).ok());
  for (const char* name : {"tau", "tau_eq7"}) {
    const int c = tau.ChannelIndex(name);
    ASSERT_GE(c, 0) << name;
    for (int y = 0; y < tau.height(); ++y) {
      for (int x = 0; x < tau.width(); ++x) tau.at(x, y, c) = static_cast<float>(factor * tau.at(x, y, c));
    }
  }
  ASSERT_TRUE(WriteExr(out + "/tau.exr", tau).ok());
}

TEST(CliRoundTrip, BlenderRenderOfTheFittedLayerReproducesTheCaptureAndPredict) {
  ASSERT_EQ(std::system("command -v blender > /dev/null"), 0) << "blender is missing (scripts/install_deps.sh)";
  TempDir dir;
  const std::string capture = dir / "capture";
  // Board at 5 mm: the scattered light (Gu Eq. 6) spreads over several camera pixels, so the
  // render's volume scattering is part of what is compared.
  RunThinslabOk("sim shadow-maps " + capture +
                " --camera-width-px 320 --camera-height-px 240 --photons 20000 --frames 2 --board-distance-mm 5 "
                "--seed 3");
  RunThinslabOk("fit tau " + capture);
  const RunResult run = RunThinslabOk("roundtrip " + capture + " --samples 32 --downsample 2 --verbose");
  std::printf("%s\n", run.output.c_str());
  // The render reports its samples, read from Blender's log: 3 passes of 32 (issue #26 item 4).
  EXPECT_NE(run.output.find("roundtrip: Blender render (3 passes): 96/96"), std::string::npos) << run.output;
  const std::string out = capture + "/fit/roundtrip";
  const nlohmann::json summary = ReadJsonFile(out + "/summary.json");
  EXPECT_EQ(summary["format"], "thinslab-roundtrip-summary");
  EXPECT_EQ(summary["image"]["width"], 160);
  EXPECT_EQ(summary["image"]["height"], 120);

  // Per region: the render against the capture within what the capture's and the render's noise
  // and the map's own error (sigma_tau) allow, and no worse than thinslab's own prediction by
  // more than that allowance; the render against predict within the render's noise plus 1 % for
  // the models' difference (Cycles' volume with all orders of scattering vs Gu Eq. 6's single
  // scattering).
  for (const char* name : {"thin", "all"}) {
    const nlohmann::json& r = Region(summary["regions"], name);
    ASSERT_GT(r["pixels"].get<int>(), 300) << r.dump();
    const double render = r["render_vs_capture_relative_rms"], predict = r["predict_vs_capture_relative_rms"],
                 between = r["render_vs_predict_relative_rms"];
    const double allowed = std::hypot(r["noise_relative_rms"].get<double>(), r["sigma_tau_relative_rms"].get<double>());
    std::printf("%s: render vs capture %.4f, predict vs capture %.4f, render vs predict %.4f, allowed %.4f\n", name,
                render, predict, between, allowed);
    EXPECT_LT(render, 2 * allowed + 0.01) << r.dump();
    EXPECT_LT(render, predict + allowed) << r.dump();
    EXPECT_LT(between, 1.5 * r["render_noise_relative_rms"].get<double>() + 0.01) << r.dump();
  }

  // The comparison can fail: the clean board is far from the capture, and so is the render of
  // a map with tau doubled.
  Image images;
  ASSERT_TRUE(ReadExr(out + "/roundtrip.exr", &images).ok());
  const double render_error = RelativeRms(images, "rendered", "measured");
  const double no_layer_error = RelativeRms(images, "clean", "measured");
  std::printf("roundtrip.exr: render vs capture %.4f, clean board vs capture %.4f\n", render_error, no_layer_error);
  EXPECT_LT(render_error, 0.25 * no_layer_error);
  ScaledFit(capture + "/fit/tau", dir / "doubled", 2.0);
  RunThinslabOk("roundtrip " + capture + " --fit " + (dir / "doubled") + " --out " + (dir / "doubled_roundtrip") +
                " --samples 32 --downsample 2");
  const double doubled_error =
      Region(ReadJsonFile(dir / "doubled_roundtrip/summary.json")["regions"], "all")["render_vs_capture_relative_rms"];
  std::printf("tau doubled: render vs capture %.4f\n", doubled_error);
  EXPECT_GT(doubled_error, 3 * render_error);

  // capture | Blender | difference | predict, each tile the render's size under a label header.
  const cv::Mat png = cv::imread(out + "/roundtrip.png", cv::IMREAD_COLOR);
  ASSERT_FALSE(png.empty());
  EXPECT_EQ(png.cols, 4 * 160 + 3 * 6);
  EXPECT_EQ(png.rows, 120 + 28);
  EXPECT_TRUE(FileExists(out + "/difference.png"));
  EXPECT_TRUE(FileExists(out + "/scene/scene.py"));
  EXPECT_TRUE(FileExists(out + "/options.ini"));
}

// A laser-lobe capture (Monte Carlo layer with all orders of scattering, g 0.8, tau 0.3, albedo
// 0.3; sensor noise, 12-bit quantisation) fitted by `fit phase` (Eq. 8, single scattering) and its
// layer rendered by Blender with all orders under the capture's laser rig, by reciprocity (one
// light group per ring, export/render_scene.h LaserProbe). The rendered rings must match the
// captured ones in shape within the noise of both and what the fit's own sigma_g allows, and agree
// with predict's Eq. 8 as closely. The check can fail: a fit whose g is 0.1 lower renders far
// from the capture.
TEST(CliRoundTrip, BlenderRenderOfTheFittedLobeReproducesTheCaptureAndPredict) {
  ASSERT_EQ(std::system("command -v blender > /dev/null"), 0) << "blender is missing (scripts/install_deps.sh)";
  TempDir dir;
  const std::string capture = dir / "laser";
  RunThinslabOk("sim laser " + capture + " --camera-width-px 400 --camera-height-px 300");
  RunThinslabOk("fit phase " + capture);
  const nlohmann::json fit = ReadJsonFile(capture + "/fit/phase/summary.json");
  EXPECT_EQ(fit["layer_albedo"], 0.3);  // Given to the fit, and rendered.
  const RunResult run = RunThinslabOk("roundtrip " + capture + " --verbose");
  std::printf("%s\n", run.output.c_str());
  EXPECT_NE(run.output.find("roundtrip: Blender render (2 passes): 16384/16384"), std::string::npos) << run.output;
  const std::string out = capture + "/fit/roundtrip";
  const nlohmann::json summary = ReadJsonFile(out + "/summary.json");
  EXPECT_EQ(summary["format"], "thinslab-roundtrip-summary");
  EXPECT_EQ(summary["kind"], "laser_lobe");
  EXPECT_EQ(summary["layer"]["albedo"], 0.3);
  const nlohmann::json& bands = summary["bands"];
  ASSERT_GE(bands.size(), 2u) << bands.dump();
  for (const nlohmann::json& band : bands) {
    ASSERT_GE(band["rings"].get<int>(), 5) << band.dump();
    const double render = band["render_vs_capture_relative_rms"], predict = band["predict_vs_capture_relative_rms"],
                 between = band["render_vs_predict_relative_rms"], render_noise = band["render_noise_relative_rms"];
    const double allowed =
        std::hypot(band["noise_relative_rms"].get<double>(), render_noise, band["sigma_g_relative_rms"].get<double>());
    std::printf("%s: render vs capture %.4f, predict vs capture %.4f, render vs predict %.4f, allowed %.4f\n",
                band["band"].get<std::string>().c_str(), render, predict, between, allowed);
    // The render's own noise is small enough for the comparison to mean something.
    EXPECT_LT(render_noise, 0.02) << band.dump();
    EXPECT_LT(render, 2 * allowed) << band.dump();
    EXPECT_LT(between, 2 * allowed) << band.dump();
  }
  const nlohmann::json& all = Band(bands, "all");
  EXPECT_GT(all["rings"].get<int>(), 15) << all.dump();
  EXPECT_GT(summary["camera"]["pixels"].get<int>(), 1000) << summary["camera"].dump();
  EXPECT_LT(summary["camera"]["render_vs_capture_relative_rms"].get<double>(), 0.05) << summary["camera"].dump();

  // A fit with g 0.1 lower renders far from the capture (and still like its own Eq. 8: the
  // exported g means what the fit's g means).
  const std::string low_g = dir / "low_g";
  ASSERT_TRUE(CreateDirectories(low_g).ok());
  nlohmann::json changed = fit;
  changed["g"] = fit["g"].get<double>() - 0.1;
  ASSERT_TRUE(WriteFileAtomically(low_g + "/summary.json", changed.dump(2)).ok());
  RunThinslabOk("roundtrip " + capture + " --fit " + low_g + " --out " + (dir / "low_g_roundtrip"));
  const nlohmann::json low_summary = ReadJsonFile(dir / "low_g_roundtrip/summary.json");
  const nlohmann::json& low = Band(low_summary["bands"], "all");
  std::printf("g - 0.1: render vs capture %.4f, render vs predict %.4f\n",
              low["render_vs_capture_relative_rms"].get<double>(), low["render_vs_predict_relative_rms"].get<double>());
  EXPECT_GT(low["render_vs_capture_relative_rms"].get<double>(),
            5 * all["render_vs_capture_relative_rms"].get<double>());
  EXPECT_LT(low["render_vs_predict_relative_rms"].get<double>(),
            2 * all["render_noise_relative_rms"].get<double>() + 0.01);

  const cv::Mat png = cv::imread(out + "/roundtrip.png", cv::IMREAD_COLOR);
  ASSERT_FALSE(png.empty());
  EXPECT_EQ(png.cols, 4 * 400 + 3 * 6);
  EXPECT_TRUE(FileExists(out + "/difference.png"));
  EXPECT_TRUE(FileExists(out + "/lobe_rings.csv"));
  EXPECT_TRUE(FileExists(out + "/scene/render_lobe_2.exr"));
}

// Relative RMS of `rendered` of one dot's roundtrip image against `measured` of another's (or the
// same), over the valid pixels at >= 10 % of that measurement's peak (as the round trip counts).
double DotLobeRms(const Image& render_image, const Image& capture_image) {
  const int r = render_image.ChannelIndex("rendered"), valid = capture_image.ChannelIndex("valid"),
            m = capture_image.ChannelIndex("measured");
  double peak = 0;
  for (int y = 0; y < capture_image.height(); ++y) {
    for (int x = 0; x < capture_image.width(); ++x) {
      if (capture_image.at(x, y, valid) > 0) peak = std::max(peak, static_cast<double>(capture_image.at(x, y, m)));
    }
  }
  double err = 0, norm = 0;
  for (int y = 0; y < capture_image.height(); ++y) {
    for (int x = 0; x < capture_image.width(); ++x) {
      if (capture_image.at(x, y, valid) == 0 || capture_image.at(x, y, m) < 0.1 * peak) continue;
      err += std::pow(render_image.at(x, y, r) - capture_image.at(x, y, m), 2);
      norm += std::pow(capture_image.at(x, y, m), 2);
    }
  }
  return norm > 0 ? std::sqrt(err / norm) : -1;
}

// Sum and centroid (render pixels) of channel `name` over the valid pixels.
struct Lobe {
  double flux = 0, x = 0, y = 0;
};
Lobe LobeOf(const Image& image, const std::string& name) {
  const int c = image.ChannelIndex(name), valid = image.ChannelIndex("valid");
  Lobe lobe;
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      if (image.at(x, y, valid) == 0) continue;
      lobe.flux += image.at(x, y, c);
      lobe.x += (x + 0.5) * image.at(x, y, c);
      lobe.y += (y + 0.5) * image.at(x, y, c);
    }
  }
  lobe.x /= lobe.flux;
  lobe.y /= lobe.flux;
  return lobe;
}

// A dot scan (Monte Carlo slab tables of nine rough regions, sensor noise, quantisation) fitted by
// `fit dmf` and exported as the rough slab `thinslab export` writes (one microfacet family, the
// equivalent roughness split between the faces, a clear dielectric), rendered by Blender under the
// capture's camera and monitor, one validation dot at a time, in the capture's DN/us. What the
// render must reproduce: where each dot's light leaves the sample (the lobe's centroid), how much
// of it (the flux, as well as predict's own model does within 15 %), and the lobe's shape at the
// dot straight below the map's centre within the noise and predict's own error; elsewhere the
// export's approximations show (docs/export.md), and the test bounds them by the comparison's
// power: each render's mismatch beyond the noise is under half of its mismatch with another dot's
// capture.
TEST(CliRoundTrip, BlenderRenderOfTheFittedSlabUnderTheDotScanRig) {
  ASSERT_EQ(std::system("command -v blender > /dev/null"), 0) << "blender is missing (scripts/install_deps.sh)";
  TempDir dir;
  const std::string capture = dir / "dots";
  RunThinslabOk("sim dot-scan " + capture + " --grid-nx 10 --grid-ny 10 --validation-dots 3");
  RunThinslabOk("fit dmf " + capture);
  const RunResult run = RunThinslabOk("roundtrip " + capture + " --downsample 6 --samples 4096");
  std::printf("%s\n", run.output.c_str());
  const std::string out = capture + "/fit/roundtrip";
  const nlohmann::json summary = ReadJsonFile(out + "/summary.json");
  EXPECT_EQ(summary["kind"], "dot_scan");
  const nlohmann::json& dots = summary["dots"];
  ASSERT_EQ(dots.size(), 3u) << dots.dump();
  std::vector<Image> images(dots.size());
  for (size_t k = 0; k < dots.size(); ++k) {
    ASSERT_TRUE(ReadExr(out + "/" + dots[k]["file"].get<std::string>(), &images[k]).ok());
    EXPECT_TRUE(FileExists(out + "/roundtrip_dot" + std::to_string(k) + ".png"));
  }
  for (size_t k = 0; k < dots.size(); ++k) {
    const nlohmann::json& render = dots[k]["render_vs_capture"];
    const double own = render["relative_rms"], noise = render["noise_relative_rms"],
                 predict = dots[k]["predict_vs_capture"]["relative_rms"];
    ASSERT_GT(render["pixels"].get<int>(), 30) << dots[k].dump();
    const Lobe rendered = LobeOf(images[k], "rendered"), measured = LobeOf(images[k], "measured"),
               predicted = LobeOf(images[k], "predicted");
    std::printf(
        "dot %zu: render vs capture %.4f (noise %.4f, predict %.4f); flux render/capture %.3f, "
        "predict/capture %.3f; centroid offset %.2f px\n",
        k, own, noise, predict, rendered.flux / measured.flux, predicted.flux / measured.flux,
        std::hypot(rendered.x - measured.x, rendered.y - measured.y));
    EXPECT_LT(std::hypot(rendered.x - measured.x, rendered.y - measured.y), 0.5) << dots[k].dump();
    EXPECT_LT(std::abs(std::log(rendered.flux / measured.flux)),
              std::abs(std::log(predicted.flux / measured.flux)) + 0.15)
        << dots[k].dump();
    for (size_t j = 0; j < dots.size(); ++j) {
      if (j == k) continue;
      const double other = DotLobeRms(images[k], images[j]);
      std::printf("  render of dot %zu against the capture of dot %zu: %.4f\n", k, j, other);
      EXPECT_GT(other, 2 * std::sqrt(std::max(0.0, own * own - noise * noise))) << dots[k].dump();
    }
    if (dots[k]["dot_px"][0] == 200.5 && dots[k]["dot_px"][1] == 200.5) {  // Below the map's centre.
      EXPECT_LT(own, 1.5 * std::hypot(noise, predict)) << dots[k].dump();
    }
  }
}

TEST(CliRoundTrip, RefusesWhatItCannotRenderByName) {
  TempDir dir;
  const std::string capture = dir / "capture";
  RunThinslabOk("sim shadow-maps " + capture + " --camera-width-px 64 --camera-height-px 48 --photons 2000 --frames 1");
  RunResult r = RunThinslab("roundtrip " + capture);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("fit tau"), std::string::npos) << r.output;
  RunThinslabOk("fit tau " + capture);
  r = RunThinslab("roundtrip " + capture + " --blender /nonexistent/blender");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--blender: cannot run '/nonexistent/blender'"), std::string::npos) << r.output;
  EXPECT_FALSE(FileExists(capture + "/fit/roundtrip"));
  r = RunThinslab("roundtrip " + capture + " --downsample 16");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--downsample 16"), std::string::npos) << r.output;
  r = RunThinslab("roundtrip " + capture + " --samples -1");
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("--samples"), std::string::npos) << r.output;
  // A laser-lobe capture without its `fit phase`.
  const std::string laser = dir / "laser";
  RunThinslabOk("sim laser " + laser + " --camera-width-px 80 --camera-height-px 60 --photons 2000");
  r = RunThinslab("roundtrip " + laser);
  EXPECT_NE(r.exit_code, 0);
  EXPECT_NE(r.output.find("`thinslab fit phase`"), std::string::npos) << r.output;
  EXPECT_FALSE(FileExists(laser + "/fit/roundtrip"));
}

}  // namespace
}  // namespace thinslab
