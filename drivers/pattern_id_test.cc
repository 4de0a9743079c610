// SPDX-License-Identifier: Apache-2.0
#include "thinslab/drivers/pattern_id.h"

#include <gtest/gtest.h>

#include <cmath>

namespace thinslab {
namespace {

void Centroid(const Image& image, double* cx, double* cy, double* sum) {
  double s = 0, sx = 0, sy = 0;
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) {
      const double v = image.at(x, y);
      s += v;
      sx += v * (x + 0.5);
      sy += v * (y + 0.5);
    }
  }
  *cx = sx / s;
  *cy = sy / s;
  *sum = s;
}

TEST(PatternIdTest, ParsesEveryForm) {
  PatternSpec spec;
  ASSERT_TRUE(ParsePatternId("", &spec).ok());
  EXPECT_EQ(spec.kind, PatternSpec::Kind::kBlack);
  ASSERT_TRUE(ParsePatternId("flat", &spec).ok());
  EXPECT_EQ(spec.kind, PatternSpec::Kind::kFlat);
  EXPECT_EQ(spec.level, 1.0);
  ASSERT_TRUE(ParsePatternId("flat:0.25", &spec).ok());
  EXPECT_EQ(spec.level, 0.25);
  ASSERT_TRUE(ParsePatternId("dot:10.5,20.25", &spec).ok());
  EXPECT_EQ(spec.kind, PatternSpec::Kind::kDots);
  ASSERT_EQ(spec.dots.size(), 1u);
  EXPECT_EQ(spec.dots[0].x_px, 10.5);
  EXPECT_EQ(spec.dots[0].y_px, 20.25);
  ASSERT_TRUE(ParsePatternId("dots:5,6,10,20,3,2", &spec).ok());
  ASSERT_EQ(spec.dots.size(), 6u);
  EXPECT_EQ(spec.dots[4].x_px, 15);  // i = 1, j = 1
  EXPECT_EQ(spec.dots[4].y_px, 26);
}

TEST(PatternIdTest, RejectsMalformedIdsWithTheField) {
  PatternSpec spec;
  Status s = ParsePatternId("flat:1.5", &spec);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("flat:1.5"), std::string::npos);
  EXPECT_NE(s.message().find("[0, 1]"), std::string::npos);
  s = ParsePatternId("dot:3", &spec);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("expects 2"), std::string::npos);
  s = ParsePatternId("dot:3,x", &spec);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("field 2"), std::string::npos);
  EXPECT_FALSE(ParsePatternId("dot:3,nan", &spec).ok());
  EXPECT_FALSE(ParsePatternId("dot:3, 4", &spec).ok());
  EXPECT_FALSE(ParsePatternId("dots:0,0,1,1,2.5,1", &spec).ok());
  EXPECT_FALSE(ParsePatternId("dots:0,0,1,1,0,1", &spec).ok());
  s = ParsePatternId("stripes:4", &spec);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.message().find("unknown pattern \"stripes\""), std::string::npos);
}

TEST(PatternIdTest, FormattedIdsRoundTrip) {
  PatternSpec spec;
  const double x = 123.456789012345, y = 0.1;
  ASSERT_TRUE(ParsePatternId(DotPatternId(x, y), &spec).ok());
  EXPECT_EQ(spec.dots[0].x_px, x);
  EXPECT_EQ(spec.dots[0].y_px, y);
  ASSERT_TRUE(ParsePatternId(FlatPatternId(1.0 / 3.0), &spec).ok());
  EXPECT_EQ(spec.level, 1.0 / 3.0);
}

