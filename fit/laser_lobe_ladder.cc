// SPDX-License-Identifier: Apache-2.0
#include "fit/laser_lobe_ladder.h"

#include <chrono>
#include <functional>
#include <cmath>
#include <nlohmann/json.hpp>

#include "core/math.h"
#include "fit/ladder_choice.h"
#include "optics/dirty_glass.h"
#include "optics/thin_slab.h"

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

Status FitLaserLobeLadder(const std::vector<LaserRing>& rings, const PhaseFitOptions& options,
                          double significance_sigmas, LaserLadderResult* result) {
  *result = LaserLadderResult();
  std::string error;
  if (!options.Check(&error)) return Status::Error("laser ladder: " + error);
  if (!(significance_sigmas >= 0)) return Status::Error("laser ladder: significance_sigmas must be >= 0");
  if (rings.size() < 10) {
    return Status::Error("laser ladder: " + std::to_string(rings.size()) +
                         " rings; at least 10 are needed to hold every other one out");
  }
  std::vector<LaserRing> train, held_out;
  for (size_t k = 0; k < rings.size(); ++k) (k % 2 == 0 ? train : held_out).push_back(rings[k]);
  result->training_rings = static_cast<int>(train.size());
  result->held_out_rings = static_cast<int>(held_out.size());

  // Each rung as a predictor of a ring's intensity, fitted to `train`.
  std::array<std::function<double(const LaserRing&)>, kNumLaserLadderRungs> predict;
  auto t = std::chrono::steady_clock::now();
  predict[0] = [](const LaserRing&) { return 0.0; };
  result->seconds[0] = Seconds(t);

  t = std::chrono::steady_clock::now();
  double sff = 0, sfi = 0;  // Weighted least squares of the one scale (closed form).
  for (const LaserRing& r : train) {
    const double f = FrisvadLobeProfile(std::cos(r.theta_rad), options.tau);
    sff += Sqr(f / r.sigma);
    sfi += f * r.intensity / Sqr(r.sigma);
  }
  result->frisvad_beta = sff > 0 ? std::max(0.0, sfi / sff) : 0;
  const double frisvad_beta = result->frisvad_beta, tau = options.tau;
  predict[1] = [frisvad_beta, tau](const LaserRing& r) {
    return frisvad_beta * FrisvadLobeProfile(std::cos(r.theta_rad), tau);
  };
  result->seconds[1] = Seconds(t);

  t = std::chrono::steady_clock::now();
  double gu_tau = options.tau;
  const bool gu_ok = FitEq8ToRings(options, train, &result->gu_beta, &result->gu_g, &gu_tau);
  const double gu_beta = result->gu_beta, gu_g = result->gu_g;
  predict[2] = [gu_ok, gu_beta, gu_g, gu_tau](const LaserRing& r) {
    return gu_ok ? gu_beta * LaserLobeProfile(std::cos(r.theta_rad), gu_g, gu_tau) : 0.0;
  };
  result->seconds[2] = Seconds(t);

  std::vector<std::vector<double>> errors(kNumLaserLadderRungs);
  for (int k = 0; k < kNumLaserLadderRungs; ++k) {
    if (k == 2 && !gu_ok) continue;  // No positive HG lobe fits: rung 2 not available.
    double train_chi2 = 0;
    for (const LaserRing& r : train) train_chi2 += Sqr((predict[k](r) - r.intensity) / r.sigma);
    result->bic[k] = train_chi2 + result->parameters[k] * std::log(static_cast<double>(train.size()));
    for (const LaserRing& r : held_out) errors[k].push_back(Sqr((predict[k](r) - r.intensity) / r.sigma));
    double sum = 0;
    for (double e : errors[k]) sum += e;
    result->held_out_chi2[k] = sum / held_out.size();
    result->squared_errors[k] = errors[k];
  }
  result->chosen_rung = SimplestRungWithinNoise(errors, significance_sigmas);
  for (int k = 0; k < kNumLaserLadderRungs; ++k) {
    if (errors[k].empty()) continue;
    if (result->chosen_by_bic < 0 || result->bic[k] < result->bic[result->chosen_by_bic]) result->chosen_by_bic = k;
  }
  return Status::Ok();
}

std::string LaserLadderJson(const LaserLadderResult& result) {
  nlohmann::ordered_json j;
  j["chosen_rung"] = result.chosen_rung;
  j["chosen_model"] = LaserLadderRungName(result.chosen_rung);
  j["chosen_by_bic"] = result.chosen_by_bic;
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
