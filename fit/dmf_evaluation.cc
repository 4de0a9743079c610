// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/dmf_evaluation.h"

#include <glog/logging.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <nlohmann/json.hpp>

#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/parallel.h"
#include "thinslab/optics/microfacet.h"

namespace thinslab {
namespace {

// Points scored between two progress reports (and between cancellation checks).
constexpr int kPointsPerReport = 4096;

// body(first, count) over [first, first + count) in chunks of kPointsPerReport points, each
// chunk reported to `progress` as the points before its end (point index order).
Status ForEachReportedChunk(int first, int count, ProgressTracker* progress, const char* what,
                            const std::function<void(int first, int count)>& body) {
  for (int start = first; start < first + count; start += kPointsPerReport) {
    const int n = std::min(kPointsPerReport, first + count - start);
    body(start, n);
    if (progress != nullptr && !progress->Report(start + n)) {
      return Status::Error(std::string(what) + ": cancelled");
    }
  }
  return Status::Ok();
}

double Median(std::vector<double> v) {
  if (v.empty()) return -1;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  return v[v.size() / 2];
}

Status ReadFace(const nlohmann::json& j, const std::string& where, DmfTruthFace* face) {
  if (!j.is_object() || !j.contains("ndf") || !j.contains("alpha_x") || !j.contains("alpha_y") ||
      !j.contains("flat")) {
    return Status::Error(where + ": needs ndf, alpha_x, alpha_y, flat");
  }
  face->ndf = j["ndf"].get<std::string>();
  if (face->ndf != "ggx" && face->ndf != "beckmann") return Status::Error(where + ".ndf: '" + face->ndf + "' unknown");
  face->alpha_x = j["alpha_x"].get<double>();
  face->alpha_y = j["alpha_y"].get<double>();
  face->flat = j["flat"].get<bool>();
  return Status::Ok();
}

}  // namespace

const DmfTruthFace* DmfTruthRegion::SingleRoughFace() const {
  if (top.flat == bottom.flat) return nullptr;
  return top.flat ? &bottom : &top;
}

Status ReadDmfTruth(const std::string& session_dir, std::vector<DmfTruthRegion>* regions) {
  const std::string path = JoinPath(JoinPath(session_dir, "ground_truth"), "truth.json");
  std::string text;
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(path, &text));
  regions->clear();
  try {
    const nlohmann::json j = nlohmann::json::parse(text);
    if (!j.contains("regions") || !j["regions"].is_array()) return Status::Error(path + ": regions missing");
    for (size_t k = 0; k < j["regions"].size(); ++k) {
      const nlohmann::json& r = j["regions"][k];
      const std::string where = path + ": regions[" + std::to_string(k) + "]";
      DmfTruthRegion region;
      region.name = r.at("name").get<std::string>();
      region.min_m = Eigen::Vector2d(r.at("min_m")[0].get<double>(), r.at("min_m")[1].get<double>());
      region.max_m = Eigen::Vector2d(r.at("max_m")[0].get<double>(), r.at("max_m")[1].get<double>());
      THINSLAB_RETURN_IF_ERROR(ReadFace(r.at("top"), where + ".top", &region.top));
      THINSLAB_RETURN_IF_ERROR(ReadFace(r.at("bottom"), where + ".bottom", &region.bottom));
      region.rho_d = r.at("rho_d").get<double>();
      region.k_s = r.at("k_s").get<double>();
      regions->push_back(region);
    }
  } catch (const nlohmann::json::exception& e) {
    return Status::Error(path + ": " + e.what());
  }
  return Status::Ok();
}

double TrueNdf(const DmfTruthFace& face, const Eigen::Vector3d& m) {
  if (face.ndf == "beckmann") return BeckmannDistribution(face.alpha_x, face.alpha_y).D(m);
  return GgxDistribution(face.alpha_x, face.alpha_y).D(m);
}

double NdfRelativeL2(const DmfPointFit& fit, const DmfNdfGrid& grid, const DmfTruthFace& face) {
  if (fit.log_ndf.empty()) return -1;
  double num = 0, den = 0;
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    if (!grid.InDisk(cell)) continue;
    const double x = grid.CellCentre(cell % grid.n()), y = grid.CellCentre(cell / grid.n());
    const Eigen::Vector3d m(x, y, std::sqrt(std::max(0.0, 1 - x * x - y * y)));
    const double t = TrueNdf(face, m);
    num += Sqr(std::exp(fit.log_ndf[cell]) - t);
    den += t * t;
  }
  return den > 0 ? std::sqrt(num / den) : -1;
}

