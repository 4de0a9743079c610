// SPDX-License-Identifier: Apache-2.0
// `thinslab export` (issue #27) on fit folders written here in the documented formats
// (docs/format.md 9.2 and 9.5; export is a change of format, so hand-made maps with known values
// test it exactly): the roughness split, the family vote, the textures' values and orientation,
// the Mitsuba .vol grid, pbrt's density array, and the Blender script run by Debian's Blender
// (the texture it looks up at the grid's corner, a small render).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "tests/testing/temp_dir.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/provenance.h"
#include "thinslab/export/export_run.h"
#include "thinslab/export/mitsuba_scene.h"
#include "thinslab/export/scene_from_fit.h"

namespace thinslab {
namespace {

constexpr int kWidth = 6, kHeight = 4;
constexpr double kPitchM = 1e-3;

std::string ReadText(const std::string& path) {
  std::string text;
  EXPECT_TRUE(ReadFileToString(path, &text).ok()) << path;
  return text;
}

size_t Count(const std::string& text, const std::string& piece) {
  size_t n = 0;
  for (size_t at = text.find(piece); at != std::string::npos; at = text.find(piece, at + 1)) ++n;
  return n;
}

Provenance TestProvenance(const std::string& command) { return Provenance{command, "test", "", ""}; }

// A `fit dmf` folder: roughness 0.1 + 0.05 col (GGX left of col 4, Beckmann right, 2 : 1 GGX),
// top-face weight row / 3, nothing fitted at (0, 0).
void WriteDmfFit(const std::string& dir) {
  ASSERT_TRUE(CreateDirectories(dir).ok());
  Image maps(kWidth, kHeight, {"top_face_weight", "smith_alpha", "equivalent_roughness", "ndf_family", "status"});
  for (int row = 0; row < kHeight; ++row) {
    for (int col = 0; col < kWidth; ++col) {
      const bool fitted = !(row == 0 && col == 0);
      maps.at(col, row, 0) = static_cast<float>(row / 3.0);
      maps.at(col, row, 1) = 0.2f;
      maps.at(col, row, 2) = fitted ? static_cast<float>(0.1 + 0.05 * col) : 0.0f;
      maps.at(col, row, 3) = fitted ? (col < 4 ? 0.0f : 1.0f) : 2.0f;
      maps.at(col, row, 4) = fitted ? 0.0f : 4.0f;
    }
  }
  maps.numeric_attributes()["grid_min_m"] = {-0.003, -0.002};
  maps.numeric_attributes()["pixel_pitch_m"] = {kPitchM};
  maps.numeric_attributes()["eta"] = {1.52};
  Rigid3d cam_from_sample =
      LookAt(Eigen::Vector3d(0.001, -0.02, 0.1), Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 1, 0));
  SetWorldToCamera(cam_from_sample, &maps);
  ASSERT_TRUE(
      WriteMapExr(JoinPath(dir, "maps.exr"), maps, {"smith_alpha", {"ndf_family", "status"}}, TestProvenance("fit dmf"))
          .ok());
  const nlohmann::json summary = {
      {"format", "thinslab-fit-summary"},
      {"model", "dai2009_dual_microfacet"},
      {"glass_thickness_m", 0.0},
      {"monitor", {{"sample_from_monitor", {{"rotation_wxyz", {1, 0, 0, 0}}, {"translation_m", {0, 0, -0.04}}}}}}};
  ASSERT_TRUE(WriteFileAtomically(JoinPath(dir, "summary.json"), summary.dump(2)).ok());
}

// A `fit tau` folder: tau = 0.1 (col + 1) + row, layer g 0.7, albedo 0.4.
void WriteTauFit(const std::string& dir) {
  ASSERT_TRUE(CreateDirectories(dir).ok());
  Image map(kWidth, kHeight, {"tau", "status"});
  for (int row = 0; row < kHeight; ++row) {
    for (int col = 0; col < kWidth; ++col) map.at(col, row, 0) = static_cast<float>(0.1 * (col + 1) + row);
  }
  map.numeric_attributes()["region_min_m"] = {0.0, 0.0};
  map.numeric_attributes()["region_max_m"] = {kWidth * kPitchM, kHeight * kPitchM};
  map.numeric_attributes()["pixel_pitch_m"] = {kPitchM};
  ASSERT_TRUE(WriteMapExr(JoinPath(dir, "tau.exr"), map, {"tau", {"status"}}, TestProvenance("fit tau")).ok());
  const nlohmann::json summary = {{"format", "thinslab-fit-summary"}, {"layer", {{"albedo", 0.4}, {"g", 0.7}}}};
  ASSERT_TRUE(WriteFileAtomically(JoinPath(dir, "summary.json"), summary.dump(2)).ok());
}

TEST(SplitRoughness, KeepsTheLobeWidthAndPutsAOneSidedRoughnessOnItsFace) {
  double top, bottom;
  SplitRoughness(0.3, 0.25, 1e-3, &top, &bottom);
  EXPECT_NEAR(top * top + bottom * bottom, 0.09, 1e-12);
  EXPECT_NEAR(top, 0.15, 1e-12);
  SplitRoughness(0.3, 1.0, 1e-3, &top, &bottom);
  EXPECT_DOUBLE_EQ(top, 0.3);
  EXPECT_DOUBLE_EQ(bottom, 1e-3);                  // The floor: renderers divide by alpha.
  SplitRoughness(0.3, -0.2, 1e-3, &top, &bottom);  // A weight outside [0, 1] is clamped.
  EXPECT_DOUBLE_EQ(top, 1e-3);
  EXPECT_DOUBLE_EQ(bottom, 0.3);
}

TEST(SceneFromFit, DmfFitBecomesASlabWithTheSplitRoughnessAndTheMajorityFamily) {
  TempDir tmp;
  WriteDmfFit(tmp / "dmf");
  RenderScene scene;
  ASSERT_TRUE(SceneFromFit(tmp / "dmf", ExportOptions(), &scene).ok());
  ASSERT_TRUE(scene.slab.has_value());
  EXPECT_FALSE(scene.layer.has_value());
  EXPECT_EQ(scene.slab->distribution, "ggx");  // 15 GGX points against 8 Beckmann.
  EXPECT_DOUBLE_EQ(scene.slab->eta, 1.52);
  EXPECT_DOUBLE_EQ(scene.slab->thickness_m, 1e-3);  // The fit's 0 becomes 1 mm, with a note.
  EXPECT_DOUBLE_EQ(scene.backlight_distance_m, 0.04);
  EXPECT_EQ(scene.grid.width, kWidth);
  EXPECT_NEAR(scene.grid.min_m.x(), -0.003, 1e-12);
  for (int row = 0; row < kHeight; ++row) {
    for (int col = 0; col < kWidth; ++col) {
      double top = 1e-3, bottom = 1e-3;
      if (row != 0 || col != 0) SplitRoughness(0.1 + 0.05 * col, row / 3.0, 1e-3, &top, &bottom);
      EXPECT_NEAR(scene.slab->top_alpha.at(col, row), top, 1e-6) << col << "," << row;
      EXPECT_NEAR(scene.slab->bottom_alpha.at(col, row), bottom, 1e-6) << col << "," << row;
    }
  }
  // The rig camera's pose, framing the whole grid.
  const SceneCamera camera = CameraOf(scene);
  EXPECT_NEAR((camera.eye - Eigen::Vector3d(0.001, -0.02, 0.1)).norm(), 0, 1e-7);  // worldToCamera is m44f.
  EXPECT_GT(scene.fov_x_rad, 0.02);
  EXPECT_LT(scene.fov_x_rad, 0.2);
  bool thickness_note = false;
  for (const std::string& note : scene.notes) thickness_note |= note.find("1 mm") != std::string::npos;
  EXPECT_TRUE(thickness_note);

  ExportOptions options;
  options.slab_thickness_mm = 2;
  ASSERT_TRUE(SceneFromFit(tmp / "dmf", options, &scene).ok());
  EXPECT_DOUBLE_EQ(scene.slab->thickness_m, 2e-3);
}

TEST(SceneFromFit, TauFitBecomesALayerWithTheFitsGAndAlbedoUnlessGiven) {
  TempDir tmp;
  WriteTauFit(tmp / "tau");
  RenderScene scene;
  ASSERT_TRUE(SceneFromFit(tmp / "tau", ExportOptions(), &scene).ok());
  ASSERT_TRUE(scene.layer.has_value());
  EXPECT_DOUBLE_EQ(scene.layer->g, 0.7);
  EXPECT_DOUBLE_EQ(scene.layer->albedo, 0.4);
  EXPECT_NEAR(scene.layer->tau.at(2, 3), 3.3, 1e-6);
  ExportOptions options;
  options.g = 0.2;
  ASSERT_TRUE(SceneFromFit(tmp / "tau", options, &scene).ok());
  EXPECT_DOUBLE_EQ(scene.layer->g, 0.2);
  EXPECT_DOUBLE_EQ(scene.layer->albedo, 0.4);
}

TEST(SceneFromFit, BadInputNamesTheFileFieldOrOption) {
  TempDir tmp;
  RenderScene scene;
  Status status = SceneFromFit(tmp / "absent", ExportOptions(), &scene);
  EXPECT_NE(status.message().find("absent: not a folder"), std::string::npos) << status.message();
  ASSERT_TRUE(CreateDirectories(tmp / "empty").ok());
  status = SceneFromFit(tmp / "empty", ExportOptions(), &scene);
  EXPECT_NE(status.message().find("holds no maps.exr"), std::string::npos) << status.message();
  WriteTauFit(tmp / "tau");
  ASSERT_TRUE(WriteFileAtomically(tmp / "tau/summary.json", "{\"format\": \"thinslab-fit-summary\"}").ok());
  status = SceneFromFit(tmp / "tau", ExportOptions(), &scene);
  EXPECT_NE(status.message().find("layer.g and layer.albedo are missing"), std::string::npos) << status.message();
  ExportOptions options;
  options.min_alpha = 0;
  status = SceneFromFit(tmp / "tau", options, &scene);
  EXPECT_NE(status.message().find("ExportOptions::min_alpha (--min-alpha)"), std::string::npos) << status.message();
  options = ExportOptions();
  options.albedo = 1.5;
  status = SceneFromFit(tmp / "tau", options, &scene);
  EXPECT_NE(status.message().find("ExportOptions::albedo"), std::string::npos) << status.message();
}

TEST(ExportFit, MitsubaSceneReferencesTexturesThatHoldTheMapsAndAVolumeOfSigmaT) {
  TempDir tmp;
  WriteDmfFit(tmp / "dmf");
  ASSERT_TRUE(ExportFit({"mitsuba", tmp / "dmf", tmp / "out", ExportOptions(), "a = 1\n"}, std::cout).ok());
  const std::string xml = ReadText(tmp / "out/scene.xml");
  EXPECT_EQ(Count(xml, "<bsdf type=\"roughdielectric\">"), 2u);
  EXPECT_EQ(Count(xml, "<string name=\"distribution\" value=\"ggx\"/>"), 2u);
  EXPECT_EQ(Count(xml, "<boolean name=\"flip_normals\" value=\"true\"/>"), 1u);  // The monitor-side face.
  EXPECT_NE(xml.find("value=\"textures/top_alpha.exr\""), std::string::npos);
  EXPECT_EQ(Count(xml, "<shape "), Count(xml, "</shape>"));
  EXPECT_EQ(Count(xml, "--"), 2 * Count(xml, "<!--"));  // No "--" inside a comment.
  Image top;
  ASSERT_TRUE(ReadExr(tmp / "out/textures/top_alpha.exr", &top).ok());
  RenderScene scene;
  ASSERT_TRUE(SceneFromFit(tmp / "dmf", ExportOptions(), &scene).ok());
  ASSERT_EQ(top.width(), kWidth);
  for (int row = 0; row < kHeight; ++row) {
    for (int col = 0; col < kWidth; ++col) EXPECT_EQ(top.at(col, row), scene.slab->top_alpha.at(col, row));
  }
  const nlohmann::json summary = nlohmann::json::parse(ReadText(tmp / "out/export.json"));
  EXPECT_EQ(summary["format"], "thinslab-export-summary");
  EXPECT_EQ(summary["slab"]["distribution"], "ggx");
  EXPECT_EQ(summary["provenance"]["options_digest"], OptionsDigest("a = 1\n"));

  WriteTauFit(tmp / "tau");
  ASSERT_TRUE(ExportFit({"mitsuba", tmp / "tau", tmp / "layer", ExportOptions(), ""}, std::cout).ok());
  const std::string vol = ReadText(tmp / "layer/layer_sigma_t.vol");
  ASSERT_EQ(vol.size(), 48u + 4u * kWidth * kHeight * 2);
  EXPECT_EQ(vol.substr(0, 3), "VOL");
  int32_t header[5];
  std::memcpy(header, vol.data() + 4, sizeof(header));
  EXPECT_EQ(header[0], 1);  // float32
  EXPECT_EQ(header[1], kWidth);
  EXPECT_EQ(header[2], kHeight);
  EXPECT_EQ(header[3], 2);
  float voxel;  // (x 2, y 3, z 1): tau 3.3 over the default 0.1 mm.
  std::memcpy(&voxel, vol.data() + 48 + 4 * ((1 * kHeight + 3) * kWidth + 2), sizeof(voxel));
  EXPECT_NEAR(voxel, 3.3 / 1e-4, 0.01);
  EXPECT_NE(ReadText(tmp / "layer/scene.xml").find("<phase type=\"hg\">\n      <float name=\"g\" value=\"0.7\"/>"),
            std::string::npos);
}

TEST(ExportFit, PbrtSceneHasTheDensityGridAndNotesABeckmannFit) {
  TempDir tmp;
  WriteTauFit(tmp / "tau");
  ASSERT_TRUE(ExportFit({"pbrt", tmp / "tau", tmp / "out", ExportOptions(), ""}, std::cout).ok());
  const std::string pbrt = ReadText(tmp / "out/scene.pbrt");
  const size_t density = pbrt.find("\"float density\" [");
  ASSERT_NE(density, std::string::npos);
  std::istringstream values(pbrt.substr(density + 17, pbrt.find(']', density) - density - 17));
  std::vector<double> numbers;
  for (double v; values >> v;) numbers.push_back(v);
  ASSERT_EQ(numbers.size(), static_cast<size_t>(kWidth * kHeight * 2));
  EXPECT_NEAR(numbers[3 * kWidth + 2], 3.3, 1e-6);  // Row 3, col 2: y grows with the index, as p0 -> p1.
  EXPECT_NE(pbrt.find("\"float g\" [ 0.7 ]"), std::string::npos);
  EXPECT_EQ(Count(pbrt, "AttributeBegin"), Count(pbrt, "AttributeEnd"));
  EXPECT_EQ(Count(pbrt, "\"") % 2, 0u);

  // A dmf fit voted Beckmann: pbrt-v4 has GGX only, and the file says so.
  WriteDmfFit(tmp / "dmf");
  Image maps;
  ASSERT_TRUE(ReadExr(tmp / "dmf/maps.exr", &maps).ok());
  for (int row = 0; row < kHeight; ++row) {
    for (int col = 0; col < kWidth; ++col) maps.at(col, row, maps.ChannelIndex("ndf_family")) = 1;
  }
  ASSERT_TRUE(
      WriteMapExr(tmp / "dmf/maps.exr", maps, {"smith_alpha", {"ndf_family", "status"}}, TestProvenance("fit dmf"))
          .ok());
  ASSERT_TRUE(ExportFit({"pbrt", tmp / "dmf", tmp / "slab", ExportOptions(), ""}, std::cout).ok());
  const std::string slab = ReadText(tmp / "slab/scene.pbrt");
  EXPECT_NE(slab.find("only Trowbridge-Reitz (GGX): the beckmann alpha maps are used as GGX alpha"), std::string::npos);
  EXPECT_EQ(Count(slab, "\"texture roughness\""), 2u);
  EXPECT_EQ(Count(slab, "\"bool remaproughness\" false"), 2u);
}

TEST(ExportFit, RefusesAnUnknownRendererAndAnOutputInsideTheFit) {
  TempDir tmp;
  WriteDmfFit(tmp / "dmf");
  Status status = ExportFit({"povray", tmp / "dmf", tmp / "out", ExportOptions(), ""}, std::cout);
  EXPECT_NE(status.message().find("'povray' is not one of mitsuba, pbrt, blender"), std::string::npos);
  status = ExportFit({"pbrt", tmp / "dmf", tmp / "dmf/scene", ExportOptions(), ""}, std::cout);
  EXPECT_FALSE(status.ok());
  EXPECT_FALSE(FileExists(tmp / "dmf/scene/scene.pbrt"));
}

// Debian's Blender runs the script: the scene's objects, the texture texel the camera-side face
// shows at the grid's (min x, min y) corner, and a small Cycles render.
TEST(ExportFit, BlenderBuildsTheSceneLooksUpTheRightTexelAndRenders) {
  ASSERT_EQ(std::system("command -v blender > /dev/null"), 0) << "blender is missing (scripts/install_deps.sh)";
  TempDir tmp;
  WriteDmfFit(tmp / "dmf");
  ASSERT_TRUE(ExportFit({"blender", tmp / "dmf", tmp / "out", ExportOptions(), ""}, std::cout).ok());
  RenderScene scene;
  ASSERT_TRUE(SceneFromFit(tmp / "dmf", ExportOptions(), &scene).ok());
  // The texel under the centre of map point (1, 0), next to the (min x, min y) corner, looked up
  // through the face's uv the way Cycles does (image rows from the bottom).
  const std::string probe = tmp / "probe.py";
  std::ofstream(probe)
      << "import bpy\n"
         "obj = bpy.data.objects['slab_camera_side']\n"
         "mesh = obj.data\n"
         "uv = mesh.uv_layers.active.data\n"
         "xs = [v.co.x for v in mesh.vertices]; ys = [v.co.y for v in mesh.vertices]\n"
         "w, h = max(xs) - min(xs), max(ys) - min(ys)\n"
         "loop = min(range(len(mesh.loops)), key=lambda k: mesh.vertices[mesh.loops[k].vertex_index].co.x"
         " + mesh.vertices[mesh.loops[k].vertex_index].co.y)\n"
         "u0, v0 = uv[loop].uv\n"
         "du = 1.5 * "
      << kPitchM << " / w; dv = 0.5 * " << kPitchM
      << " / h\n"
         "u, v = u0 + du, v0 - dv if v0 > 0.5 else v0 + dv\n"
         "node = [n for n in obj.material_slots[0].material.node_tree.nodes if n.type == 'TEX_IMAGE'][0]\n"
         "image = node.image\n"
         "col, row = int(u * image.size[0]), int(v * image.size[1])\n"
         "value = image.pixels[4 * (row * image.size[0] + col)]\n"
         "print('probe texel %.6f' % value)\n";
  const std::string log = tmp / "blender.log";
  const std::string command = "cd '" + tmp.path() +
                              "' && blender -b --factory-startup --python out/scene.py --python probe.py "
                              "-- --save scene.blend --render render.png --samples 4 --resolution-percent 10 > '" +
                              log + "' 2>&1";
  const int code = std::system(command.c_str());
  const std::string output = ReadText(log);
  ASSERT_EQ(code, 0) << output;
  EXPECT_NE(output.find("thinslab scene: backlight, camera, slab_camera_side, slab_monitor_side"), std::string::npos)
      << output;
  EXPECT_EQ(output.find("Error"), std::string::npos) << output;
  const size_t at = output.find("probe texel ");
  ASSERT_NE(at, std::string::npos) << output;
  // Point (1, 0) is rough on the camera side (weight 0); (1, 3), where a flipped v would land,
  // is smooth there (weight 1).
  EXPECT_NEAR(std::stod(output.substr(at + 12)), scene.slab->bottom_alpha.at(1, 0), 1e-6) << output;
  EXPECT_GT(scene.slab->bottom_alpha.at(1, 0), 10 * scene.slab->bottom_alpha.at(1, kHeight - 1));
  EXPECT_TRUE(FileExists(tmp / "scene.blend"));
  EXPECT_TRUE(FileExists(tmp / "render.png"));
}

}  // namespace
}  // namespace thinslab
