// SPDX-License-Identifier: Apache-2.0
#include "thinslab/sim/layer_path_tracer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <string>

#include "thinslab/core/math.h"
#include "thinslab/optics/dirty_glass_layer.h"
#include "thinslab/optics/fresnel.h"
#include "thinslab/optics/thin_slab.h"

namespace thinslab {
namespace {

using Vec3 = Eigen::Vector3d;
using Bsdf = std::function<double(const Vec3& wo)>;

// The model value matching a LayerBsdfEstimate bin: integral of f mu dw over the bin divided
// by (bin solid angle * bin-centre mu); z_sign picks the exit hemisphere. The model is
// symmetric about the plane of incidence, so the +phi half stands for both.
double ModelBin(const Bsdf& f, const LayerPathTracerResult& r, int mu_idx, int phi_idx,
                double z_sign, int sub = 16) {
  double sum = 0;
  for (int a = 0; a < sub; ++a) {
    const double mu = (mu_idx + (a + 0.5) / sub) / r.num_mu_bins;
    const double s = std::sqrt(1 - mu * mu);
    for (int b = 0; b < sub; ++b) {
      const double phi = (phi_idx + (b + 0.5) / sub) * kPi / r.num_phi_bins;
      sum += f(Vec3(s * std::cos(phi), s * std::sin(phi), z_sign * mu)) * mu;
    }
  }
  return sum / (sub * sub * r.MuCenter(mu_idx));
}

std::vector<double> ModelBins(const Bsdf& f, const LayerPathTracerResult& r, double z_sign) {
  std::vector<double> out(r.num_mu_bins * r.num_phi_bins);
  for (int m = 0; m < r.num_mu_bins; ++m) {
    for (int p = 0; p < r.num_phi_bins; ++p) out[m * r.num_phi_bins + p] = ModelBin(f, r, m, p, z_sign);
  }
  return out;
}

// Agreement of a model with an MC estimate over the bins the MC resolves (relative standard
// error below max_rel_se): chi^2 per bin and the largest |z|.
struct Agreement {
  int bins = 0;
  double chi2_per_bin = 0;
  double max_abs_z = 0;
};
Agreement Compare(const std::vector<double>& model, const LayerBsdfEstimate& mc,
                  double max_rel_se = 0.1) {
  Agreement a;
  double chi2 = 0;
  for (size_t i = 0; i < model.size(); ++i) {
    if (mc.value[i] <= 0 || mc.std_error[i] > max_rel_se * mc.value[i]) continue;
    const double z = (model[i] - mc.value[i]) / mc.std_error[i];
    chi2 += z * z;
    a.max_abs_z = std::max(a.max_abs_z, std::abs(z));
    ++a.bins;
  }
  a.chi2_per_bin = a.bins > 0 ? chi2 / a.bins : 0;
  return a;
}

LayerBsdfEstimate Sum(const LayerBsdfEstimate& a, const LayerBsdfEstimate& b) {
  LayerBsdfEstimate s = a;
  for (size_t i = 0; i < s.value.size(); ++i) {
    s.value[i] += b.value[i];
    s.std_error[i] = std::hypot(a.std_error[i], b.std_error[i]);
  }
  return s;
}

// RMS relative difference of model vs reference over bins the reference resolves to
// max_rel_se, and the RMS relative standard error of the reference over those bins.
struct RmsRel {
  int bins = 0;
  double rms_rel = 0;
  double rms_noise = 0;
};
RmsRel RmsRelative(const std::vector<double>& model, const LayerBsdfEstimate& ref,
                   double max_rel_se = 0.05) {
  RmsRel r;
  for (size_t i = 0; i < model.size(); ++i) {
    if (ref.value[i] <= 0 || ref.std_error[i] > max_rel_se * ref.value[i]) continue;
    r.rms_rel += Sqr(model[i] / ref.value[i] - 1);
    r.rms_noise += Sqr(ref.std_error[i] / ref.value[i]);
    ++r.bins;
  }
  if (r.bins > 0) {
    r.rms_rel = std::sqrt(r.rms_rel / r.bins);
    r.rms_noise = std::sqrt(r.rms_noise / r.bins);
  }
  return r;
}

// Flux fraction held by binned BSDF values.
double Flux(const std::vector<double>& bins, const LayerPathTracerResult& r) {
  double sum = 0;
  for (int m = 0; m < r.num_mu_bins; ++m) {
    for (int p = 0; p < r.num_phi_bins; ++p) {
      sum += bins[m * r.num_phi_bins + p] * r.BinSolidAngle() * r.MuCenter(m);
    }
  }
  return sum;
}

Vec3 IncidentDir(const LayerPathTracerOptions& o) {
  return Vec3(std::sin(o.incident_theta_rad), 0,
              (o.incident_from_below ? -1 : 1) * std::cos(o.incident_theta_rad));
}

DirtyGlassLayer<double> GuLayer(const LayerPathTracerOptions& o) {
  DirtyGlassLayer<double> layer;
  layer.tau = o.tau;
  layer.albedo = o.albedo;
  layer.g = o.g;
  layer.n1 = o.n1;
  layer.n2 = o.n2;
  layer.n3 = o.n3;
  layer.thin_slab = o.glass_slab;
  return layer;
}

// Energy: every path ends reflected, transmitted, absorbed or dropped.
TEST(LayerPathTracer, EnergyConservation) {
  LayerPathTracerOptions o;
  o.tau = 1.0;
  o.albedo = 0.9;
  o.g = 0.5;
  o.n2 = 1.4;
  o.n3 = 1.52;
  o.glass_slab = true;
  o.incident_theta_rad = 0.6;
  o.num_paths = 200000;
  const LayerPathTracerResult r = TraceLayer(o);
  const double total = r.reflected.specular + r.reflected.scattered_flux + r.transmitted.specular +
                       r.transmitted.scattered_flux + r.absorbed + r.dropped;
  // Russian roulette keeps it unbiased, not exact: allow a few standard errors.
  EXPECT_NEAR(total, 1.0, 5e-3);
  EXPECT_LT(r.dropped, 1e-4);
  // Binned BSDF integrates back to the scattered flux.
  double binned = 0;
  for (int m = 0; m < r.num_mu_bins; ++m) {
    for (int p = 0; p < r.num_phi_bins; ++p) {
      const int i = m * r.num_phi_bins + p;
      binned += (r.transmitted.single.value[i] + r.transmitted.multiple.value[i]) *
                r.BinSolidAngle() * r.MuCenter(m);
    }
  }
  EXPECT_NEAR(binned, r.transmitted.scattered_flux, 1e-9);
  // An absorber scatters nothing out.
  o.albedo = 0;
  const LayerPathTracerResult black = TraceLayer(o);
  EXPECT_EQ(black.reflected.scattered_flux + black.transmitted.scattered_flux, 0.0);
  // Deterministic for a seed.
  o.albedo = 0.9;
  o.num_paths = 20000;
  EXPECT_EQ(TraceLayer(o).transmitted.scattered_flux, TraceLayer(o).transmitted.scattered_flux);
}

// tau = 0: the stochastic Fresnel choices reproduce the incoherent two-interface stack,
// R = F12 + T12^2 F23 / (1 - F21 F23), T = T12 T23 / (1 - F21 F23), within binomial noise.
TEST(LayerPathTracer, ZeroTauIsIncoherentFresnelStack) {
  for (double theta : {0.0, 0.7, 1.3}) {
    LayerPathTracerOptions o;
    o.tau = 0;
    o.n2 = 1.8;  // Strong interfaces so the interreflection term is resolved.
    o.n3 = 1.3;
    o.incident_theta_rad = theta;
    o.num_paths = 400000;
    const LayerPathTracerResult r = TraceLayer(o);
    const double f12 = FresnelDielectric(std::cos(theta), o.n2);
    const double c2 = std::sqrt(1 - Sqr(std::sin(theta) / o.n2));
    const double f23 = FresnelDielectric(c2, o.n3 / o.n2);
    const double denom = 1 - f12 * f23;
    const double R = f12 + Sqr(1 - f12) * f23 / denom;
    const double sigma = std::sqrt(R * (1 - R) / o.num_paths);
    EXPECT_NEAR(r.reflected.specular, R, 4 * sigma) << "theta=" << theta;
    EXPECT_NEAR(r.transmitted.specular, (1 - f12) * (1 - f23) / denom, 4 * sigma);
    // Gu's first-order paths (Eqs. 1, 2, 5) are the model's terms exactly.
    const DirtyGlassLayerSpecular<double> gu = GuLayer(o).Specular(IncidentDir(o));
    EXPECT_NEAR(r.reflected.specular_gu, gu.reflectance, 4 * sigma);
    EXPECT_NEAR(r.transmitted.specular_gu, gu.transmittance, 4 * sigma);
  }
}

// The real correctness check of both codes: Gu's single-scattering BRDF/BTDF (with
// flux-consistent radiometry) equals the MC tally of exactly the paths it describes, bin by
// bin, within MC noise, for any incidence, either side, and the thin slab. The specular terms
// equal the MC's unscattered flux on the same paths.
TEST(LayerPathTracer, GuModelMatchesItsPathsWithinNoise) {
  struct Case {
    const char* name;
    double theta, n2;
    bool from_below, slab;
  };
  const Case cases[] = {{"air 0deg", 0.0, 1.4, false, false},
                        {"air 55deg", 0.96, 1.4, false, false},
                        {"glass 30deg", 0.52, 1.4, true, false},
                        {"slab air 40deg", 0.7, 1.33, false, true},
                        {"slab below 25deg", 0.44, 1.6, true, true}};
  for (const Case& c : cases) {
    LayerPathTracerOptions o;
    o.tau = 0.3;
    o.albedo = 0.5;
    o.g = 0.6;
    o.n2 = c.n2;
    o.n3 = 1.52;
    o.glass_slab = c.slab;
    o.incident_from_below = c.from_below;
    o.incident_theta_rad = c.theta;
    o.num_paths = 4000000;  // The back-scattered lobe holds ~1 % of the flux.
    o.seed = 7;
    const LayerPathTracerResult r = TraceLayer(o);
    const DirtyGlassLayer<double> layer = GuLayer(o);
    const Vec3 wi = IncidentDir(o);
    const double zr = c.from_below ? -1 : 1;
    const Bsdf f = [&](const Vec3& wo) { return layer.Bsdf(wi, wo); };
    const Agreement refl = Compare(ModelBins(f, r, zr), r.reflected.single_gu);
    const Agreement trans = Compare(ModelBins(f, r, -zr), r.transmitted.single_gu);
    std::printf("%-18s BRDF bins %3d chi2/bin %.2f max|z| %.1f | BTDF bins %3d chi2/bin %.2f max|z| %.1f\n",
                c.name, refl.bins, refl.chi2_per_bin, refl.max_abs_z, trans.bins,
                trans.chi2_per_bin, trans.max_abs_z);
    // ~50-200 bins: chi2/bin of a correct model is 1 +- 0.2; a 3 % bias in a lobe fails it.
    EXPECT_GT(refl.bins, 20) << c.name;
    EXPECT_GT(trans.bins, 40) << c.name;
    EXPECT_LT(refl.chi2_per_bin, 1.6) << c.name;
    EXPECT_LT(trans.chi2_per_bin, 1.6) << c.name;
    EXPECT_LT(refl.max_abs_z, 5.0) << c.name;
    EXPECT_LT(trans.max_abs_z, 5.0) << c.name;
    // The printed radiometry of Eqs. 3, 4, 6 (no (n_out / n2)^2, mu'_i / mu_i) is far outside
    // the noise whenever n2 != n1: the check has teeth.
    DirtyGlassLayer<double> printed = layer;
    printed.as_printed = true;
    const Bsdf fp = [&](const Vec3& wo) { return printed.Bsdf(wi, wo); };
    const Agreement printed_t = Compare(ModelBins(fp, r, -zr), r.transmitted.single_gu);
    const Agreement printed_r = Compare(ModelBins(fp, r, zr), r.reflected.single_gu);
    std::printf("%-18s printed Eqs. 3-6:  BRDF chi2/bin %.0f | BTDF chi2/bin %.0f\n", c.name,
                printed_r.chi2_per_bin, printed_t.chi2_per_bin);
    EXPECT_GT(printed_r.chi2_per_bin, 10.0) << c.name;
    const DirtyGlassLayerSpecular<double> spec = layer.Specular(wi);
    const double sigma = std::sqrt(0.25 / o.num_paths);
    EXPECT_NEAR(r.reflected.specular_gu, spec.reflectance, 4 * sigma) << c.name;
    EXPECT_NEAR(r.transmitted.specular_gu, spec.transmittance, 4 * sigma) << c.name;
  }
}

// Frisvad et al. 2005 Eqs. 4, 5 (HG phase) against the index-matched MC's single-scatter tally
// at oblique incidence: agreement within noise, with E(0) the beam-normal irradiance (the
// BSDF forms divide by mu0).
TEST(LayerPathTracer, FrisvadMatchesSingleScatterTally) {
  for (double g : {0.0, 0.7}) {
    LayerPathTracerOptions o;
    o.tau = 0.2;
    o.albedo = 0.8;
    o.g = g;
    o.n1 = o.n2 = o.n3 = 1.0;
    o.incident_theta_rad = 0.9;
    o.num_paths = 1000000;
    o.seed = 11;
    const LayerPathTracerResult r = TraceLayer(o);
    ThinSlab<double> slab;
    slab.tau1 = o.tau;
    slab.albedo = o.albedo;
    slab.g = g;
    const double mu0 = std::cos(o.incident_theta_rad);
    const Vec3 wi = IncidentDir(o);
    // Exit azimuth relative to the direction towards the light: phi of wo (wi is at phi 0).
    const Bsdf fr = [&](const Vec3& wo) {
      return slab.ReflectedBsdf(mu0, wo.z(), -wi.dot(wo));
    };
    const Bsdf ft = [&](const Vec3& wo) {
      return slab.TransmittedBsdf(mu0, -wo.z(), -wi.dot(wo));
    };
    const Agreement refl = Compare(ModelBins(fr, r, 1), r.reflected.single);
    const Agreement trans = Compare(ModelBins(ft, r, -1), r.transmitted.single);
    std::printf("Frisvad g=%.1f: BRDF bins %3d chi2/bin %.2f max|z| %.1f | BTDF bins %3d chi2/bin %.2f max|z| %.1f\n",
                g, refl.bins, refl.chi2_per_bin, refl.max_abs_z, trans.bins, trans.chi2_per_bin,
                trans.max_abs_z);
    EXPECT_GT(refl.bins, 40);
    EXPECT_GT(trans.bins, 40);
    EXPECT_LT(refl.chi2_per_bin, 1.6) << "g=" << g;
    EXPECT_LT(trans.chi2_per_bin, 1.6) << "g=" << g;
    EXPECT_LT(refl.max_abs_z, 5.0);
    EXPECT_LT(trans.max_abs_z, 5.0);
    // The direct term of Eqs. 7-8.
    EXPECT_NEAR(r.transmitted.specular, slab.DirectTransmittance(mu0),
                4 * std::sqrt(0.25 / o.num_paths));
    // Scattered flux: the BSDF form carries it; reading E(0) as the surface irradiance (Frisvad
    // Eq. 6 inserted into Eq. 4) loses the factor mu0 = 0.62.
    const Bsdf ft_radiance = [&](const Vec3& wo) {
      return slab.TransmittedRadiance(mu0, -wo.z(), -wi.dot(wo));
    };
    const double mc_flux = Flux(r.transmitted.single.value, r);
    EXPECT_NEAR(Flux(ModelBins(ft, r, -1), r) / mc_flux, 1.0, 0.01);
    EXPECT_NEAR(Flux(ModelBins(ft_radiance, r, -1), r) / mc_flux, mu0, 0.01);
  }
}

// Frisvad et al. quote (after Chandrasekhar p. 205) that for tau1 <= 0.2 the single-scattering
// approximation is within 1 % of the correct value. Measured against full transport for
// conservative isotropic scattering (the hardest case): scattered flux ratio model / MC on
// each side, the same for the total emergent flux on the far side (direct + diffuse, Eq. 8),
// and the RMS relative difference of the diffuse lobes. Printed (docs/models/thin_slab.md);
// asserted only as a bound (the model never exceeds full transport).
TEST(LayerPathTracer, FrisvadVersusFullTransportTable) {
  std::printf("\nFrisvad thin slab vs full MC, index-matched, g 0, albedo 1, 4e5 paths, 8 x 6 bins\n");
  std::printf("  mu0  tau1 | R flux ratio  rms_rel | T flux ratio  rms_rel | total T (direct+diffuse) ratio\n");
  for (double mu0 : {1.0, 0.5}) {
    for (double tau : {0.05, 0.1, 0.2, 0.5, 1.0}) {
      LayerPathTracerOptions o;
      o.tau = tau;
      o.albedo = 1.0;
      o.g = 0.0;
      o.n1 = o.n2 = o.n3 = 1.0;
      o.incident_theta_rad = std::acos(mu0);
      o.num_paths = 400000;
      o.num_mu_bins = 8;
      o.num_phi_bins = 6;
      o.seed = 5;
      const LayerPathTracerResult r = TraceLayer(o);
      const ThinSlab<double> slab{tau, 1.0, 0.0};
      const Vec3 wi = IncidentDir(o);
      const Bsdf fr = [&](const Vec3& wo) { return slab.ReflectedBsdf(mu0, wo.z(), -wi.dot(wo)); };
      const Bsdf ft = [&](const Vec3& wo) { return slab.TransmittedBsdf(mu0, -wo.z(), -wi.dot(wo)); };
      const std::vector<double> mr = ModelBins(fr, r, 1), mt = ModelBins(ft, r, -1);
      const RmsRel rr = RmsRelative(mr, Sum(r.reflected.single, r.reflected.multiple), 0.1);
      const RmsRel rt = RmsRelative(mt, Sum(r.transmitted.single, r.transmitted.multiple), 0.1);
      const double ratio_r = Flux(mr, r) / r.reflected.scattered_flux;
      const double ratio_t = Flux(mt, r) / r.transmitted.scattered_flux;
      const double direct = slab.DirectTransmittance(mu0);
      const double ratio_total = (direct + Flux(mt, r)) / (r.transmitted.specular + r.transmitted.scattered_flux);
      std::printf("  %4.2f %4.2f |  %6.3f     %6.3f   |  %6.3f     %6.3f   | %6.4f\n", mu0, tau, ratio_r,
                  rr.rms_rel, ratio_t, rt.rms_rel, ratio_total);
      // Single scattering only drops light (albedo 1: all of it would eventually leave).
      EXPECT_LT(ratio_r, 1.0);
      EXPECT_LT(ratio_t, 1.0);
      EXPECT_LT(ratio_total, 1.0);
      // Frisvad et al. quote < 1 % for tau <= 0.2 (Chandrasekhar); measured, the total
      // transmitted light (direct + single) stays within 1 % only to tau 0.1 at normal
      // incidence (2.5 % low at 0.2): assert what holds (docs/models/thin_slab.md).
      if (mu0 == 1.0 && tau <= 0.1) {
        EXPECT_GT(ratio_total, 0.99) << "tau " << tau;
      }
    }
  }
}

// Light scattered once from the refracted incident beam and then mirrored by the face it
// first meets (Fresnel, or total internal reflection beyond asin(n1 / n2) at the air face)
// lands in the opposite lobe; Gu's single-scatter terms drop these paths. Returned relative
// to the lobe it lands in (HG-weighted over scattering directions, attenuation ignored):
// *to_brdf = (scattered towards the glass and mirrored) / (scattered towards the air), and
// *to_btdf the other way round.
void MirroredScatterShares(const LayerPathTracerOptions& o, double* to_brdf, double* to_btdf) {
  const double s_i = o.n1 * std::sin(o.incident_theta_rad) / o.n2;
  const Vec3 d_i(-s_i, 0, -std::sqrt(1 - s_i * s_i));  // Propagation in the layer.
  const int n_mu = 400, n_phi = 200;
  double up = 0, down = 0, up_mirrored = 0, down_mirrored = 0;
  for (int a = 0; a < n_mu; ++a) {
    const double z = -1 + (a + 0.5) * 2.0 / n_mu;
    const double s = std::sqrt(1 - z * z);
    for (int b = 0; b < n_phi; ++b) {
      const double phi = (b + 0.5) * 2 * kPi / n_phi;
      const Vec3 d(s * std::cos(phi), s * std::sin(phi), z);
      const double p = HenyeyGreenstein(d_i.dot(d), o.g);
      if (z > 0) {
        up += p;
        up_mirrored += p * FresnelDielectric(z, o.n1 / o.n2);
      } else {
        down += p;
        down_mirrored += p * FresnelDielectric(-z, o.n3 / o.n2);
      }
    }
  }
  *to_brdf = down_mirrored / up;
  *to_btdf = up_mirrored / down;
}

// Gu's model against full transport (all scattering orders, all interface paths) as a
// function of tau and albedo: RMS relative difference of the diffuse lobes over the exit bins
// the MC resolves to 10 %, and the ratio of scattered flux (model / MC). Asserted where single
// scattering should hold (tau <= 0.3, albedo <= 0.5) against an a-priori estimate of what the
// model neglects, per lobe:
//   multiple scattering: a once-scattered photon scatters again with probability ~ omega0
//     times its optical path to the boundary, tau_p = tau (1 + ln(1 / tau)) averaged over exit
//     cosines (min(tau / mu, 1) integrated over mu; grazing exits dominate). Relative to the
//     forward (BTDF) lobe that is omega0 tau_p; the weak back (BRDF) lobe gets it from both
//     "forward then back" and "back then forward", 2 omega0 tau_p;
//   mirrored single scattering, relative to the lobe it lands in (MirroredScatterShares);
//   plus 3x the MC's own RMS relative noise.
// Printed everywhere (docs/models/dirty_glass_layer.md).
TEST(LayerPathTracer, GuVersusFullTransportTable) {
  struct Material {
    const char* name;
    double n2;
  };
  for (const Material& m : {Material{"dust (n2 = n1 = 1)", 1.0}, Material{"lipid (n2 = 1.4)", 1.4}}) {
    std::printf("\nGu layer model vs full MC transport, %s, n3 1.52 semi-infinite, g 0.6, theta_i 30 deg "
                "from air, 1e6 (asserted cells 2e6) paths, 8 x 6 bins\n", m.name);
    std::printf("  tau albedo | BTDF rms_rel [vs Gu paths] (MC noise) flux | BRDF rms_rel [vs Gu paths] (MC "
                "noise) flux | MC multiple share | tol BTDF BRDF\n");
    for (double tau : {0.05, 0.1, 0.3, 1.0, 2.0}) {
      for (double albedo : {0.1, 0.5, 0.9}) {
        LayerPathTracerOptions o;
        o.tau = tau;
        o.albedo = albedo;
        o.g = 0.6;
        o.n2 = m.n2;
        o.n3 = 1.52;
        o.incident_theta_rad = 30 * kPi / 180;
        const bool asserted = tau <= 0.3 && albedo <= 0.5;
        o.num_paths = asserted ? 2000000 : 1000000;  // The weak back-scattered lobe needs it.
        o.num_mu_bins = 8;
        o.num_phi_bins = 6;
        o.seed = 3;
        const LayerPathTracerResult r = TraceLayer(o);
        const DirtyGlassLayer<double> layer = GuLayer(o);
        const Vec3 wi = IncidentDir(o);
        const Bsdf f = [&](const Vec3& wo) { return layer.Bsdf(wi, wo); };
        const std::vector<double> model_t = ModelBins(f, r, -1), model_r = ModelBins(f, r, 1);
        const LayerBsdfEstimate all_t = Sum(r.transmitted.single, r.transmitted.multiple);
        const LayerBsdfEstimate all_r = Sum(r.reflected.single, r.reflected.multiple);
        // Bins resolved to 10 %; the MC noise is part of the tolerance below.
        const RmsRel t = RmsRelative(model_t, all_t, 0.1), rr = RmsRelative(model_r, all_r, 0.1);
        const RmsRel t_gu = RmsRelative(model_t, r.transmitted.single_gu, 0.1);
        const RmsRel r_gu = RmsRelative(model_r, r.reflected.single_gu, 0.1);
        const double flux_t = Flux(model_t, r) / r.transmitted.scattered_flux;
        const double flux_r = Flux(model_r, r) / r.reflected.scattered_flux;
        const double multiple =
            (Flux(r.transmitted.multiple.value, r) + Flux(r.reflected.multiple.value, r)) /
            (r.transmitted.scattered_flux + r.reflected.scattered_flux);
        double mirror_r = 0, mirror_t = 0;
        MirroredScatterShares(o, &mirror_r, &mirror_t);
        const double tau_p = tau * (1 + std::log(1 / tau));
        const double tol_t = albedo * tau_p + mirror_t, tol_r = 2 * albedo * tau_p + mirror_r;
        std::printf("  %4.2f %4.2f  | %6.3f [%5.3f] (%5.3f) %5.3f | %6.3f [%5.3f] (%5.3f) %5.3f | %5.3f | %5.3f %5.3f\n",
                    tau, albedo, t.rms_rel, t_gu.rms_rel, t.rms_noise, flux_t, rr.rms_rel, r_gu.rms_rel,
                    rr.rms_noise, flux_r, multiple, tol_t, tol_r);
        if (asserted) {
          SCOPED_TRACE(std::string(m.name) + " tau=" + std::to_string(tau) +
                       " albedo=" + std::to_string(albedo));
          EXPECT_GE(t.bins, 8);  // Dust: light reaches the glass only within asin(1 / n3).
          EXPECT_GE(rr.bins, 4);
          EXPECT_LT(t.rms_rel, tol_t + 3 * t.rms_noise);
          EXPECT_LT(rr.rms_rel, tol_r + 3 * rr.rms_noise);
          EXPECT_LT(std::abs(flux_t - 1), tol_t);
          EXPECT_LT(std::abs(flux_r - 1), tol_r);
          // The model only drops light: it never exceeds full transport.
          EXPECT_LT(flux_t, 1.0);
          EXPECT_LT(flux_r, 1.0);
        }
      }
    }
  }
}

}  // namespace
}  // namespace thinslab
