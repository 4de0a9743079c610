// SPDX-License-Identifier: Apache-2.0
// Small math helpers named for the math (pbrt-v4 util/math.h style).
#pragma once

#include <glog/logging.h>

#include <algorithm>
#include <cmath>
#include <type_traits>

namespace thinslab {

constexpr double kPi = 3.14159265358979323846;
constexpr double kInvPi = 1.0 / kPi;
constexpr double kInv2Pi = 1.0 / (2.0 * kPi);
constexpr double kInv4Pi = 1.0 / (4.0 * kPi);

template <typename T>
inline T Sqr(const T& x) {
  return x * x;
}

template <typename T>
inline T Clamp(const T& x, const T& lo, const T& hi) {
  return x < lo ? lo : (x > hi ? hi : x);
}

template <typename T, typename U>
inline T Lerp(const U& t, const T& a, const T& b) {
  return (1 - t) * a + t * b;
}

// sqrt of a quantity that is non-negative up to round-off.
inline double SafeSqrt(double x) {
  DCHECK_GE(x, -1e-9) << "SafeSqrt argument is too negative";
  return std::sqrt(std::max(0.0, x));
}

// The value of a double, or the scalar part of a ceres::Jet, for branch decisions in physics
// code templated on T.
template <typename T>
inline double ScalarValue(const T& x) {
  if constexpr (std::is_arithmetic_v<T>) {
    return static_cast<double>(x);
  } else {
    return x.a;
  }
}

}  // namespace thinslab