std::vector<DmfRegionAccuracy> CompareDmfWithTruth(const DmfSliceSet& slices, const DmfMaps& maps,
                                                   const std::vector<DmfTruthRegion>& regions,
                                                   double held_out_tolerance) {
  std::vector<DmfRegionAccuracy> out;
  const Status status = CompareDmfWithTruth(slices, maps, regions, held_out_tolerance, &out);
  CHECK(status.ok()) << status.message();  // Slices in memory: nothing to read.
  return out;
}

Status CompareDmfWithTruth(const DmfSliceSet& slices, const DmfMaps& maps, const std::vector<DmfTruthRegion>& regions,
                           double held_out_tolerance, std::vector<DmfRegionAccuracy>* accuracy,
                           const ProgressCallback& progress, const std::vector<double>* held_out_errors) {
  const DmfNdfGrid grid(maps.ndf_resolution);
  const bool held_out = std::any_of(slices.train.begin(), slices.train.end(), [](uint8_t t) { return t == 0; });
  const int64_t n = slices.num_points();
  constexpr char kWhat[] = "CompareDmfWithTruth";
  if (held_out_errors != nullptr && held_out_errors->size() != static_cast<size_t>(n)) {
    return Status::Error(std::string(kWhat) + ": held-out errors of " + std::to_string(held_out_errors->size()) +
                         " points for " + std::to_string(n));
  }
  // Held-out errors first, one band of points at a time (streamed slices): the costly part, a
  // stage of its own so that each ETA counts items of one cost.
  std::vector<double> held_out_error(slices.num_points(), -1);
  if (held_out && held_out_errors != nullptr) {
    held_out_error = *held_out_errors;
  } else if (held_out) {
    ProgressTracker errors(progress, "fit dmf: ground truth, held-out errors", n);
    THINSLAB_RETURN_IF_ERROR(ForEachPointBand(slices, [&](int first, int count) {
      return ForEachReportedChunk(first, count, &errors, kWhat, [&](int start, int chunk) {
        ParallelFor(chunk, DefaultThreadCount(),
                    [&](int k) { held_out_error[start + k] = DmfHeldOutError(slices, maps, start + k); });
      });
    }));
  }
  ProgressTracker tracker(progress, "fit dmf: ground truth, regions", static_cast<int64_t>(regions.size()) * n);
  int64_t done = 0;
  std::vector<DmfRegionAccuracy>& out = *accuracy;
  out.clear();
  for (const DmfTruthRegion& r : regions) {
    DmfRegionAccuracy a;
    a.name = r.name;
    a.true_k_s = r.k_s;
    a.true_rho_d = r.rho_d;
    std::vector<double> alpha, ndf, held, k_s, rho_d, roughness;
    const DmfTruthFace* single = r.SingleRoughFace();
    int family_right = 0, family_undecided = 0, face_right = 0;
    const bool isotropic_single = single != nullptr && single->alpha_x == single->alpha_y;
    const bool same_faces = !r.top.flat && !r.bottom.flat && r.top.ndf == r.bottom.ndf &&
                            r.top.alpha_x == r.bottom.alpha_x && r.top.alpha_y == r.bottom.alpha_y;
    const double true_alpha = single != nullptr ? (single == &r.top ? 1.0 : 0.0) : same_faces ? 0.5 : -1;
    int covered = 0, rough_1 = 0, rough_2 = 0, alpha_1 = 0, alpha_2 = 0;
    const double margin = slices.pitch_m;
    for (int p = 0; p < slices.num_points(); ++p) {
      if ((p + 1) % kPointsPerReport == 0 && !tracker.Report(done + p + 1))
        return Status::Error(std::string(kWhat) + ": cancelled");
      const Eigen::Vector3d x = slices.PointPosition(p);
      if (x.x() < r.min_m.x() + margin || x.x() > r.max_m.x() - margin || x.y() < r.min_m.y() + margin ||
          x.y() > r.max_m.y() - margin) {
        continue;
      }
      ++a.points;
      const DmfPointFit& f = maps.fits[p];
      ++a.statuses[static_cast<int>(f.status)];
      const bool ok = f.status == DmfStatus::kOk || f.status == DmfStatus::kInterpolated;
      ++(ok ? a.ok : a.flagged);
      if (!f.HasNdf()) continue;
      ++a.fitted;
      alpha.push_back(f.alpha);
      k_s.push_back(f.k_s);
      rho_d.push_back(f.rho_d);
      roughness.push_back(f.roughness.roughness);
      if (ok) {
        ++covered;
        if (isotropic_single) {
          const double e = std::abs(f.roughness.roughness - single->alpha_x);
          rough_1 += e <= f.sigma_roughness;
          rough_2 += e <= 2 * f.sigma_roughness;
        }
        if (true_alpha >= 0) {
          const double e = std::abs(f.alpha - true_alpha);
          alpha_1 += e <= f.sigma_alpha;
          alpha_2 += e <= 2 * f.sigma_alpha;
        }
      }
      if (single != nullptr) {
        ndf.push_back(NdfRelativeL2(f.log_ndf.empty() ? maps.FitWithNdf(p) : f, grid, *single));
        family_right += NdfFamilyName(f.roughness.family) == single->ndf;
        family_undecided += f.roughness.family == NdfFamily::kUndecided;
        face_right += RoughFaceOf(f.alpha) == (single == &r.top ? RoughFace::kTop : RoughFace::kBottom);
      }
      bool correct = f.k_s * kDmfCorrectKsRatio >= r.k_s && f.k_s <= kDmfCorrectKsRatio * r.k_s;
      if (const DmfTruthFace* face = r.SingleRoughFace()) correct = correct && (f.alpha > 0.5) == (face == &r.top);
      if (held_out) {
        const double e = held_out_error[p];
        if (e >= 0) held.push_back(e);
        if (ok && e > held_out_tolerance) ++a.silent_wrong;
        correct = correct && e <= held_out_tolerance;
      }
      ++(correct ? a.correct : a.wrong);
      if (!ok) ++(correct ? a.false_alarms : a.detected);
    }
    a.median_alpha = Median(alpha);
    a.median_ndf_l2 = Median(ndf);
    a.median_held_out = Median(held);
    a.median_k_s = Median(k_s);
    a.median_rho_d = Median(rho_d);
    a.median_roughness = Median(roughness);
    if (covered > 0 && isotropic_single) {
      a.roughness_within_1_sigma = static_cast<double>(rough_1) / covered;
      a.roughness_within_2_sigma = static_cast<double>(rough_2) / covered;
    }
    if (covered > 0 && true_alpha >= 0) {
      a.alpha_within_1_sigma = static_cast<double>(alpha_1) / covered;
      a.alpha_within_2_sigma = static_cast<double>(alpha_2) / covered;
    }
    if (single != nullptr && a.fitted > 0) {
      a.true_roughness = std::sqrt(single->alpha_x * single->alpha_y);
      a.family_right = static_cast<double>(family_right) / a.fitted;
      a.family_undecided = static_cast<double>(family_undecided) / a.fitted;
      a.face_right = static_cast<double>(face_right) / a.fitted;
    }
    out.push_back(a);
    done += n;
    if (!tracker.Report(done)) return Status::Error(std::string(kWhat) + ": cancelled");
  }
  return Status::Ok();
}

