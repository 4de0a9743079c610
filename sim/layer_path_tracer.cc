// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/layer_path_tracer.h"

#include <glog/logging.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "thinslab/core/math.h"
#include "thinslab/optics/fresnel.h"
#include "thinslab/optics/henyey_greenstein.h"

namespace thinslab {
namespace {

struct Dir {
  double x, y, z;
};

// Per-bin sums of path weights and of their squares, for the mean and its standard error.
struct BinAccumulator {
  std::vector<double> sum, sum_sq;
  explicit BinAccumulator(int n) : sum(n, 0.0), sum_sq(n, 0.0) {}
  void Add(int idx, double w) {
    sum[idx] += w;
    sum_sq[idx] += w * w;
  }
};

struct SideAccumulator {
  double specular = 0, specular_gu = 0, scattered = 0;
  BinAccumulator single, single_gu, multiple;
  explicit SideAccumulator(int n) : single(n), single_gu(n), multiple(n) {}
};

enum class Medium { kAirAbove, kLayer, kGlass, kAirBelow };

// Stochastic Fresnel event at a horizontal interface from index n_from into n_to: reflects
// (flips d.z) with probability F, else refracts (Snell, tangential part scaled by
// n_from / n_to). Returns true on reflection.
bool CrossInterface(double n_from, double n_to, double u, Dir* d) {
  const double cos_i = std::abs(d->z);
  const double f = FresnelDielectric(cos_i, n_to / n_from);  // 1 under TIR.
  if (u < f) {
    d->z = -d->z;
    return true;
  }
  const double r = n_from / n_to;
  d->x *= r;
  d->y *= r;
  const double cos_t = SafeSqrt(1.0 - (d->x * d->x + d->y * d->y));
  d->z = d->z < 0 ? -cos_t : cos_t;
  return false;
}

// New propagation direction at scattering angle acos(cos_t) and azimuth phi about d
// (orthonormal basis of Duff et al. 2017, "Building an Orthonormal Basis, Revisited").
Dir Scatter(const Dir& d, double cos_t, double phi) {
  const double sign = std::copysign(1.0, d.z);
  const double a = -1.0 / (sign + d.z);
  const double b = d.x * d.y * a;
  const Dir u{1.0 + sign * d.x * d.x * a, sign * b, -sign * d.x};
  const Dir v{b, sign + d.y * d.y * a, -d.y};
  const double sin_t = SafeSqrt(1.0 - cos_t * cos_t);
  const double cu = sin_t * std::cos(phi), cv = sin_t * std::sin(phi);
  Dir n{cu * u.x + cv * v.x + cos_t * d.x, cu * u.y + cv * v.y + cos_t * d.y,
        cu * u.z + cv * v.z + cos_t * d.z};
  const double norm = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
  n.x /= norm;
  n.y /= norm;
  n.z /= norm;
  return n;
}

LayerBsdfEstimate Finish(const BinAccumulator& acc, const LayerPathTracerResult& r,
                         double num_paths) {
  LayerBsdfEstimate out;
  const int n = static_cast<int>(acc.sum.size());
  out.value.resize(n);
  out.std_error.resize(n);
  for (int idx = 0; idx < n; ++idx) {
    const double mu_c = r.MuCenter(idx / r.num_phi_bins);
    const double norm = 1.0 / (r.BinSolidAngle() * mu_c);
    const double mean = acc.sum[idx] / num_paths;
    const double var = std::max(0.0, acc.sum_sq[idx] / num_paths - mean * mean) / num_paths;
    out.value[idx] = mean * norm;
    out.std_error[idx] = std::sqrt(var) * norm;
  }
  return out;
}

}  // namespace

double LayerPathTracerResult::PhiCenter(int phi_idx) const {
  return (phi_idx + 0.5) * kPi / num_phi_bins;
}

double LayerPathTracerResult::BinSolidAngle() const {
  return 2.0 * (1.0 / num_mu_bins) * (kPi / num_phi_bins);
}

LayerPathTracerResult TraceLayer(const LayerPathTracerOptions& options) {
  CHECK_GE(options.tau, 0.0);
  CHECK(options.albedo >= 0.0 && options.albedo <= 1.0) << "albedo " << options.albedo;
  CHECK(std::abs(options.g) < 1.0) << "g " << options.g;
  CHECK(options.incident_theta_rad >= 0.0 && options.incident_theta_rad < kPi / 2);
  CHECK_GT(options.num_paths, 0);
  CHECK_GT(options.num_mu_bins, 0);
  CHECK_GT(options.num_phi_bins, 0);

  LayerPathTracerResult result;
  result.num_mu_bins = options.num_mu_bins;
  result.num_phi_bins = options.num_phi_bins;
  const int num_bins = options.num_mu_bins * options.num_phi_bins;
  SideAccumulator top(num_bins), bottom(num_bins);
  SideAccumulator& refl = options.incident_from_below ? bottom : top;
  SideAccumulator& trans = options.incident_from_below ? top : bottom;

  std::mt19937_64 rng(options.seed);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const double tau = options.tau;
  const double n1 = options.n1, n2 = options.n2, n3 = options.n3;
  const double sin_i = std::sin(options.incident_theta_rad);
  const double cos_i = std::cos(options.incident_theta_rad);
  double absorbed = 0, dropped = 0;

  for (int path = 0; path < options.num_paths; ++path) {
    // Propagation direction = -wi, wi = (sin, 0, +-cos).
    Dir d{-sin_i, 0.0, options.incident_from_below ? cos_i : -cos_i};
    Medium medium = options.incident_from_below
                        ? (options.glass_slab ? Medium::kAirBelow : Medium::kGlass)
                        : Medium::kAirAbove;
    double depth = 0;  // Optical depth below the air-layer face, in [0, tau].
    double weight = 1;
    int order = 0, reflections_before = 0, reflections_after = 0, events = 0;
    auto count_reflection = [&](bool reflected) {
      if (reflected) ++(order == 0 ? reflections_before : reflections_after);
    };
    bool exited_top = false, done = false;
    while (!done) {
      if (++events > options.max_events) {
        dropped += weight;
        break;
      }
      switch (medium) {
        case Medium::kAirAbove:
          if (d.z > 0) {
            exited_top = true;
            done = true;
          } else {
            const bool r = CrossInterface(n1, n2, uni(rng), &d);
            count_reflection(r);
            if (!r) medium = Medium::kLayer, depth = 0;
          }
          break;
        case Medium::kAirBelow:
          if (d.z < 0) {
            done = true;
          } else {
            const bool r = CrossInterface(n1, n3, uni(rng), &d);
            count_reflection(r);
            if (!r) medium = Medium::kGlass;
          }
          break;
        case Medium::kGlass:
          if (d.z < 0) {
            if (!options.glass_slab) {
              done = true;
            } else {
              const bool r = CrossInterface(n3, n1, uni(rng), &d);
              count_reflection(r);
              if (!r) medium = Medium::kAirBelow;
            }
          } else {
            const bool r = CrossInterface(n3, n2, uni(rng), &d);
            count_reflection(r);
            if (!r) medium = Medium::kLayer, depth = tau;
          }
          break;
        case Medium::kLayer: {
          const double step = -std::log(1.0 - uni(rng));  // Free path in optical length.
          const double to_boundary = d.z < 0 ? (tau - depth) / -d.z : depth / d.z;
          if (step >= to_boundary) {
            if (d.z < 0) {
              depth = tau;
              const bool r = CrossInterface(n2, n3, uni(rng), &d);
              count_reflection(r);
              if (!r) medium = Medium::kGlass;
            } else {
              depth = 0;
              const bool r = CrossInterface(n2, n1, uni(rng), &d);
              count_reflection(r);
              if (!r) medium = Medium::kAirAbove;
            }
            break;
          }
          depth = Clamp(depth - d.z * step, 0.0, tau);
          // Scattering event: the (1 - omega0) share is absorbed; new HG direction.
          absorbed += weight * (1.0 - options.albedo);
          weight *= options.albedo;
          ++order;
          if (weight < 1e-3) {  // Russian roulette keeps the estimate unbiased.
            if (uni(rng) >= 0.1) {
              done = true;
              weight = 0;
              break;
            }
            weight /= 0.1;
          }
          const double cos_t = SampleHenyeyGreensteinCosTheta(uni(rng), options.g);
          d = Scatter(d, cos_t, 2.0 * kPi * uni(rng));
          break;
        }
      }
    }
    if (!done || weight == 0) continue;
    // Exit: tally on the side the path left by, in the medium it ends in.
    SideAccumulator& side = exited_top ? top : bottom;
    const bool is_reflection = &side == &refl;
    const int reflections = reflections_before + reflections_after;
    if (order == 0) {
      side.specular += weight;
      // Gu Eqs. 1, 2 (and the slab's F31 path): exactly one mirror event; Eq. 5: none.
      if (reflections == (is_reflection ? 1 : 0)) side.specular_gu += weight;
      continue;
    }
    side.scattered += weight;
    const double mu = std::abs(d.z);
    const double phi = std::abs(std::atan2(d.y, d.x));
    const int mu_idx = std::min(options.num_mu_bins - 1, static_cast<int>(mu * options.num_mu_bins));
    const int phi_idx =
        std::min(options.num_phi_bins - 1, static_cast<int>(phi / kPi * options.num_phi_bins));
    const int idx = mu_idx * options.num_phi_bins + phi_idx;
    if (order >= 2) {
      side.multiple.Add(idx, weight);
      continue;
    }
    side.single.Add(idx, weight);
    // Gu Eqs. 3, 6: scatter straight from the refracted beam and leave with no mirror event;
    // Eq. 4: one mirror event at the far side (F23, or F31 through the slab) before the
    // scattering, none after. Not in Gu: any mirror event after the scattering, e.g. the
    // scattered light reflected (or totally reflected) at the face it first meets.
    const bool gu_path = reflections_after == 0 &&
                         (is_reflection ? reflections_before <= 1 : reflections_before == 0);
    if (gu_path) side.single_gu.Add(idx, weight);
  }

  const double n = options.num_paths;
  auto finish_side = [&](const SideAccumulator& acc, LayerSideTally* out) {
    out->specular = acc.specular / n;
    out->specular_gu = acc.specular_gu / n;
    out->scattered_flux = acc.scattered / n;
    out->single = Finish(acc.single, result, n);
    out->single_gu = Finish(acc.single_gu, result, n);
    out->multiple = Finish(acc.multiple, result, n);
  };
  finish_side(refl, &result.reflected);
  finish_side(trans, &result.transmitted);
  result.absorbed = absorbed / n;
  result.dropped = dropped / n;
  return result;
}

}  // namespace thinslab
