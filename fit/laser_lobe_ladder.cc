// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/laser_lobe_ladder.h"

#include <chrono>
#include <cmath>
#include <functional>
#include <sstream>
#include <nlohmann/json.hpp>

#include "thinslab/core/math.h"
#include "thinslab/fit/ladder_choice.h"
#include "thinslab/optics/dirty_glass.h"
#include "thinslab/optics/thin_slab.h"

namespace thinslab {
namespace {

double Seconds(std::chrono::steady_clock::time_point since) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
}

// Rung 1's lobe shape: Frisvad's single-scattered transmitted radiance of a normally lit slab
// at exit cosine mu (scattering cosine mu too), times the cos^4 of the board geometry that
// Eq. 8 carries (optics/dirty_glass.h, LaserLobeProfile).
double FrisvadLobeProfile(double cos_theta, double tau) {
  const ThinSlab<double> slab{tau, 1.0, 0.0};
  return slab.TransmittedBsdf(1.0, cos_theta, cos_theta) * Sqr(Sqr(cos_theta));
}

}  // namespace

const char* LaserLadderRungName(int rung) {
  switch (rung) {
    case 0: return "attenuator";
    case 1: return "frisvad_isotropic_slab";
    case 2: return "gu_hg_layer";
    default: return "none";
  }
}

namespace {

// Each rung fitted to `train`, as a predictor of a ring's intensity; rung 2 is empty (not
// available) when no positive HG lobe fits.
struct LadderFits {
  std::array<std::function<double(const LaserRing&)>, kNumLaserLadderRungs> predict;
  double frisvad_beta = 0, gu_beta = 0, gu_g = 0;
  std::array<double, kNumLaserLadderRungs> seconds{{0, 0, 0}};
};

LadderFits FitRungs(const std::vector<LaserRing>& train, const PhaseFitOptions& options) {
  LadderFits fits;
  auto t = std::chrono::steady_clock::now();
  fits.predict[0] = [](const LaserRing&) { return 0.0; };
  fits.seconds[0] = Seconds(t);

  t = std::chrono::steady_clock::now();
  double sff = 0, sfi = 0;  // Weighted least squares of the one scale (closed form).
  for (const LaserRing& r : train) {
    const double f = FrisvadLobeProfile(std::cos(r.theta_rad), options.tau);
    sff += Sqr(f / r.sigma);
    sfi += f * r.intensity / Sqr(r.sigma);
  }
  fits.frisvad_beta = sff > 0 ? std::max(0.0, sfi / sff) : 0;
  const double frisvad_beta = fits.frisvad_beta, tau = options.tau;
  fits.predict[1] = [frisvad_beta, tau](const LaserRing& r) {
    return frisvad_beta * FrisvadLobeProfile(std::cos(r.theta_rad), tau);
  };
  fits.seconds[1] = Seconds(t);

  t = std::chrono::steady_clock::now();
  double gu_tau = options.tau;
  if (FitEq8ToRings(options, train, &fits.gu_beta, &fits.gu_g, &gu_tau)) {
    const double gu_beta = fits.gu_beta, gu_g = fits.gu_g;
    fits.predict[2] = [gu_beta, gu_g, gu_tau](const LaserRing& r) {
      return gu_beta * LaserLobeProfile(std::cos(r.theta_rad), gu_g, gu_tau);
    };
  }
  fits.seconds[2] = Seconds(t);
  return fits;
}

}  // namespace

