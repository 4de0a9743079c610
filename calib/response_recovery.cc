// SPDX-License-Identifier: Apache-2.0
#include "thinslab/calib/response_recovery.h"

#include <Eigen/Dense>
#include <Eigen/Sparse>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <random>
#include <sstream>
#include <tuple>

#include "thinslab/calib/hdr_merge.h"

namespace thinslab {

bool ResponseRecoveryOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(saturation_dn > 1)) {
    msg << "ResponseRecoveryOptions::saturation_dn = " << saturation_dn << ". Violated constraint: > 1";
  } else if (max_knots < 16 || max_knots > 4096) {
    msg << "ResponseRecoveryOptions::max_knots = " << max_knots << ". Violated constraint: 16..4096";
  } else if (num_samples < 20 || num_samples > 1000000) {
    msg << "ResponseRecoveryOptions::num_samples = " << num_samples << ". Violated constraint: 20..1e6";
  } else if (num_strata < 1 || num_strata > num_samples) {
    msg << "ResponseRecoveryOptions::num_strata = " << num_strata << ". Violated constraint: 1..num_samples";
  } else if (!(smoothness_lambda >= 0) || !std::isfinite(smoothness_lambda)) {
    msg << "ResponseRecoveryOptions::smoothness_lambda = " << smoothness_lambda << ". Violated constraint: >= 0";
  } else if (!(robertson_smoothness_lambda >= 0) || !std::isfinite(robertson_smoothness_lambda)) {
    msg << "ResponseRecoveryOptions::robertson_smoothness_lambda = " << robertson_smoothness_lambda
        << ". Violated constraint: >= 0";
  } else if (min_exposures < 2) {
    msg << "ResponseRecoveryOptions::min_exposures = " << min_exposures << ". Violated constraint: >= 2";
  } else if (max_iterations < 1) {
    msg << "ResponseRecoveryOptions::max_iterations = " << max_iterations << ". Violated constraint: >= 1";
  } else if (!(tolerance > 0)) {
    msg << "ResponseRecoveryOptions::tolerance = " << tolerance << ". Violated constraint: > 0";
  } else if (!(reference_dn >= 0 && reference_dn < saturation_dn)) {
    msg << "ResponseRecoveryOptions::reference_dn = " << reference_dn
        << ". Violated constraint: [0, saturation_dn) (0 = saturation_dn / 2)";
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

std::string ResponseRecoverySummary::BriefReport() const {
  std::ostringstream out;
  out << "response: " << num_samples << " pixels, " << num_rows << " equations, " << num_knots << " knots";
  if (iterations > 0) out << ", " << iterations << " iterations";
  out << ", rms log residual " << rms_log_residual << ", " << monotonicity_fixes << " monotonicity fixes, "
      << solve_s << " s, values cover " << static_cast<int>(std::lround(100 * dn_coverage)) << " % of the DN range";
  return out.str();
}

namespace {

std::string FrameName(const std::vector<ResponseFrame>& frames, size_t k) {
  return frames[k].name.empty() ? "frame " + std::to_string(k) : "frame '" + frames[k].name + "'";
}

bool Usable(double z, double saturation_dn) { return z > 0 && z < saturation_dn - 0.5; }

// A (pixel, exposure) equation: the sample's position on the knot grid and its weight.
struct Row {
  int sample;
  int knot;       // Left knot j; the sample lies between j and j + 1.
  double alpha;   // Position within [j, j + 1].
  double log_t;   // ln t_k.
  double t;
  double weight;  // Hat weight of z.
  double z;
};

Status CheckBracket(const std::vector<ResponseFrame>& frames, const ResponseRecoveryOptions& options) {
  if (frames.size() < static_cast<size_t>(options.min_exposures)) {
    return Status::Error("RecoverResponse: too few exposures: got " + std::to_string(frames.size()) +
                         ", need at least " + std::to_string(options.min_exposures));
  }
  for (size_t k = 0; k < frames.size(); ++k) {
    if (frames[k].dn == nullptr || frames[k].dn->empty()) {
      return Status::Error("RecoverResponse: " + FrameName(frames, k) + ": image missing");
    }
  }
  const Image& first = *frames[0].dn;
  for (size_t k = 0; k < frames.size(); ++k) {
    const ResponseFrame& f = frames[k];
    if (f.dn->width() != first.width() || f.dn->height() != first.height() || f.dn->num_channels() != 1) {
      return Status::Error("RecoverResponse: " + FrameName(frames, k) + " is " + std::to_string(f.dn->width()) + "x" +
                           std::to_string(f.dn->height()) + "x" + std::to_string(f.dn->num_channels()) + ", " +
                           FrameName(frames, 0) + " is " + std::to_string(first.width()) + "x" +
                           std::to_string(first.height()) + "x1");
    }
    if (f.bit_depth < 8 || f.bit_depth > 16) {
      return Status::Error("RecoverResponse: " + FrameName(frames, k) + ": bit_depth " + std::to_string(f.bit_depth) +
                           ": response recovery needs integer frames of 8..16 bits");
    }
    if (f.bit_depth != frames[0].bit_depth) {
      return Status::Error("RecoverResponse: mixed bit depths: " + FrameName(frames, k) + " has bit_depth " +
                           std::to_string(f.bit_depth) + ", " + FrameName(frames, 0) + " has " +
                           std::to_string(frames[0].bit_depth));
    }
    if (!(f.exposure_time_us > 0) || !std::isfinite(f.exposure_time_us)) {
      return Status::Error("RecoverResponse: " + FrameName(frames, k) + ": exposure_time_us must be > 0, got " +
                           std::to_string(f.exposure_time_us));
    }
    if (k > 0 && f.exposure_time_us == frames[k - 1].exposure_time_us) {
      return Status::Error("RecoverResponse: duplicate exposure: " + FrameName(frames, k) + " and " +
                           FrameName(frames, k - 1) + " both have exposure_time_us " +
                           std::to_string(f.exposure_time_us) + " (average repeated frames first)");
    }
    if (k > 0 && f.exposure_time_us < frames[k - 1].exposure_time_us) {
      return Status::Error("RecoverResponse: non-monotonic exposures: " + FrameName(frames, k) + " (" +
                           std::to_string(f.exposure_time_us) + " us) follows " + FrameName(frames, k - 1) + " (" +
                           std::to_string(frames[k - 1].exposure_time_us) + " us); order the bracket by exposure");
    }
  }
  // Per-frame content: a frame saturated everywhere carries nothing; a longer exposure that is
  // darker on average than a shorter one means the recorded exposures are not the applied ones.
  std::vector<double> mean(frames.size(), 0);
  for (size_t k = 0; k < frames.size(); ++k) {
    size_t saturated = 0;
    double sum = 0;
    for (float z : frames[k].dn->data()) {
      if (z >= options.saturation_dn - 0.5) ++saturated;
      sum += std::min<double>(z, options.saturation_dn);
    }
    if (saturated == frames[k].dn->data().size()) {
      return Status::Error("RecoverResponse: " + FrameName(frames, k) + ": every pixel is saturated (>= " +
                           std::to_string(options.saturation_dn) + " DN above black); drop it or shorten it");
    }
    mean[k] = sum / frames[k].dn->data().size();
    if (k > 0 && mean[k] < mean[k - 1] - 0.5 - 0.02 * std::abs(mean[k - 1])) {
      std::ostringstream msg;
      msg << "RecoverResponse: non-monotonic exposures: " << FrameName(frames, k) << " ("
          << frames[k].exposure_time_us << " us) is darker on average (" << mean[k] << " DN) than "
          << FrameName(frames, k - 1) << " (" << frames[k - 1].exposure_time_us << " us, " << mean[k - 1]
          << " DN): exposure_time_us does not match the images";
      return Status::Error(msg.str());
    }
  }
  return Status::Ok();
}

// Smoothness rows sqrt(lambda * rows / du^3) * max(w(z_j), 0.01) * (x_{j-1} - 2 x_j + x_{j+1}):
// a discretisation of rows * lambda * integral of w(u) x''(u)^2 du over u = z / z_sat, so
// lambda does not depend on sample or knot counts. The floor keeps knots without data (and the
// ends, where w = 0) determined.
void AddSmoothness(int num_knots, double lambda, int num_rows, double saturation_dn, Eigen::MatrixXd* normal) {
  if (lambda <= 0) return;
  const double du = 1.0 / (num_knots - 1);
  const double scale = lambda * num_rows / (du * du * du);
  for (int j = 1; j + 1 < num_knots; ++j) {
    const double z = saturation_dn * j * du;
    const double w = std::max(HatWeight(z, saturation_dn), 0.01);
    const double c = scale * w * w;
    const int idx[3] = {j - 1, j, j + 1};
    const double a[3] = {1, -2, 1};
    for (int p = 0; p < 3; ++p) {
      for (int q = 0; q < 3; ++q) (*normal)(idx[p], idx[q]) += c * a[p] * a[q];
    }
  }
}

double Interpolate(const Eigen::VectorXd& knots, const Row& row) {
  return (1 - row.alpha) * knots[row.knot] + row.alpha * knots[row.knot + 1];
}

// Debevec & Malik 1997: one linear least-squares problem in (g at the knots, ln E_i). The ln E_i
// are eliminated first (each appears only in its own pixel's rows: a Schur complement), leaving
// a dense knots x knots system.
Eigen::VectorXd SolveDebevec(const std::vector<Row>& rows, int num_samples, int num_knots,
                             const ResponseRecoveryOptions& options, double reference_dn, double* rms) {
  Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(num_knots, num_knots);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(num_knots);
  std::vector<double> h_ee(num_samples, 0), b_e(num_samples, 0);
  // Rows are grouped by sample (built that way); walk each sample's rows together.
  size_t r0 = 0;
  while (r0 < rows.size()) {
    size_t r1 = r0;
    while (r1 < rows.size() && rows[r1].sample == rows[r0].sample) ++r1;
    const int i = rows[r0].sample;
    // Row: w * ((1 - a) g_j + a g_{j+1} - ln E_i) = w ln t.
    std::vector<std::pair<int, double>> h;  // Column of H_gE for this sample.
    for (size_t r = r0; r < r1; ++r) {
      const Row& row = rows[r];
      const double w2 = row.weight * row.weight;
      const int idx[2] = {row.knot, row.knot + 1};
      const double c[2] = {1 - row.alpha, row.alpha};
      for (int p = 0; p < 2; ++p) {
        for (int q = 0; q < 2; ++q) normal(idx[p], idx[q]) += w2 * c[p] * c[q];
        rhs[idx[p]] += w2 * c[p] * row.log_t;
        h.emplace_back(idx[p], -w2 * c[p]);
      }
      h_ee[i] += w2;
      b_e[i] += -w2 * row.log_t;
    }
    if (h_ee[i] > 0) {
      for (const auto& [p, hp] : h) {
        rhs[p] -= hp * b_e[i] / h_ee[i];
        for (const auto& [q, hq] : h) normal(p, q) -= hp * hq / h_ee[i];
      }
    }
    r0 = r1;
  }
  AddSmoothness(num_knots, options.smoothness_lambda, static_cast<int>(rows.size()), options.saturation_dn, &normal);
  // Fixes the free offset of (g, ln E) (Debevec's g(Z_mid) = 0; here g(reference) = ln reference,
  // so that L(reference) = reference).
  const double u = reference_dn / options.saturation_dn * (num_knots - 1);
  const int j = std::min(static_cast<int>(u), num_knots - 2);
  const double a = u - j;
  const double c_ref = std::sqrt(static_cast<double>(rows.size()));
  normal(j, j) += c_ref * (1 - a) * (1 - a);
  normal(j, j + 1) += c_ref * (1 - a) * a;
  normal(j + 1, j) += c_ref * (1 - a) * a;
  normal(j + 1, j + 1) += c_ref * a * a;
  rhs[j] += c_ref * (1 - a) * std::log(reference_dn);
  rhs[j + 1] += c_ref * a * std::log(reference_dn);
  Eigen::VectorXd g = normal.ldlt().solve(rhs);
  // The offset constraint holds up to round-off; make it exact.
  g.array() += std::log(reference_dn) - ((1 - a) * g[j] + a * g[j + 1]);
  // Residuals with the back-substituted ln E_i.
  std::vector<double> log_e(num_samples, 0), num(num_samples, 0);
  for (const Row& row : rows) {
    const double w2 = row.weight * row.weight;
    num[row.sample] += w2 * (Interpolate(g, row) - row.log_t);
  }
  for (int i = 0; i < num_samples; ++i) log_e[i] = h_ee[i] > 0 ? num[i] / h_ee[i] : 0;
  double sum_r2 = 0, sum_w2 = 0;
  for (const Row& row : rows) {
    const double r = Interpolate(g, row) - log_e[row.sample] - row.log_t;
    sum_r2 += row.weight * row.weight * r * r;
    sum_w2 += row.weight * row.weight;
  }
  *rms = sum_w2 > 0 ? std::sqrt(sum_r2 / sum_w2) : 0;
  return g.array().exp().matrix();
}

// Robertson et al. 2003 on the knot grid.
Eigen::VectorXd SolveRobertson(const std::vector<Row>& rows, int num_samples, int num_knots,
                               const ResponseRecoveryOptions& options, double reference_dn, double* rms,
                               int* iterations) {
  const double du = 1.0 / (num_knots - 1);
  Eigen::VectorXd lin(num_knots);
  for (int j = 0; j < num_knots; ++j) lin[j] = options.saturation_dn * j * du;  // Start linear.
  auto normalise = [&](Eigen::VectorXd* l) {
    const double u = reference_dn / options.saturation_dn * (num_knots - 1);
    const int j = std::min(static_cast<int>(u), num_knots - 2);
    const double value = (1 - (u - j)) * (*l)[j] + (u - j) * (*l)[j + 1];
    *l *= reference_dn / value;
  };
  std::vector<double> x(num_samples, 0);
  // The data term's normal matrix does not change between iterations (only its right-hand
  // side does): factor it once.
  Eigen::MatrixXd normal = Eigen::MatrixXd::Zero(num_knots, num_knots);
  for (const Row& row : rows) {
    const int idx[2] = {row.knot, row.knot + 1};
    const double c[2] = {1 - row.alpha, row.alpha};
    for (int p = 0; p < 2; ++p) {
      for (int q = 0; q < 2; ++q) normal(idx[p], idx[q]) += row.weight * c[p] * c[q];
    }
  }
  // Not in the paper: a weak smoothness term in the linear domain (Robertson's per-level means
  // need none at 8 bits, but with knots some may see no sample).
  AddSmoothness(num_knots, options.robertson_smoothness_lambda, static_cast<int>(rows.size()), options.saturation_dn,
                &normal);
  // Tiny ridge: a knot no sample reaches and no smoothness row ties down stays determined.
  for (int j = 0; j < num_knots; ++j) normal(j, j) += 1e-9 * (1 + normal(j, j));
  const Eigen::LDLT<Eigen::MatrixXd> ldlt = normal.ldlt();
  int it = 0;
  for (; it < options.max_iterations; ++it) {
    // Irradiance step: x_i = sum_k w t_k L(z_ik) / sum_k w t_k^2 (Robertson et al. Eq. 10).
    std::vector<double> num(num_samples, 0), den(num_samples, 0);
    for (const Row& row : rows) {
      num[row.sample] += row.weight * row.t * Interpolate(lin, row);
      den[row.sample] += row.weight * row.t * row.t;
    }
    for (int i = 0; i < num_samples; ++i) x[i] = den[i] > 0 ? num[i] / den[i] : 0;
    // Response step: L minimises sum (L(z_ik) - t_k x_i)^2 over every sample at that level
    // (Eq. 12's per-level mean, generalised to interpolated knots).
    Eigen::VectorXd rhs = Eigen::VectorXd::Zero(num_knots);
    for (const Row& row : rows) {
      if (den[row.sample] <= 0) continue;
      const double target = row.t * x[row.sample];
      rhs[row.knot] += row.weight * (1 - row.alpha) * target;
      rhs[row.knot + 1] += row.weight * row.alpha * target;
    }
    Eigen::VectorXd next = ldlt.solve(rhs);
    normalise(&next);
    const double change = (next - lin).cwiseAbs().maxCoeff() / reference_dn;
    lin = next;
    if (change < options.tolerance) {
      ++it;
      break;
    }
  }
  *iterations = it;
  double sum_r2 = 0, sum_w2 = 0;
  for (const Row& row : rows) {
    const double l = Interpolate(lin, row), target = row.t * x[row.sample];
    if (l <= 0 || target <= 0) continue;
    const double r = std::log(l / target);
    sum_r2 += row.weight * row.weight * r * r;
    sum_w2 += row.weight * row.weight;
  }
  *rms = sum_w2 > 0 ? std::sqrt(sum_r2 / sum_w2) : 0;
  return lin;
}

}  // namespace

std::vector<size_t> SampleBracketPixels(const std::vector<ResponseFrame>& frames, double saturation_dn,
                                        int num_samples, int num_strata, uint64_t seed) {
  const size_t n = frames[0].dn->data().size();
  // Sum of the clipped values over the bracket: strictly increasing with irradiance wherever
  // any frame responds, so equal-width bands of it are bands of irradiance.
  std::vector<float> key(n, -1.0f);
  float key_min = std::numeric_limits<float>::max(), key_max = std::numeric_limits<float>::lowest();
  for (size_t i = 0; i < n; ++i) {
    float sum = 0;
    bool usable = false;
    for (const ResponseFrame& f : frames) {
      const float z = f.dn->data()[i];
      usable |= Usable(z, saturation_dn);
      sum += std::clamp(z, 0.0f, static_cast<float>(saturation_dn));
    }
    if (!usable) continue;
    key[i] = sum;
    key_min = std::min(key_min, sum);
    key_max = std::max(key_max, sum);
  }
  std::vector<std::vector<size_t>> strata(num_strata);
  const double span = std::max(1e-6, static_cast<double>(key_max) - key_min);
  for (size_t i = 0; i < n; ++i) {
    if (key[i] < 0) continue;
    const int s = std::min(num_strata - 1, static_cast<int>((key[i] - key_min) / span * num_strata));
    strata[s].push_back(i);
  }
  const int per_stratum = (num_samples + num_strata - 1) / num_strata;
  std::vector<size_t> chosen;
  for (int s = 0; s < num_strata; ++s) {
    std::vector<size_t>& pool = strata[s];
    // A fixed permutation per stratum (seed, stratum): the first m pixels of it are the same
    // whatever m, so sample sets are nested across sample counts.
    std::mt19937_64 rng(seed * 0x9E3779B97F4A7C15ULL + static_cast<uint64_t>(s));
    const size_t take = std::min(pool.size(), static_cast<size_t>(per_stratum));
    for (size_t a = 0; a < take; ++a) {
      std::uniform_int_distribution<size_t> pick(a, pool.size() - 1);
      std::swap(pool[a], pool[pick(rng)]);
      chosen.push_back(pool[a]);
    }
  }
  return chosen;
}

double BracketDnCoverage(const std::vector<ResponseFrame>& frames, double saturation_dn, int num_bins) {
  if (frames.empty() || !(saturation_dn > 0) || num_bins < 1) return 0;
  std::vector<size_t> counts(num_bins, 0);
  size_t usable = 0;
  for (const ResponseFrame& f : frames) {
    if (f.dn == nullptr) continue;
    for (float z : f.dn->data()) {
      if (!Usable(z, saturation_dn)) continue;
      ++counts[std::min(num_bins - 1, static_cast<int>(z / saturation_dn * num_bins))];
      ++usable;
    }
  }
  const double min_count = std::max(3.0, 1e-5 * static_cast<double>(usable));
  const auto covered = std::count_if(counts.begin(), counts.end(), [&](size_t c) { return c >= min_count; });
  return static_cast<double>(covered) / num_bins;
}

int ChooseResponseBracket(const std::vector<BracketCandidate>& candidates) {
  int best = -1;
  for (size_t k = 0; k < candidates.size(); ++k) {
    const BracketCandidate& c = candidates[k];
    if (best < 0) {
      best = static_cast<int>(k);
      continue;
    }
    const BracketCandidate& b = candidates[best];
    if (std::make_tuple(c.num_exposures, c.dn_coverage, c.num_frames) >
        std::make_tuple(b.num_exposures, b.dn_coverage, b.num_frames)) {
      best = static_cast<int>(k);
    }
  }
  return best;
}

Status RecoverResponse(const std::vector<ResponseFrame>& frames, const ResponseRecoveryOptions& options,
                       CameraResponse* response, ResponseRecoverySummary* summary) {
  const auto start = std::chrono::steady_clock::now();
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  THINSLAB_RETURN_IF_ERROR(CheckBracket(frames, options));
  const double z_sat = options.saturation_dn;
  const double reference_dn = options.reference_dn > 0 ? options.reference_dn : 0.5 * z_sat;
  const int num_knots = static_cast<int>(std::min<double>(options.max_knots, std::floor(z_sat) + 1));
  const std::vector<size_t> pixels =
      SampleBracketPixels(frames, z_sat, options.num_samples, options.num_strata, options.seed);
  std::vector<Row> rows;
  int num_samples = 0;
  for (size_t pixel : pixels) {
    size_t first = rows.size();
    for (const ResponseFrame& f : frames) {
      const double z = f.dn->data()[pixel];
      if (!Usable(z, z_sat)) continue;
      Row row;
      row.sample = num_samples;
      const double u = std::min(z / z_sat, 1.0) * (num_knots - 1);
      row.knot = std::min(static_cast<int>(u), num_knots - 2);
      row.alpha = u - row.knot;
      row.t = f.exposure_time_us;
      row.log_t = std::log(f.exposure_time_us);
      row.weight = HatWeight(z, z_sat);
      row.z = z;
      rows.push_back(row);
    }
    // A pixel seen in a single frame ties its ln E to nothing else: drop it.
    if (rows.size() - first < 2) {
      rows.resize(first);
      continue;
    }
    ++num_samples;
  }
  if (num_samples < 20) {
    return Status::Error("RecoverResponse: only " + std::to_string(num_samples) +
                         " pixels are unsaturated and above black in at least two frames; the bracket does not "
                         "overlap (need >= 20)");
  }
  ResponseRecoverySummary s;
  double rms = 0;
  Eigen::VectorXd lin;
  if (options.method == ResponseMethod::kDebevec) {
    lin = SolveDebevec(rows, num_samples, num_knots, options, reference_dn, &rms);
  } else {
    lin = SolveRobertson(rows, num_samples, num_knots, options, reference_dn, &rms, &s.iterations);
  }
  if (!lin.allFinite()) {
    return Status::Error("RecoverResponse: the least-squares solution is not finite (degenerate bracket?)");
  }
  CameraResponse r;
  r.method = options.method == ResponseMethod::kDebevec ? "debevec" : "robertson";
  r.bit_depth = frames[0].bit_depth;
  r.black_level_dn = options.black_level_dn;
  r.saturation_dn = options.black_level_dn + z_sat;
  r.reference_dn = reference_dn;
  r.knots_dn.resize(num_knots);
  r.linear_dn.resize(num_knots);
  for (int j = 0; j < num_knots; ++j) {
    r.knots_dn[j] = z_sat * j / (num_knots - 1);
    r.linear_dn[j] = std::max(lin[j], 0.0);
    // Noise can make a poorly sampled stretch dip; a response is non-decreasing.
    if (j > 0 && r.linear_dn[j] < r.linear_dn[j - 1]) {
      r.linear_dn[j] = r.linear_dn[j - 1];
      ++s.monotonicity_fixes;
    }
  }
  // Exact normalisation L(reference) = reference on the piecewise-linear curve (Debevec's
  // constraint held for the log-domain interpolation).
  const double at_reference = r.Linearize(reference_dn);
  if (!(at_reference > 0)) {
    return Status::Error("RecoverResponse: the recovered response is not positive at reference_dn " +
                         std::to_string(reference_dn));
  }
  for (double& l : r.linear_dn) l *= reference_dn / at_reference;
  for (const ResponseFrame& f : frames) r.exposures_us.push_back(f.exposure_time_us);
  r.num_samples = num_samples;
  r.smoothness_lambda = options.smoothness_lambda;
  r.rms_log_residual = rms;
  r.iterations = s.iterations;
  THINSLAB_RETURN_IF_ERROR(r.Validate().WithContext("RecoverResponse"));
  s.num_samples = num_samples;
  s.num_rows = static_cast<int>(rows.size());
  s.num_knots = num_knots;
  s.rms_log_residual = rms;
  s.dn_coverage = BracketDnCoverage(frames, z_sat);
  s.solve_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  *response = r;
  if (summary != nullptr) *summary = s;
  return Status::Ok();
}

}  // namespace thinslab
