// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/rough_slab_photon_tracer.h"

#include <glog/logging.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <random>

#include "thinslab/core/math.h"
#include "thinslab/optics/fresnel.h"
#include "thinslab/optics/microfacet.h"

namespace thinslab {
namespace {

// GGX visible-normal sample for wi (local frame, wi.z > 0), Heitz 2018, "Sampling the GGX
// Distribution of Visible Normals", Listing 1 (anisotropic: stretch by alpha_x, alpha_y).
// Density over m: G1(wi) max(0, wi . m) D(m) / wi.z.
Eigen::Vector3d SampleGgxVisibleNormal(const Eigen::Vector3d& wi, double ax, double ay, double u1, double u2) {
  const Eigen::Vector3d vh = Eigen::Vector3d(ax * wi.x(), ay * wi.y(), wi.z()).normalized();
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
  return Eigen::Vector3d(ax * nh.x(), ay * nh.y(), std::max(1e-12, nh.z())).normalized();
}

// Inverse error function on (-1, 1): Giles 2010 single-precision starting value ("Approximating
// the erfinv function", GPU Computing Gems), polished by two Newton steps on std::erf to
// double precision. |y| is clamped below 1 - 1e-15 (|x| <= ~5.6).
double ErfInv(double y) {
  y = std::clamp(y, -1 + 1e-15, 1 - 1e-15);
  double w = -std::log((1.0 - y) * (1.0 + y)), p;
  if (w < 5.0) {
    w -= 2.5;
    p = 2.81022636e-08;
    p = 3.43273939e-07 + p * w;
    p = -3.5233877e-06 + p * w;
    p = -4.39150654e-06 + p * w;
    p = 0.00021858087 + p * w;
    p = -0.00125372503 + p * w;
    p = -0.00417768164 + p * w;
    p = 0.246640727 + p * w;
    p = 1.50140941 + p * w;
  } else {
    w = std::sqrt(w) - 3;
    p = -0.000200214257;
    p = 0.000100950558 + p * w;
    p = 0.00134934322 + p * w;
    p = -0.00367342844 + p * w;
    p = 0.00573950773 + p * w;
    p = -0.0076224613 + p * w;
    p = 0.00943887047 + p * w;
    p = 1.00167406 + p * w;
    p = 2.83297682 + p * w;
  }
  double x = p * y;
  for (int k = 0; k < 2; ++k) {
    const double err = std::erf(x) - y;
    x -= err / (2 / std::sqrt(kPi) * std::exp(-x * x));
  }
  return x;
}

// Visible slopes of the unit-roughness Beckmann distribution seen from a direction at polar
// angle theta_i in the x-z plane (Heitz and d'Eon 2014, Sec. 4 / Appendix; Jakob 2014's
// numerically robust inversion, as pbrt-v3 BeckmannSample11, in double precision): the slope
// along x has density proportional to (1 - x tan theta_i) exp(-x^2) on x < cot theta_i; its
// CDF is inverted in the erf domain by safeguarded Newton-bisection; the slope along y is
// Gaussian (erfinv of a uniform).
void SampleBeckmannVisibleSlopes11(double cos_theta_i, double u1, double u2, double* slope_x, double* slope_y) {
  if (cos_theta_i > 1 - 1e-12) {
    // Normal incidence: the visible slopes are the slopes (density D(m) m.z).
    const double r = std::sqrt(-std::log1p(-u1)), phi = 2 * kPi * u2;
    *slope_x = r * std::cos(phi);
    *slope_y = r * std::sin(phi);
    return;
  }
  const double sin_theta_i = std::sqrt(std::max(0.0, 1 - cos_theta_i * cos_theta_i));
  const double tan_theta_i = sin_theta_i / cos_theta_i;
  const double cot_theta_i = 1 / tan_theta_i;
  double a = -1, c = std::erf(cot_theta_i);
  const double sample_x = std::max(u1, 1e-12);
  const double theta_i = std::acos(cos_theta_i);
  const double fit = 1 + theta_i * (-0.876 + theta_i * (0.4265 - 0.0594 * theta_i));
  double b = c - (1 + c) * std::pow(1 - sample_x, fit);
  const double inv_sqrt_pi = 1 / std::sqrt(kPi);
  const double normalization = 1 / (1 + c + inv_sqrt_pi * tan_theta_i * std::exp(-cot_theta_i * cot_theta_i));
  for (int it = 0; it < 100; ++it) {
    if (!(b >= a && b <= c)) b = 0.5 * (a + c);
    const double inv_erf = ErfInv(b);
    const double value = normalization * (1 + b + inv_sqrt_pi * tan_theta_i * std::exp(-inv_erf * inv_erf)) - sample_x;
    const double derivative = normalization * (1 - inv_erf * tan_theta_i);
    if (std::abs(value) < 1e-12) break;
    if (value > 0) {
      c = b;
    } else {
      a = b;
    }
    if (c - a < 1e-15) break;
    b -= value / derivative;
  }
  *slope_x = ErfInv(b);
  *slope_y = ErfInv(2 * std::max(u2, 1e-15) - 1);
}

// Beckmann visible normal (Heitz and d'Eon 2014, Sec. 4): stretch wi to unit roughness, sample
// the visible slopes there, rotate them to wi's azimuth, unstretch.
Eigen::Vector3d SampleBeckmannVisibleNormal(const Eigen::Vector3d& wi, double ax, double ay, double u1, double u2) {
  const Eigen::Vector3d ws = Eigen::Vector3d(ax * wi.x(), ay * wi.y(), wi.z()).normalized();
  double sx, sy;
  SampleBeckmannVisibleSlopes11(ws.z(), u1, u2, &sx, &sy);
  const double sin_theta = std::sqrt(ws.x() * ws.x() + ws.y() * ws.y());
  const double cos_phi = sin_theta > 0 ? ws.x() / sin_theta : 1.0;
  const double sin_phi = sin_theta > 0 ? ws.y() / sin_theta : 0.0;
  const double rx = cos_phi * sx - sin_phi * sy;
  const double ry = sin_phi * sx + cos_phi * sy;
  return Eigen::Vector3d(-ax * rx, -ay * ry, 1.0).normalized();
}

enum class Event { kReflected, kRefracted, kMasked };

// One interface: its NDF kind and roughness along x and y.
struct Face {
  RoughSlabNdf ndf;
  double ax, ay;
  double G1(const Eigen::Vector3d& w, const Eigen::Vector3d& m) const {
    return ndf == RoughSlabNdf::kGgx ? GgxDistribution(ax, ay).G1(w, m) : BeckmannDistribution(ax, ay).G1(w, m);
  }
};

// One scattering event on a microsurface in its local frame: wi.z > 0 is the side the
// photon comes from, eta_rel = eta_other_side / eta_this_side. *wo is the new propagation
// direction (pointing away from the surface).
Event Interact(const Eigen::Vector3d& wi, const Face& face, double eta_rel, std::mt19937_64& rng,
               Eigen::Vector3d* wo) {
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const double u1 = uni(rng), u2 = uni(rng);
  const Eigen::Vector3d m = SampleVisibleNormal(face.ndf, face.ax, face.ay, wi, u1, u2);
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
  if (!right_side || uni(rng) >= face.G1(*wo, m)) return Event::kMasked;
  return event;
}

Eigen::Vector3d FlipZ(const Eigen::Vector3d& v) { return Eigen::Vector3d(v.x(), v.y(), -v.z()); }

}  // namespace

const char* RoughSlabNdfName(RoughSlabNdf ndf) { return ndf == RoughSlabNdf::kGgx ? "ggx" : "beckmann"; }

bool ParseRoughSlabNdf(const std::string& name, RoughSlabNdf* ndf) {
  if (name == "ggx" || name == "GGX") {
    *ndf = RoughSlabNdf::kGgx;
  } else if (name == "beckmann" || name == "Beckmann") {
    *ndf = RoughSlabNdf::kBeckmann;
  } else {
    return false;
  }
  return true;
}

Eigen::Vector3d SampleVisibleNormal(RoughSlabNdf ndf, double alpha_x, double alpha_y, const Eigen::Vector3d& wi,
                                    double u1, double u2) {
  return ndf == RoughSlabNdf::kGgx ? SampleGgxVisibleNormal(wi, alpha_x, alpha_y, u1, u2)
                                   : SampleBeckmannVisibleNormal(wi, alpha_x, alpha_y, u1, u2);
}

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
  const Face top{options.ndf_top, options.alpha_top, options.alpha_top_y > 0 ? options.alpha_top_y : options.alpha_top};
  const Face bottom{options.ndf_bottom, options.alpha_bottom,
                    options.alpha_bottom_y > 0 ? options.alpha_bottom_y : options.alpha_bottom};
  for (const Face& f : {top, bottom}) {
    CHECK_GE(f.ax, kMinMicrofacetAlpha);
    CHECK_GE(f.ay, kMinMicrofacetAlpha);
    CHECK_LE(f.ax, kMaxMicrofacetAlpha);
    CHECK_LE(f.ay, kMaxMicrofacetAlpha);
  }
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
  result.transmitted_once_counts.assign(result.transmitted_counts.size(), 0);
  result.once_offset_x.assign(result.transmitted_counts.size(), 0.0);
  result.once_offset_y.assign(result.transmitted_counts.size(), 0.0);
  int64_t reflected = 0, transmitted = 0, masked = 0, capped = 0;
  std::mt19937_64 rng(options.seed);
  const double inv_eta = 1.0 / options.eta;
  const double h = 2.0 / options.num_bins;