Status FitLaserLobeLadder(const std::vector<LaserRing>& rings, const PhaseFitOptions& options,
                          double significance_sigmas, const PhaseFitSummary* full_fit, LaserLadderResult* result) {
  *result = LaserLadderResult();
  std::string error;
  if (!options.Check(&error)) return Status::Error("laser ladder: " + error);
  if (!(significance_sigmas >= 0)) return Status::Error("laser ladder: significance_sigmas must be >= 0");
  if (rings.size() < 5) {
    return Status::Error("laser ladder: " + std::to_string(rings.size()) +
                         " rings; at least 5 are needed (rung 2 has two parameters to fit on the rest)");
  }
  const int n = static_cast<int>(rings.size());
  std::vector<std::vector<double>> errors(kNumLaserLadderRungs);
  std::array<bool, kNumLaserLadderRungs> available{{true, true, true}};
  auto score = [&](const LadderFits& fits, const std::vector<LaserRing>& held_out) {
    for (int k = 0; k < kNumLaserLadderRungs; ++k) {
      available[k] = available[k] && static_cast<bool>(fits.predict[k]);  // Rung 2 may not fit a split.
      if (!available[k]) continue;
      for (const LaserRing& r : held_out) errors[k].push_back(Sqr((fits.predict[k](r) - r.intensity) / r.sigma));
    }
  };
  // The rungs fitted to the even rings (>= 10 rings) or to all (leave-one-out): reported, and
  // the BIC of the training rings.
  LadderFits reported;
  std::vector<LaserRing> bic_rings;
  if (n >= 10) {
    // Every other ring held out: half the rings train, the other half test.
    result->split = "odd rings held out";
    std::vector<LaserRing> train, held_out;
    for (int k = 0; k < n; ++k) (k % 2 == 0 ? train : held_out).push_back(rings[k]);
    result->training_rings = static_cast<int>(train.size());
    result->held_out_rings = static_cast<int>(held_out.size());
    reported = FitRungs(train, options);
    score(reported, held_out);
    bic_rings = train;
  } else {
    // Too few rings to give half away: each ring is predicted by the rungs fitted to the others.
    result->split = "leave-one-out";
    result->training_rings = n - 1;
    result->held_out_rings = n;
    for (int k = 0; k < n; ++k) {
      std::vector<LaserRing> train;
      for (int j = 0; j < n; ++j) {
        if (j != k) train.push_back(rings[j]);
      }
      score(FitRungs(train, options), {rings[k]});
    }
    reported = FitRungs(rings, options);
    bic_rings = rings;
  }
  result->frisvad_beta = reported.frisvad_beta;
  result->gu_beta = reported.gu_beta;
  result->gu_g = reported.gu_g;
  result->seconds = reported.seconds;
  for (int k = 0; k < kNumLaserLadderRungs; ++k) {
    if (!available[k] || !reported.predict[k]) {
      errors[k].clear();
      continue;
    }
    double chi2 = 0;
    for (const LaserRing& r : bic_rings) chi2 += Sqr((reported.predict[k](r) - r.intensity) / r.sigma);
    result->bic[k] = chi2 + result->parameters[k] * std::log(static_cast<double>(bic_rings.size()));
    double sum = 0;
    for (double e : errors[k]) sum += e;
    result->held_out_chi2[k] = sum / errors[k].size();
    result->squared_errors[k] = errors[k];
  }
  result->chosen_rung = SimplestRungWithinNoise(errors, significance_sigmas);
  for (int k = 0; k < kNumLaserLadderRungs; ++k) {
    if (errors[k].empty()) continue;
    if (result->chosen_by_bic < 0 || result->bic[k] < result->bic[result->chosen_by_bic]) result->chosen_by_bic = k;
  }
  // The held-out rings may be too few to tell what the fit of all of them does: a simpler rung
  // is not kept when that fit rejects it. Rung 1 is HG at g = 0 for `fit tau --phase`, so a g
  // more than 3 sigma_g from 0 rejects it (and rung 0, no scattered light, with it).
  if (full_fit != nullptr && full_fit->IsUsable() && result->chosen_rung >= 0 && result->chosen_rung < 2 &&
      !errors[2].empty() && std::abs(full_fit->g) > 3 * full_fit->sigma_g) {
    std::ostringstream why;
    why.precision(3);
    why << "the held-out rings chose rung " << result->chosen_rung << " (" << LaserLadderRungName(result->chosen_rung)
        << "), but the fit of all " << n << " rings gives g = " << full_fit->g << " +- " << full_fit->sigma_g
        << ", " << std::abs(full_fit->g) / full_fit->sigma_g << " sigma_g from 0: rung 2";
    result->overruled_rung = result->chosen_rung;
    result->overrule_reason = why.str();
    result->chosen_rung = 2;
  }
  return Status::Ok();
}

std::string LaserLadderJson(const LaserLadderResult& result) {
  nlohmann::ordered_json j;
  j["chosen_rung"] = result.chosen_rung;
  j["chosen_model"] = LaserLadderRungName(result.chosen_rung);
  j["chosen_by_bic"] = result.chosen_by_bic;
  j["split"] = result.split;
  if (result.overruled_rung >= 0) {
    j["held_out_choice"] = result.overruled_rung;
    j["overrule_reason"] = result.overrule_reason;
  }
  j["training_rings"] = result.training_rings;
  j["held_out_rings"] = result.held_out_rings;
  nlohmann::ordered_json rungs = nlohmann::ordered_json::array();
  for (int k = 0; k < kNumLaserLadderRungs; ++k) {
    nlohmann::ordered_json r;
    r["rung"] = k;
    r["model"] = LaserLadderRungName(k);
    r["parameters"] = result.parameters[k];
    r["available"] = !result.squared_errors[k].empty();
    r["held_out_chi2_per_ring"] = result.held_out_chi2[k];
    r["bic"] = result.bic[k];
    r["seconds"] = result.seconds[k];
    rungs.push_back(r);
  }
  j["rungs"] = rungs;
  j["parameters_saved"] = result.chosen_rung >= 0 ? result.parameters[2] - result.parameters[result.chosen_rung] : 0;
  j["frisvad_beta"] = result.frisvad_beta;
  j["gu_beta"] = result.gu_beta;
  j["gu_g"] = result.gu_g;
  return j.dump(2) + "\n";
}

}  // namespace thinslab