std::string DmfComparisonJson(const std::vector<DmfRegionAccuracy>& accuracy) {
  nlohmann::json j;
  j["format"] = "thinslab-dmf-comparison";
  j["note"] = "medians over points at least one grid pitch inside each region; -1 = not applicable";
  for (const DmfRegionAccuracy& a : accuracy) {
    nlohmann::json statuses = nlohmann::json::object();
    for (const auto& [code, n] : a.statuses) statuses[DmfStatusName(static_cast<DmfStatus>(code))] = n;
    j["regions"].push_back({{"name", a.name},
                            {"statuses", statuses},
                            {"points", a.points},
                            {"fitted", a.fitted},
                            {"median_alpha", a.median_alpha},
                            {"median_ndf_relative_l2", a.median_ndf_l2},
                            {"median_held_out_relative_rms", a.median_held_out},
                            {"median_k_s", a.median_k_s},
                            {"true_k_s", a.true_k_s},
                            {"median_rho_d", a.median_rho_d},
                            {"true_rho_d", a.true_rho_d},
                            {"ok", a.ok},
                            {"flagged", a.flagged},
                            {"ok_with_held_out_above_0.5", a.silent_wrong},
                            {"correct", a.correct},
                            {"flagged_correct", a.false_alarms},
                            {"wrong", a.wrong},
                            {"flagged_wrong", a.detected},
                            {"median_equivalent_roughness", a.median_roughness},
                            {"true_roughness", a.true_roughness},
                            {"family_right_fraction", a.family_right},
                            {"family_undecided_fraction", a.family_undecided},
                            {"rough_face_right_fraction", a.face_right},
                            {"roughness_within_1_sigma", a.roughness_within_1_sigma},
                            {"roughness_within_2_sigma", a.roughness_within_2_sigma},
                            {"top_face_weight_within_1_sigma", a.alpha_within_1_sigma},
                            {"top_face_weight_within_2_sigma", a.alpha_within_2_sigma}});
  }
  return j.dump(2) + "\n";
}

