// SPDX-License-Identifier: Apache-2.0
// The pictures a person reads (issue #26 item 5): a named legend for categories, a diverging
// scale with white at zero for signed values, a scale bar in mm, and the CSV behind a chart.
#include "thinslab/core/false_color.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>
#include <string>

#include "thinslab/core/file.h"
#include "thinslab/core/plot.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

constexpr int kMargin = 10;  // core/false_color.cc draws the map at (10, 10).

cv::Vec3b MapPixel(const cv::Mat& png, int x, int y, int scale) {
  return png.at<cv::Vec3b>(kMargin + y * scale + scale / 2, kMargin + x * scale + scale / 2);
}

TEST(FalseColor, CategoriesGetDistinctNamedColors) {
  TempDir dir;
  Image status(4, 1, {"status"});
  for (int x = 0; x < 4; ++x) status.at(x, 0) = static_cast<float>(x);
  status.at(3, 0) = 9;  // Not a named code: grey.
  FalseColorOptions o;
  o.scale_kind = ColorScale::kCategorical;
  o.category_names = {"ok", "dark", "saturated"};
  o.scale = 8;
  const std::string path = dir / "status.png";
  ASSERT_TRUE(WriteFalseColorPng(path, status, 0, nullptr, o).ok());
  const cv::Mat png = cv::imread(path);
  ASSERT_FALSE(png.empty());
  EXPECT_NE(MapPixel(png, 0, 0, 8), MapPixel(png, 1, 0, 8));
  EXPECT_NE(MapPixel(png, 1, 0, 8), MapPixel(png, 2, 0, 8));
  EXPECT_EQ(MapPixel(png, 3, 0, 8), cv::Vec3b(128, 128, 128));
  o.category_names.clear();
  EXPECT_FALSE(WriteFalseColorPng(path, status, 0, nullptr, o).ok());
}

TEST(FalseColor, SignedValuesAreWhiteAtZeroAndOppositeHuesEitherSide) {
  TempDir dir;
  Image error(3, 1, {"error"});
  error.at(0, 0) = -0.1f;
  error.at(1, 0) = 0.0f;
  error.at(2, 0) = 0.05f;
  FalseColorOptions o;
  o.scale_kind = ColorScale::kDiverging;
  o.max_value = 0.1;
  o.scale = 8;
  const std::string path = dir / "error.png";
  ASSERT_TRUE(WriteFalseColorPng(path, error, 0, nullptr, o).ok());
  const cv::Mat png = cv::imread(path);
  const cv::Vec3b negative = MapPixel(png, 0, 0, 8), zero = MapPixel(png, 1, 0, 8), positive = MapPixel(png, 2, 0, 8);
  EXPECT_EQ(zero, cv::Vec3b(247, 247, 247));
  EXPECT_GT(negative[0], negative[2]);  // Blue (BGR).
  EXPECT_GT(positive[2], positive[0]);  // Red.
}

TEST(FalseColor, ScaleBarInMillimetres) {
  TempDir dir;
  const Image flat(100, 60, {"tau"}, 0.5f);
  FalseColorOptions o;
  o.scale = 2;
  const std::string with = dir / "with.png", without = dir / "without.png";
  ASSERT_TRUE(WriteFalseColorPng(without, flat, 0, nullptr, o).ok());
  o.pixel_pitch_m = 1e-4;  // 10 mm wide: a 2 mm bar, 20 map pixels = 40 canvas pixels.
  ASSERT_TRUE(WriteFalseColorPng(with, flat, 0, nullptr, o).ok());
  const cv::Mat a = cv::imread(with), b = cv::imread(without);
  const int bar_y = kMargin + 120 - 10;  // DrawScaleBar: 10 px above the map's bottom.
  int white = 0;
  for (int x = kMargin; x < kMargin + 200; ++x) white += a.at<cv::Vec3b>(bar_y, x) == cv::Vec3b(255, 255, 255);
  EXPECT_EQ(white, 40);
  EXPECT_NE(b.at<cv::Vec3b>(bar_y, kMargin + 20), cv::Vec3b(255, 255, 255));
}

TEST(Plot, WritesTheDataBesideTheChart) {
  TempDir dir;
  PlotSeries s;
  s.x = {1, 2};
  s.y = {3, 4.5};
  s.y_error = {0.1, 0.2};
  s.label = "measured, ring";
  PlotPanel panel;
  panel.series = {s};
  panel.y_label = "L";
  const std::string path = dir / "lobe.png";
  ASSERT_TRUE(WritePlotPng(path, {panel}, PlotOptions()).ok());
  std::string csv;
  ASSERT_TRUE(ReadFileToString(dir / "lobe_data.csv", &csv).ok());
  EXPECT_NE(csv.find("panel,y_label,series,x,y,y_error\n"), std::string::npos) << csv;
  EXPECT_NE(csv.find("0,\"L\",\"measured, ring\",2,4.5,0.2\n"), std::string::npos) << csv;
}

}  // namespace
}  // namespace thinslab
