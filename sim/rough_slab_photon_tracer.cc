// SPDX-License-Identifier: Apache-2.0
#include "sim/rough_slab_photon_tracer.h"

#include <glog/logging.h>

#include <Eigen/Geometry>
#include <cmath>
#include <random>

#include "core/math.h"
#include "optics/fresnel.h"
#include "optics/microfacet.h"

namespace thinslab {
namespace {

// GGX visible-normal sample for wi (local frame, wi.z > 0), Heitz 2018, "Sampling the GGX
// Distribution of Visible Normals", Listing 1 (isotropic alpha). Density over m:
// G1(wi) max(0, wi . m) D(m) / wi.z.
Eigen::Vector3d SampleGgxVisibleNormal(const Eigen::Vector3d& wi, double alpha, double u1, double u2) {
  const Eigen::Vector3d vh = Eigen::Vector3d(alpha * wi.x(), alpha * wi.y(), wi.z()).normalized();
  const double lensq = vh.x() * vh.x() + vh.y() * vh.y();
  const Eigen::Vector3d t1 =
      lensq > 0 ? Eigen::Vector3d(-vh.y(), vh.x(), 0) / std::sqrt(lensq) : Eigen::Vector3d(1, 0, 0);
  const Eigen::Vector3d t2 = vh.cross(t1);
  const double r = std::sqrt(u1), phi = 2 * kPi * u2;
  const double p1 = r * std::cos(phi);
  double p2 = r * std::sin(phi);
  const double s = 0.5 * (1 + vh.z());
  p2 = (1 - s) * std::sqrt(std::max(0.0, 1 - p1 * p1)) + s * p2;
  const Eigen::Vector3d nh = p1 * t1 + p2 * t2 + std::sqrt(std::max(0.0, 1 - p1 * p1 - p2 * p2)) * vh;
  return Eigen::Vector3d(alpha * nh.x(), alpha * nh.y(), std::max(1e-12, nh.z())).normalized();
}

enum class Event { kReflected, kRefracted, kMasked };

// One scattering event on a GGX microsurface in its local frame: wi.z > 0 is the side the
// photon comes from, eta_rel = eta_other_side / eta_this_side. *wo is the new propagation
// direction (pointing away from the surface).
Event Interact(const Eigen::Vector3d& wi, double alpha, double eta_rel, std::mt19937_64& rng, Eigen::Vector3d* wo) {
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const GgxDistribution ggx(alpha);
  const double u1 = uni(rng), u2 = uni(rng);
  const Eigen::Vector3d m = SampleGgxVisibleNormal(wi, alpha, u1, u2);
  const double i_dot_m = wi.dot(m);
  if (!(i_dot_m > 0)) return Event::kMasked;  // Measure-zero round-off case.
  const double fresnel = FresnelDielectric(i_dot_m, eta_rel);
  Event event;
  if (uni(rng) < fresnel) {
    *wo = Reflect(wi, m);  // Walter Eq. 39.
    event = Event::kReflected;
  } else {
    // Walter Eq. 40; F = 1 under TIR so refraction cannot fail here.
    CHECK(Refract(wi, m, eta_rel, wo));
    event = Event::kRefracted;
  }
  // Smith masking of the exit direction (Walter Eq. 23, second factor; chi^+ inside G1 also
  // drops directions that point into the wrong side of the macro-surface).
  const bool right_side = event == Event::kReflected ? wo->z() > 0 : wo->z() < 0;
  if (!right_side || uni(rng) >= ggx.G1(*wo, m)) return Event::kMasked;
  return event;
}

Eigen::Vector3d FlipZ(const Eigen::Vector3d& v) { return Eigen::Vector3d(v.x(), v.y(), -v.z()); }

}  // namespace

double RoughSlabPhotonTracerResult::CellAreaInDisk(int row, int col) const {
  constexpr int kSub = 16;
  const double h = CellWidth(), hs = h / kSub;
  const double x0 = -1 + col * h, y0 = -1 + row * h;
  int inside = 0;
  for (int j = 0; j < kSub; ++j) {
    for (int k = 0; k < kSub; ++k) {
      const double x = x0 + (k + 0.5) * hs, y = y0 + (j + 0.5) * hs;
      if (x * x + y * y < 1) ++inside;
    }
  }
  return inside * hs * hs;
}

double RoughSlabPhotonTracerResult::Btdf(int row, int col) const {
  const double area = CellAreaInDisk(row, col);
  if (area <= 0) return 0;
  return transmitted_counts[row * num_bins + col] / (static_cast<double>(num_photons) * area);
}

double RoughSlabPhotonTracerResult::BtdfStdError(int row, int col) const {
  const double area = CellAreaInDisk(row, col);
  if (area <= 0) return 0;
  return std::sqrt(static_cast<double>(transmitted_counts[row * num_bins + col])) /
         (static_cast<double>(num_photons) * area);
}

RoughSlabPhotonTracerResult TraceRoughSlab(const RoughSlabPhotonTracerOptions& options) {
  CHECK_GT(options.eta, 1.0);
  CHECK_GE(options.alpha_top, kMinMicrofacetAlpha);
  CHECK_GE(options.alpha_bottom, kMinMicrofacetAlpha);
  CHECK_LE(options.alpha_top, kMaxMicrofacetAlpha);
  CHECK_LE(options.alpha_bottom, kMaxMicrofacetAlpha);
  CHECK_GT(options.wi.z(), 0.0);
  CHECK_NEAR(options.wi.norm(), 1.0, 1e-9);
  CHECK_GT(options.num_photons, 0);
  CHECK_GE(options.num_bins, 1);
  CHECK_GE(options.max_interactions, 2);

  RoughSlabPhotonTracerResult result;
  result.num_bins = options.num_bins;
  result.num_photons = options.num_photons;
  result.transmitted_counts.assign(static_cast<size_t>(options.num_bins) * options.num_bins, 0);
  result.transmitted_by_hits.assign(options.max_interactions + 1, 0);
  int64_t reflected = 0, transmitted = 0, masked = 0, capped = 0;
  std::mt19937_64 rng(options.seed);
  const double inv_eta = 1.0 / options.eta;
  const double h = 2.0 / options.num_bins;

  for (int64_t p = 0; p < options.num_photons; ++p) {
    // First hit: top face from the air, global frame is its local frame.
    Eigen::Vector3d d;  // Propagation direction.
    Event e = Interact(options.wi, options.alpha_top, options.eta, rng, &d);
    if (e == Event::kMasked) {
      ++masked;
      continue;
    }
    if (e == Event::kReflected) {
      ++reflected;
      continue;
    }
    int hits = 1;
    bool done = false;
    while (!done) {
      if (hits >= options.max_interactions) {
        ++capped;
        break;
      }
      ++hits;
      Eigen::Vector3d out;
      if (d.z() < 0) {
        // Bottom face from inside: local frame = global frame (incoming side +z).
        e = Interact(-d, options.alpha_bottom, inv_eta, rng, &out);
        if (e == Event::kMasked) {
          ++masked;
          done = true;
        } else if (e == Event::kRefracted) {
          ++transmitted;
          ++result.transmitted_by_hits[hits];
          const int col = std::min(options.num_bins - 1, static_cast<int>((out.x() + 1) / h));
          const int row = std::min(options.num_bins - 1, static_cast<int>((out.y() + 1) / h));
          ++result.transmitted_counts[static_cast<size_t>(row) * options.num_bins + col];
          done = true;
        } else {
          d = out;
        }
      } else {
        // Top face from inside: local frame has z flipped so that the incoming side is +z.
        e = Interact(FlipZ(-d), options.alpha_top, inv_eta, rng, &out);
        if (e == Event::kMasked) {
          ++masked;
          done = true;
        } else if (e == Event::kRefracted) {
          ++reflected;
          done = true;
        } else {
          d = FlipZ(out);
        }
      }
    }
  }
  const double n = static_cast<double>(options.num_photons);
  result.reflected = reflected / n;
  result.transmitted = transmitted / n;
  result.masked = masked / n;
  result.capped = capped / n;
  CHECK_EQ(reflected + transmitted + masked + capped, options.num_photons);
  return result;
}

}  // namespace thinslab