namespace {
// Predictions of the dots `use` selects (positions; each point's values and sigmas from
// `values(p)` and `sigmas(p)`, sigmas may be nullptr) against their measurements, as
// EvaluateValidationDots describes; points visited band by band (ForEachPointBand) when
// `banded`, else all at once. `point_errors` (optional): every point's relative RMS error,
// flagged points' too (-1 where none: no NDF, no dot in the lobe).
template <typename Values, typename Sigmas>
Status EvaluateDotPredictions(const DmfSliceSet& slices, const DmfMaps& maps,
                              const std::vector<DmfTruthRegion>& regions, double lobe_fraction,
                              const std::vector<Eigen::Vector3d>& positions, const Values& values, const Sigmas& sigmas,
                              const std::vector<uint8_t>& use, bool banded, int num_threads,
                              std::vector<DmfValidationError>* result, ProgressTracker* progress, const char* what,
                              std::vector<double>* point_errors = nullptr) {
  const int nd = static_cast<int>(positions.size());
  std::vector<DmfValidationError>& out = *result;
  out.assign(1 + regions.size(), DmfValidationError());
  out[0].region = "all";
  for (size_t r = 0; r < regions.size(); ++r) out[1 + r].region = regions[r].name;
  if (std::none_of(use.begin(), use.end(), [](uint8_t u) { return u != 0; })) return Status::Ok();
  const DmfNdfGrid grid(maps.ndf_resolution);
  std::vector<double> num(out.size(), 0), den(out.size(), 0), noise(out.size(), 0), unsampled_num(out.size(), 0);
  std::vector<std::vector<double>> point_rms(out.size());
  // One point's pairs (on the threads); the sums below in point order, whatever the threads.
  struct PointScore {
    bool scored = false, unsampled_peak = false;
    int pairs = 0;
    double num = 0, den = 0, noise = 0;
  };
  if (point_errors != nullptr) point_errors->assign(slices.num_points(), -1);
  auto score_point = [&](int p) {
    PointScore score;
    const DmfPointFit& stored = maps.fits[p];
    const bool pooled = stored.status == DmfStatus::kOk || stored.status == DmfStatus::kInterpolated;
    if ((!pooled && point_errors == nullptr) || !stored.HasNdf()) return score;
    const Eigen::Vector3d x = slices.PointPosition(p);
    const Eigen::Vector3d entry = slices.LightEntryPoint(p);
    const Eigen::Vector3d o = SampleToOptical((slices.camera_centre - x).normalized());
    const float* value = values(p);
    const float* sigma = sigmas(p);
    double peak = 0;
    for (int v = 0; v < nd; ++v) {
      if (use[v]) peak = std::max(peak, value[v] - stored.rho_d);
    }
    if (!(peak > 0)) return score;
    // The lobe the fit saw: the point's highest training dot.
    const float* grid_values = slices.PointValues(p);
    double training_peak = 0;
    for (size_t q = 0; q < slices.train.size(); ++q) {
      if (slices.train[q] != 0) training_peak = std::max(training_peak, grid_values[q] - stored.rho_d);
    }
    score.scored = true;
    score.unsampled_peak = peak > kUnsampledPeakFactor * training_peak;
    DmfPointFit rebuilt;
    const DmfPointFit& fit = stored.log_ndf.empty() ? (rebuilt = maps.FitWithNdf(p)) : stored;
    for (int v = 0; v < nd; ++v) {
      const double above = value[v] - fit.rho_d;
      if (!use[v] || above < lobe_fraction * peak) continue;
      const Eigen::Vector3d i = SampleToOptical((positions[v] - entry).normalized());
      const double d = PredictDualMicrofacet(fit, grid, maps.eta, i, o) - value[v];
      score.num += d * d;
      score.den += above * above;
      if (sigma != nullptr) score.noise += Sqr(static_cast<double>(sigma[v]));
      ++score.pairs;
    }
    if (point_errors != nullptr && score.den > 0) (*point_errors)[p] = std::sqrt(score.num / score.den);
    score.scored = pooled;  // Flagged points: their error only, outside the pooled figures.
    return score;
  };
  std::vector<PointScore> scores;
  auto score_chunk = [&](int first, int count) {
    scores.assign(count, PointScore());
    ParallelFor(count, num_threads, [&](int k) { scores[k] = score_point(first + k); });
    for (int k = 0; k < count; ++k) {
      const PointScore& s = scores[k];
      if (!s.scored) continue;
      auto add = [&](size_t r) {
        ++out[r].points;
        out[r].pairs += s.pairs;
        num[r] += s.num;
        den[r] += s.den;
        noise[r] += s.noise;
        if (s.den > 0) point_rms[r].push_back(std::sqrt(s.num / s.den));
        if (s.unsampled_peak) {
          ++out[r].unsampled_peak_points;
          unsampled_num[r] += s.num;
        }
      };
      add(0);
      const Eigen::Vector3d x = slices.PointPosition(first + k);
      for (size_t r = 0; r < regions.size(); ++r) {
        const DmfTruthRegion& region = regions[r];
        const double margin = slices.pitch_m;
        if (x.x() >= region.min_m.x() + margin && x.x() <= region.max_m.x() - margin &&
            x.y() >= region.min_m.y() + margin && x.y() <= region.max_m.y() - margin) {
          add(1 + r);
        }
      }
    }
  };
  auto points = [&](int first, int count) { return ForEachReportedChunk(first, count, progress, what, score_chunk); };
  THINSLAB_RETURN_IF_ERROR(banded ? ForEachPointBand(slices, points) : points(0, slices.num_points()));
  for (size_t k = 0; k < out.size(); ++k) {
    if (!(den[k] > 0)) continue;
    out[k].relative_rms = std::sqrt(num[k] / den[k]);
    out[k].noise_relative_rms = std::sqrt(noise[k] / den[k]);
    out[k].unsampled_peak_error_share = num[k] > 0 ? unsampled_num[k] / num[k] : 0;
    std::vector<double>& r = point_rms[k];
    if (!r.empty()) {
      std::nth_element(r.begin(), r.begin() + r.size() / 2, r.end());
      out[k].median_point_relative_rms = r[r.size() / 2];
    }
  }
  return Status::Ok();
}
}  // namespace

