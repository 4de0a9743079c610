// SPDX-License-Identifier: Apache-2.0
// Slices of one material seen from different sample points are one shape on the u grid
// (fit/dmf_slice_shape.h) and different vectors when indexed by dot.
#include "thinslab/fit/dmf_slice_shape.h"

#include <gtest/gtest.h>

#include <cmath>

#include "thinslab/fit/single_interface_fit.h"

namespace thinslab {
namespace {

// The slice a point at sample-plane position x (metres, optical frame z = 0) records of a slab
// with a GGX 0.3 rough top, from a 20 x 20 dot grid 96 mm wide on the plane z = 0.04 m (optical
// frame: the light side), centred on the straight-through direction of a camera 1 m away at 45
// degrees; every other dot trains.
DmfSlice SliceAt(const Eigen::Vector2d& x) {
  SingleInterfaceFit material;
  material.ok = true;
  material.alpha = 0.3;
  material.k_s = 1;
  const Eigen::Vector3d point(x.x(), x.y(), 0), camera(0, 0.71, -0.71);
  DmfSlice slice;
  slice.o = (camera - point).normalized();
  for (int iy = 0; iy < 20; ++iy) {
    for (int ix = 0; ix < 20; ++ix) {
      const Eigen::Vector3d dot(-0.048 + ix * 0.096 / 19, -0.048 - 0.04 + iy * 0.096 / 19, 0.04);
      slice.i.push_back((dot - point).normalized());
      slice.value.push_back(PredictSingleInterface(material, 1.5, slice.i.back(), slice.o));
      slice.train.push_back((ix + iy) % 2 == 0);
    }
  }
  return slice;
}

double RelativeDistance(const std::vector<float>& a, const std::vector<float>& b) {
  double d = 0, n = 0;
  for (size_t k = 0; k < a.size(); ++k) {
    d += (a[k] - b[k]) * (a[k] - b[k]);
    n += a[k] * a[k];
  }
  return std::sqrt(d / n);
}

std::vector<float> DotShape(const DmfSlice& s) {
  std::vector<float> shape;
  double sum = 0;
  for (int q = 0; q < s.num_dots(); ++q) sum += s.train[q] ? s.value[q] : 0;
  for (int q = 0; q < s.num_dots(); ++q) {
    if (s.train[q]) shape.push_back(static_cast<float>(s.value[q] / sum));
  }
  return shape;
}

TEST(DmfSliceShape, OneMaterialIsOneShapeWhereverThePointLies) {
  const DmfSlice centre = SliceAt(Eigen::Vector2d(0, 0));
  const SliceShapeGrid grid = MakeSliceShapeGrid(centre, 20);
  std::vector<float> at_centre(grid.num_nodes()), moved(grid.num_nodes());
  ASSERT_TRUE(AlignedSliceShape(centre, grid, at_centre.data()));
  const DmfSlice other = SliceAt(Eigen::Vector2d(0.012, -0.008));  // 12 mm and 8 mm away.
  ASSERT_TRUE(AlignedSliceShape(other, grid, moved.data()));
  const double aligned = RelativeDistance(at_centre, moved);
  const double by_dot = RelativeDistance(DotShape(centre), DotShape(other));
  std::printf("same material 14 mm apart: aligned shapes differ by %.3f, dot-indexed shapes by %.3f\n", aligned,
              by_dot);
  EXPECT_LT(aligned, 0.15);
  EXPECT_GT(by_dot, 3 * aligned);
}

TEST(DmfSliceShape, ShapeIsNormalisedAndEmptySlicesAreRefused) {
  const DmfSlice centre = SliceAt(Eigen::Vector2d(0, 0));
  const SliceShapeGrid grid = MakeSliceShapeGrid(centre, 12);
  std::vector<float> shape(grid.num_nodes());
  ASSERT_TRUE(AlignedSliceShape(centre, grid, shape.data()));
  double sum = 0;
  for (float v : shape) {
    EXPECT_GE(v, 0.0f);
    sum += v;
  }
  EXPECT_NEAR(sum, 1.0, 1e-5);
  DmfSlice dark = centre;
  for (double& v : dark.value) v = 0;
  EXPECT_FALSE(AlignedSliceShape(dark, grid, shape.data()));
  for (float v : shape) EXPECT_EQ(v, 0.0f);
}

}  // namespace
}  // namespace thinslab