  for (int64_t p = 0; p < options.num_photons; ++p) {
    // First hit: top face from the air, global frame is its local frame.
    Eigen::Vector3d d;  // Propagation direction.
    Event e = Interact(options.wi, top, options.eta, rng, &d);
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
    Eigen::Vector2d lateral = Eigen::Vector2d::Zero();  // Across a slab of unit thickness.
    while (!done) {
      if (hits >= options.max_interactions) {
        ++capped;
        break;
      }
      ++hits;
      lateral += d.head<2>() / std::abs(d.z());  // One crossing of the slab.
      Eigen::Vector3d out;
      if (d.z() < 0) {
        // Bottom face from inside: local frame = global frame (incoming side +z).
        e = Interact(-d, bottom, inv_eta, rng, &out);
        if (e == Event::kMasked) {
          ++masked;
          done = true;
        } else if (e == Event::kRefracted) {
          ++transmitted;
          ++result.transmitted_by_hits[hits];
          const int col = std::min(options.num_bins - 1, static_cast<int>((out.x() + 1) / h));
          const int row = std::min(options.num_bins - 1, static_cast<int>((out.y() + 1) / h));
          const size_t cell = static_cast<size_t>(row) * options.num_bins + col;
          ++result.transmitted_counts[cell];
          if (hits == 2) {
            ++result.transmitted_once_counts[cell];
            result.once_offset_x[cell] += lateral.x();
            result.once_offset_y[cell] += lateral.y();
          } else {
            result.multiple_offsets.push_back(lateral.cast<float>());
          }
          done = true;
        } else {
          d = out;
        }
      } else {
        // Top face from inside: local frame has z flipped so that the incoming side is +z.
        e = Interact(FlipZ(-d), top, inv_eta, rng, &out);
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