Status EvaluateValidationDots(const DmfSliceSet& slices, const DmfMaps& maps,
                              const std::vector<DmfTruthRegion>& regions, double lobe_fraction, int num_threads,
                              std::vector<DmfValidationError>* out, const ProgressCallback& progress) {
  const DmfValidationDots& validation = slices.validation;
  const size_t nv = validation.positions.size();
  ProgressTracker tracker(progress, "fit dmf: validation dots", nv > 0 ? slices.num_points() : 0);
  // Streamed: the training dots' values (each point's training peak) are read band by band.
  return EvaluateDotPredictions(
      slices, maps, regions, lobe_fraction, validation.positions,
      [&](int p) { return validation.value.data() + static_cast<size_t>(p) * nv; },
      [&](int p) { return validation.sigma.empty() ? nullptr : validation.sigma.data() + static_cast<size_t>(p) * nv; },
      std::vector<uint8_t>(nv, 1), slices.spill != nullptr, num_threads, out, &tracker, "EvaluateValidationDots");
}

std::vector<DmfValidationError> EvaluateValidationDots(const DmfSliceSet& slices, const DmfMaps& maps,
                                                       const std::vector<DmfTruthRegion>& regions,
                                                       double lobe_fraction) {
  std::vector<DmfValidationError> out;
  const Status status = EvaluateValidationDots(slices, maps, regions, lobe_fraction, DefaultThreadCount(), &out);
  CHECK(status.ok()) << status.message();  // In memory: nothing to read.
  return out;
}

Status EvaluateHeldOutDots(const DmfSliceSet& slices, const DmfMaps& maps, const std::vector<DmfTruthRegion>& regions,
                           double lobe_fraction, int num_threads, std::vector<DmfValidationError>* out,
                           const ProgressCallback& progress, std::vector<double>* point_errors) {
  ProgressTracker tracker(progress, "fit dmf: held-out dots", slices.num_points());
  std::vector<uint8_t> held_out(slices.train.size());
  for (size_t q = 0; q < held_out.size(); ++q) held_out[q] = slices.train[q] == 0;
  return EvaluateDotPredictions(
      slices, maps, regions, lobe_fraction, slices.dot_positions, [&](int p) { return slices.PointValues(p); },
      [&](int p) { return slices.PointSigmas(p); }, held_out, true, num_threads, out, &tracker, "EvaluateHeldOutDots",
      point_errors);
}

std::vector<DmfValidationError> EvaluateHeldOutDots(const DmfSliceSet& slices, const DmfMaps& maps,
                                                    const std::vector<DmfTruthRegion>& regions, double lobe_fraction) {
  std::vector<DmfValidationError> out;
  const Status status =
      EvaluateHeldOutDots(slices, maps, regions, lobe_fraction, DefaultThreadCount(), &out, ProgressCallback());
  CHECK(status.ok()) << status.message();  // Slices in memory: nothing to read.
  return out;
}

}  // namespace thinslab