// The anti-aliased dot's total equals the disc area and its intensity centroid is the requested
// sub-pixel centre, for radii from 1 to 4 px and arbitrary fractional offsets.
TEST(PatternIdTest, DotCentroidAndAreaAreExact) {
  const double pi = std::acos(-1.0);
  double worst = 0;
  for (double r : {1.0, 1.5, 2.0, 3.3, 4.0}) {
    for (double fx : {0.0, 0.13, 0.5, 0.77}) {
      for (double fy : {0.0, 0.31, 0.5, 0.94}) {
        PatternSpec spec;
        const double x = 20 + fx, y = 17 + fy;
        ASSERT_TRUE(ParsePatternId(DotPatternId(x, y), &spec).ok());
        Image image;
        ASSERT_TRUE(RasterizePattern(spec, 40, 36, r, &image).ok());
        double cx, cy, sum;
        Centroid(image, &cx, &cy, &sum);
        EXPECT_NEAR(sum, pi * r * r, 1e-5 * pi * r * r) << r;
        worst = std::max({worst, std::abs(cx - x), std::abs(cy - y)});
      }
    }
  }
  // Tent-kernel sampling preserves the first moments; only the quadrature error remains
  // (measured 1.6e-8 px; a box kernel would give 0.02 px here).
  EXPECT_LT(worst, 1e-4);
  RecordProperty("worst_centroid_error_px", std::to_string(worst));
}

TEST(PatternIdTest, FlatBlackAndClippedDots) {
  PatternSpec spec;
  Image image;
  ASSERT_TRUE(ParsePatternId("flat:0.5", &spec).ok());
  ASSERT_TRUE(RasterizePattern(spec, 4, 3, 2, &image).ok());
  for (float v : image.data()) EXPECT_EQ(v, 0.5f);
  ASSERT_TRUE(ParsePatternId("", &spec).ok());
  ASSERT_TRUE(RasterizePattern(spec, 4, 3, 2, &image).ok());
  for (float v : image.data()) EXPECT_EQ(v, 0.0f);
  // A dot on the corner is clipped to the quarter inside the image; one far away draws nothing.
  ASSERT_TRUE(ParsePatternId("dots:0,0,1000,1000,2,1", &spec).ok());
  ASSERT_TRUE(RasterizePattern(spec, 10, 10, 3, &image).ok());
  double s = 0;
  for (float v : image.data()) s += v;
  EXPECT_NEAR(s, std::acos(-1.0) * 9 / 4, 0.01);
  EXPECT_FALSE(RasterizePattern(spec, 0, 10, 3, &image).ok());
  EXPECT_FALSE(RasterizePattern(spec, 10, 10, 0, &image).ok());
  EXPECT_FALSE(RasterizePattern(spec, 10, 10, 1e9, &image).ok());
  // Coordinates far outside int range draw nothing (and are no undefined behaviour).
  ASSERT_TRUE(ParsePatternId("dots:-1e300,1e300,1,1,2,2", &spec).ok());
  ASSERT_TRUE(RasterizePattern(spec, 10, 10, 3, &image).ok());
  for (float v : image.data()) EXPECT_EQ(v, 0.0f);
}

// A grid shares one stamp per sub-pixel phase; every dot of it must equal a single-dot raster.
TEST(PatternIdTest, GridDotsEqualSingleDots) {
  PatternSpec grid, single;
  ASSERT_TRUE(ParsePatternId("dots:10.3,12.7,20,15.5,3,2", &grid).ok());
  Image g, one;
  ASSERT_TRUE(RasterizePattern(grid, 80, 50, 2.5, &g).ok());
  Image sum(80, 50, 0.0f);
  for (const PatternSpec::Dot& d : grid.dots) {
    ASSERT_TRUE(ParsePatternId(DotPatternId(d.x_px, d.y_px), &single).ok());
    ASSERT_TRUE(RasterizePattern(single, 80, 50, 2.5, &one).ok());
    for (size_t i = 0; i < one.data().size(); ++i) sum.data()[i] += one.data()[i];
  }
  double total = 0;
  for (size_t i = 0; i < g.data().size(); ++i) {
    EXPECT_NEAR(g.data()[i], sum.data()[i], 1e-6) << i;
    total += g.data()[i];
  }
  EXPECT_NEAR(total, 6 * std::acos(-1.0) * 2.5 * 2.5, 1e-3);
}

}  // namespace
}  // namespace thinslab
