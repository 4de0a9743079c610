// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/tau_fit.h"

#include <ceres/ceres.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <iomanip>
#include <memory>
#include <sstream>
#include <vector>

#include "thinslab/core/parallel.h"
#include "thinslab/core/math.h"
#include "thinslab/fit/cost_functions/shadow_attenuation_cost.h"
#include "thinslab/optics/dirty_glass.h"
#include "thinslab/fit/tau_prediction.h"
#include "thinslab/optics/shadow_map_model.h"

namespace thinslab {

std::vector<std::string> TauPixelStatusNames() {
  return {"ok", "dark", "saturated", "outside", "clamped", "next_to_clamped", "mixed"};
}

bool TauFitOptions::Check(std::string* error) const {
  std::ostringstream msg;
  if (!(layer_albedo >= 0 && layer_albedo <= 1)) {
    msg << "TauFitOptions::layer_albedo = " << layer_albedo << ". Violated constraint: [0, 1]";
  } else if (!(layer_g > -1 && layer_g < 1)) {
    msg << "TauFitOptions::layer_g = " << layer_g << ". Violated constraint: (-1, 1)";
  } else if (reference != "frame" && reference != "auto" && reference != "flat") {
    msg << "TauFitOptions::reference = '" << reference << "'. Violated constraint: 'frame', 'auto' or 'flat'";
  } else if (!(tau_max > 0 && tau_max <= 20)) {
    msg << "TauFitOptions::tau_max = " << tau_max << ". Violated constraint: (0, 20]";
  } else if (!(min_reference_fraction > 0 && min_reference_fraction < 1)) {
    msg << "TauFitOptions::min_reference_fraction = " << min_reference_fraction << ". Violated constraint: (0, 1)";
  } else if (!(max_sigma_tau > 0)) {
    msg << "TauFitOptions::max_sigma_tau = " << max_sigma_tau << ". Violated constraint: > 0";
  } else if (!(max_mixed_tau_step > 0)) {
    msg << "TauFitOptions::max_mixed_tau_step = " << max_mixed_tau_step << ". Violated constraint: > 0";
  } else if (!(smoothness_sigma_tau >= 0)) {
    msg << "TauFitOptions::smoothness_sigma_tau = " << smoothness_sigma_tau << ". Violated constraint: >= 0";
  } else if (max_outer_iterations < 1) {
    msg << "TauFitOptions::max_outer_iterations = " << max_outer_iterations << ". Violated constraint: >= 1";
  } else if (!(outer_tolerance_tau > 0)) {
    msg << "TauFitOptions::outer_tolerance_tau = " << outer_tolerance_tau << ". Violated constraint: > 0";
  } else if (!(kernel_max_angle_deg > 0 && kernel_max_angle_deg < 90)) {
    msg << "TauFitOptions::kernel_max_angle_deg = " << kernel_max_angle_deg << ". Violated constraint: (0, 90)";
  } else if (num_threads < 1 || num_threads > kMaxThreads) {
    msg << "TauFitOptions::num_threads = " << num_threads << ". Violated constraint: 1.." << kMaxThreads;
  } else {
    return true;
  }
  *error = msg.str();
  return false;
}

std::string TauFitSummary::BriefReport() const {
  std::ostringstream out;
  out << "FitTau: " << (result == Result::kSuccess ? "success" : (result == Result::kFailure ? "failure" : "not run"))
      << ", " << pixels_fitted << "/" << pixels_total << " pixels fitted, " << outer_iterations
      << " outer iterations, " << total_s << " s";
  return out.str();
}

std::string TauFitSummary::FullReport() const {
  auto pct = [&](int64_t n) { return pixels_total > 0 ? 100.0 * n / pixels_total : 0.0; };
  std::ostringstream out;
  out << BriefReport() << "\n"
      << "message: " << message << "\n"
      << "grid: " << width << " x " << height << "\n"
      << "pixels fitted:    " << pixels_fitted << " (" << pct(pixels_fitted) << " %)\n"
      << "pixels dark:      " << pixels_dark << " (" << pct(pixels_dark) << " %; " << pixels_dark_noise
      << " of them because sigma_tau > max_sigma_tau)\n"
      << "pixels saturated: " << pixels_saturated << " (" << pct(pixels_saturated) << " %)\n"
      << "pixels outside:   " << pixels_outside << " (" << pct(pixels_outside) << " %)\n"
      << "pixels clamped:   " << pixels_clamped << " (" << pct(pixels_clamped) << " %)\n"
      << "pixels next to clamped: " << pixels_next_to_clamped << " (" << pct(pixels_next_to_clamped) << " %)\n"
      << "pixels mixed:     " << pixels_mixed << " (" << pct(pixels_mixed) << " %)\n"
      << "camera footprint on the board [mm]: median " << camera_footprint_median_m * 1e3 << " (" 
      << camera_footprint_min_m * 1e3 << " .. " << camera_footprint_max_m * 1e3 << "), map pitch "
      << pixel_pitch_m * 1e3 << " mm, " << camera_pixels_per_map_pixel << " camera pixels per map pixel\n"
      << "median sigma_tau parts (ok pixels): noise " << median_sigma_noise << ", reference " << median_sigma_reference
      << ", multiple scattering " << median_sigma_model << ", resolution " << median_sigma_resolution << "\n"
      << "final max tau update: " << final_max_update_tau << "\n"
      << "mean scattered fraction of measured light: " << mean_scattered_fraction << "\n"
      << "time plain / refine / total [s]: " << plain_s << " / " << refine_s << " / " << total_s << "\n";
  for (const std::string& w : warnings) out << "warning: " << w << "\n";
  return out.str();
}

namespace {

using Clock = std::chrono::steady_clock;
double Seconds(Clock::time_point a, Clock::time_point b) {
  return std::chrono::duration<double>(b - a).count();
}

// A linear model sum_c coef_c basis_c(i) (at most 6 terms) through the clean part of the shadow
// image: iteratively keeps pixels no more than 2.5 robust sigmas below the current fit
// (contaminant only darkens, Eq. 5). Not in Gu et al. 2007, which takes I_clean from clean
// regions by hand.
constexpr int kMaxBasis = 6;
using CleanBasis = std::function<void(int pixel, double* b)>;

// *relative_misfit: the RMS of (shadow - fit) / fit over the pixels kept as clean, beyond what
// their noise (`variance`, may be empty) explains: the surface's own error as a reference.
Status FitCleanReference(const Image& shadow, const Image& variance, const std::vector<uint8_t>& usable,
                         int num_basis, const CleanBasis& basis, const std::string& name, Image* reference,
                         int64_t* clean_pixels, double* relative_misfit) {
  const int w = shadow.width(), h = shadow.height();
  std::vector<int> keep;
  for (int i = 0; i < w * h; ++i) {
    if (usable[i]) keep.push_back(i);
  }
  const size_t total = keep.size();
  if (total < 50) return Status::Error(name + " reference: fewer than 50 usable pixels");
  Eigen::VectorXd coef = Eigen::VectorXd::Zero(num_basis);
  for (int iteration = 0; iteration < 50; ++iteration) {
    Eigen::MatrixXd a(keep.size(), num_basis);
    Eigen::VectorXd rhs(keep.size());
    for (size_t k = 0; k < keep.size(); ++k) {
      double b[kMaxBasis];
      basis(keep[k], b);
      for (int c = 0; c < num_basis; ++c) a(k, c) = b[c];
      rhs(k) = shadow.data()[keep[k]];
    }
    coef = a.colPivHouseholderQr().solve(rhs);
    std::vector<double> residuals(keep.size());
    for (size_t k = 0; k < keep.size(); ++k) residuals[k] = rhs(k) - a.row(k).dot(coef);
    // Noise scale from the positive residuals only: contamination only darkens (Eq. 5), so
    // the clean pixels' noise shows above the fit, uncontaminated by the shadows below it.
    std::vector<double> positive;
    for (double r : residuals) {
      if (r > 0) positive.push_back(r);
    }
    if (positive.empty()) break;
    std::nth_element(positive.begin(), positive.begin() + positive.size() / 2, positive.end());
    const double sigma = 1.4826 * positive[positive.size() / 2];
    std::vector<int> next;
    for (int i = 0; i < w * h; ++i) {
      if (!usable[i]) continue;
      double b[kMaxBasis];
      basis(i, b);
      double fit = 0;
      for (int c = 0; c < num_basis; ++c) fit += b[c] * coef(c);
      if (shadow.data()[i] >= fit - 2.5 * sigma) next.push_back(i);
    }
    if (next.size() == keep.size()) break;
    keep.swap(next);
  }
  if (keep.size() < total / 10) {
    return Status::Error(name + " reference: fewer than 10% of the pixels look clean (" + std::to_string(keep.size()) +
                         " of " + std::to_string(total) + "); capture a reference frame of clean glass");
  }
  *clean_pixels = static_cast<int64_t>(keep.size());
  *reference = Image(w, h);
  for (int i = 0; i < w * h; ++i) {
    double b[kMaxBasis];
    basis(i, b);
    double fit = 0;
    for (int c = 0; c < num_basis; ++c) fit += b[c] * coef(c);
    reference->data()[i] = static_cast<float>(fit);
  }
  double residual2 = 0, noise2 = 0;
  int64_t counted = 0;
  for (int i : keep) {
    const double fit = reference->data()[i];
    if (!(fit > 0)) continue;
    residual2 += Sqr((shadow.data()[i] - fit) / fit);
    if (!variance.empty()) noise2 += variance.data()[i] / Sqr(fit);
    ++counted;
  }
  *relative_misfit = counted > 0 ? std::sqrt(std::max(0.0, (residual2 - noise2) / counted)) : 0;
  return Status::Ok();
}

double Median(std::vector<float> values) {
  if (values.empty()) return 0;
  std::nth_element(values.begin(), values.begin() + values.size() / 2, values.end());
  return values[values.size() / 2];
}

}  // namespace

Status FitTau(const TauFitOptions& options, const RectifiedShadowMaps& data, TauMaps* maps,
              TauFitSummary* summary) {
  const auto t_start = Clock::now();
  *summary = TauFitSummary();
  std::string error;
  if (!options.Check(&error)) return Status::Error(error);
  const int w = data.shadow.width(), h = data.shadow.height();
  const size_t n = static_cast<size_t>(w) * h;
  summary->width = w;
  summary->height = h;
  summary->pixels_total = static_cast<int64_t>(n);
  if (n == 0) return Status::Error("FitTau: empty shadow map");
  THINSLAB_RETURN_IF_ERROR(CheckPixelTraceInside(options.trace, w, h, "--pixel (TauFitOptions::trace)"));

  // Masks and the reference.
  std::vector<uint8_t> status(n, static_cast<uint8_t>(TauPixelStatus::kOk));
  for (size_t i = 0; i < n; ++i) {
    if (data.outside.data()[i] > 0) {
      status[i] = static_cast<uint8_t>(TauPixelStatus::kOutside);
    } else if (data.saturated.data()[i] > 0) {
      status[i] = static_cast<uint8_t>(TauPixelStatus::kSaturated);
    }
  }
  Image reference;
  if (options.reference == "frame") {
    if (data.reference.empty()) {
      return Status::Error("FitTau: TauFitOptions::reference = 'frame' but the session has no 'reference' frames; "
                           "capture clean glass or use reference 'auto'");
    }
    reference = data.reference;
  }
  // Reference "auto" / "flat": a clean surface through the pixels of `clean_light` judged clean.
  const bool judged_reference = options.reference != "frame";
  auto fit_judged_reference = [&](const Image& clean_light) {
    std::vector<uint8_t> usable(n);
    for (size_t i = 0; i < n; ++i) usable[i] = status[i] == 0 && clean_light.data()[i] > 0;
    if (options.reference == "auto") {
      auto quadratic = [w, h](int i, double* b) {
        const double x = ((i % w) + 0.5) / w - 0.5, y = ((i / w) + 0.5) / h - 0.5;
        b[0] = 1;
        b[1] = x;
        b[2] = y;
        b[3] = x * x;
        b[4] = x * y;
        b[5] = y * y;
      };
      return FitCleanReference(clean_light, data.shadow_variance, usable, 6, quadratic, "auto", &reference,
                               &summary->pixels_judged_clean, &summary->reference_relative_sigma);
    }
    auto flat = [&data](int i, double* b) { b[0] = data.flat.data()[i]; };
    return FitCleanReference(clean_light, data.shadow_variance, usable, 1, flat, "flat", &reference,
                             &summary->pixels_judged_clean, &summary->reference_relative_sigma);
  };
  if (options.reference == "flat") {
    if (data.flat.empty()) {
      return Status::Error("FitTau: TauFitOptions::reference = 'flat' but the session has no calib/flat_field.exr; "
                           "run `thinslab calib flat` or use reference 'frame' or 'auto'");
    }
    // Map pixels without a valid flat are masked as dark (no reference).
    for (size_t i = 0; i < n; ++i) {
      if (status[i] == 0 && !(data.flat.data()[i] > 0)) status[i] = static_cast<uint8_t>(TauPixelStatus::kDark);
    }
  }
  if (judged_reference) THINSLAB_RETURN_IF_ERROR(fit_judged_reference(data.shadow));
  const double ref_median = [&]() {
    std::vector<float> ref_values;
    for (size_t i = 0; i < n; ++i) {
      if (status[i] == 0) ref_values.push_back(reference.data()[i]);
    }
    return Median(std::move(ref_values));
  }();
  if (!(ref_median > 0)) {
    return Status::Error("FitTau: the reference has no signal (median " + std::to_string(ref_median) +
                         " DN/us over unmasked pixels)");
  }
  std::vector<double> m(n, 1.0), sigma_m(n, 1.0);
  const double min_ratio = std::exp(-options.tau_max);
  auto compute_ratio = [&](size_t i) {
    const double r = reference.data()[i], s = data.shadow.data()[i];
    m[i] = s / r;
    double var_s = data.shadow_variance.empty() ? 0 : data.shadow_variance.data()[i];
    double var_r = (options.reference == "frame" && !data.reference_variance.empty()) ? data.reference_variance.data()[i] : 0;
    const double var_m = (var_s + Sqr(m[i]) * var_r) / Sqr(r);
    sigma_m[i] = std::max(std::sqrt(var_m), 1e-4);
    // Signal indistinguishable from zero: cannot be measured.
    if (s <= 2.0 * std::sqrt(var_s) && s < min_ratio * r) status[i] = static_cast<uint8_t>(TauPixelStatus::kDark);
  };
  for (size_t i = 0; i < n; ++i) {
    if (status[i] != 0) continue;
    if (!(reference.data()[i] > options.min_reference_fraction * ref_median)) {
      status[i] = static_cast<uint8_t>(TauPixelStatus::kDark);
      continue;
    }
    compute_ratio(i);
  }

  // Plain estimate, Gu et al. 2007 Eq. 7: tau = -ln(I / I_clean).
  Image tau_plain(w, h);
  for (size_t i = 0; i < n; ++i) {
    if (status[i] != 0) continue;
    tau_plain.data()[i] = static_cast<float>(m[i] > min_ratio ? -std::log(m[i]) : options.tau_max);
  }
  const auto t_plain = Clock::now();
  summary->plain_s = Seconds(t_start, t_plain);
  const bool tracing = options.trace.enabled() && options.trace.x < w && options.trace.y < h;
  const size_t traced = tracing ? static_cast<size_t>(options.trace.y) * w + options.trace.x : 0;
  std::ostream* trace = options.trace.out;
  if (tracing) {
    const size_t i = traced;
    *trace << std::setprecision(9) << "pixel (" << options.trace.x << ", " << options.trace.y
           << "): shadow " << data.shadow.data()[i] << " DN/us (variance "
           << (data.shadow_variance.empty() ? 0.f : data.shadow_variance.data()[i]) << "), clean reference "
           << reference.data()[i] << " DN/us (" << options.reference << ", median " << ref_median
           << ")\n  ratio m = " << m[i] << " +- " << sigma_m[i] << ", status after masking "
           << TauPixelStatusNames()[status[i]] << ", tau_eq7 = -ln m = " << tau_plain.data()[i] << " (Gu Eq. 7)\n";
  }

  std::vector<double> tau(n, 0.0);
  for (size_t i = 0; i < n; ++i) tau[i] = tau_plain.data()[i];
  std::vector<double> scattered(n, 0.0);
  // Multiply scattered light over E0 (the model term of sigma_tau below); 0 without refinement.
  std::vector<double> multiply_scattered(n, 0.0);
  if (options.refine_scattering && options.layer_albedo > 0) {
    auto bank = std::make_unique<ScatterKernelBank>(
        LayerScatterKernelBank(options, data.board_distance_m, data.pixel_pitch_m, w, h));
    // Incident light proxy: the reference (E0 times the board-to-camera factor, which varies
    // slowly compared with the scattering kernel). Unmeasured pixels emit with the median.
    Image e0(w, h), tau_image(w, h);
    for (size_t i = 0; i < n; ++i) {
      e0.data()[i] = status[i] == static_cast<uint8_t>(TauPixelStatus::kOutside) ? static_cast<float>(ref_median)
                                                                                  : reference.data()[i];
    }
    const int64_t num_params = std::count(status.begin(), status.end(), static_cast<uint8_t>(TauPixelStatus::kOk));
    // Ceres problem of the smoothness-prior variant, built once: the data residuals read the
    // unscattered ratio d_p = m_p - S_p, which each outer iteration updates.
    std::vector<double> unscattered(n, 1.0);
    std::vector<double> next = tau;
    std::unique_ptr<ceres::Problem> problem;
    if (options.smoothness_sigma_tau > 0 && num_params > 0) {
      ceres::Problem::Options problem_options;
      problem_options.enable_fast_removal = false;
      problem.reset(new ceres::Problem(problem_options));
      for (size_t i = 0; i < n; ++i) {
        if (status[i] != 0) continue;
        problem->AddResidualBlock(ShadowAttenuationCost::Create(&unscattered[i], sigma_m[i]), nullptr, &next[i]);
        problem->SetParameterLowerBound(&next[i], 0, -1.0);
        problem->SetParameterUpperBound(&next[i], 0, options.tau_max);
      }
      for (int y = 0; y < h; ++y) {
        for (int x = 0; x < w; ++x) {
          const size_t i = static_cast<size_t>(y) * w + x;
          if (status[i] != 0) continue;
          if (x + 1 < w && status[i + 1] == 0) {
            problem->AddResidualBlock(TauSmoothnessCost::Create(options.smoothness_sigma_tau),
                                      new ceres::HuberLoss(1.0), &next[i], &next[i + 1]);
          }
          if (y + 1 < h && status[i + w] == 0) {
            problem->AddResidualBlock(TauSmoothnessCost::Create(options.smoothness_sigma_tau),
                                      new ceres::HuberLoss(1.0), &next[i], &next[i + w]);
          }
        }
      }
    }
    // The fixed point on S first converges with the closed-form per-pixel update (the prior
    // moves tau little, so S hardly changes); then at most two outer iterations polish with
    // the Ceres solve of the prior, which costs ~10x a closed-form iteration.
    bool polishing = false;
    int polish_iterations = 0, reference_refits = 0;
    constexpr int kMaxReferenceRefits = 10;
    ProgressTracker progress(options.progress, "fit tau: scattered-light iterations (Gu Eq. 6)",
                             options.max_outer_iterations);
    // Each refit of a judged clean reference (below) starts a new fixed point with its own budget.
    int iteration_budget = options.max_outer_iterations;
    for (int outer = 0; outer < iteration_budget; ++outer) {
      if (!progress.Report(outer)) return Status::Error("FitTau: cancelled");
      for (size_t i = 0; i < n; ++i) tau_image.data()[i] = static_cast<float>(std::clamp(tau[i], 0.0, options.tau_max));
      const Image s_board = bank->Scattered(e0, tau_image);
      for (size_t i = 0; i < n; ++i) {
        scattered[i] = s_board.data()[i] / e0.data()[i];
        unscattered[i] = m[i] - scattered[i];
      }
      next = tau;
      if (!polishing) {
        for (size_t i = 0; i < n; ++i) {
          if (status[i] != 0) continue;
          next[i] = unscattered[i] > min_ratio ? -std::log(unscattered[i]) : options.tau_max;
        }
      } else {
        // The normal equations are a diagonal data term plus a weak grid Laplacian: well
        // conditioned, so conjugate gradients with a Jacobi preconditioner beat a sparse
        // Cholesky factorisation (which fills in on a 2-D grid) by far.
        ceres::Solver::Options solver_options;
        solver_options.linear_solver_type = ceres::CGNR;
        solver_options.preconditioner_type = ceres::JACOBI;
        solver_options.max_linear_solver_iterations = 50;
        solver_options.max_num_iterations = 10;
        solver_options.num_threads = options.num_threads;
        solver_options.function_tolerance = 1e-7;
        solver_options.logging_type = ceres::SILENT;
        ceres::Solver::Summary ceres_summary;
        ceres::Solve(solver_options, problem.get(), &ceres_summary);
        if (ceres_summary.termination_type == ceres::FAILURE) {
          summary->result = TauFitSummary::Result::kFailure;
          summary->message = "Ceres failed: " + ceres_summary.message;
          return Status::Error("FitTau: " + summary->message);
        }
      }
      double max_update = 0;
      for (size_t i = 0; i < n; ++i) {
        if (status[i] == 0) max_update = std::max(max_update, std::abs(next[i] - tau[i]));
      }
      if (tracing) {
        *trace << "  iteration " << outer + 1 << (polishing ? " (Ceres, smoothness prior)" : "")
               << ": scattered S/E0 = " << scattered[traced] << " (Gu Eq. 6), unscattered m - S = "
               << unscattered[traced] << ", tau " << tau[traced] << " -> " << next[traced]
               << " (largest update over the map " << max_update << ")\n";
      }
      tau = next;
      summary->outer_iterations = outer + 1;
      summary->final_max_update_tau = max_update;
      if (polishing) ++polish_iterations;
      const bool converged = max_update < options.outer_tolerance_tau;
      if (judged_reference && reference_refits < kMaxReferenceRefits) {
        // Not in Gu et al. 2007: the pixels judged clean carry the light the layer scatters
        // onto them (Eq. 6), so a surface through them reads I_clean high and tau high (+0.006
        // over a densely specked texture at 1 mm, docs/stability.md). Refit it through the
        // shadow less the modelled S at every iteration, along with the map, until it moves by
        // less than the tau tolerance. (Refitting only once the map had converged gave the same
        // maps in 2.5x the iterations.)
        Image clean_light(w, h);
        for (size_t i = 0; i < n; ++i) clean_light.data()[i] = data.shadow.data()[i] - s_board.data()[i];
        const Image before = reference;
        THINSLAB_RETURN_IF_ERROR(fit_judged_reference(clean_light));
        // d tau = d I_clean / I_clean, so the surface's largest relative move is in tau units.
        double largest_change = 0;
        for (size_t i = 0; i < n; ++i) {
          if (status[i] == 0)
            largest_change =
                std::max(largest_change, std::abs(static_cast<double>(reference.data()[i]) / before.data()[i] - 1));
        }
        ++reference_refits;
        if (largest_change < options.outer_tolerance_tau) reference_refits = kMaxReferenceRefits;
        iteration_budget = outer + 1 + options.max_outer_iterations;
        for (size_t i = 0; i < n; ++i) {
          if (status[i] == 0) compute_ratio(i);
          if (status[i] != static_cast<uint8_t>(TauPixelStatus::kOutside)) e0.data()[i] = reference.data()[i];
        }
        if (tracing)
          *trace << "  clean reference refitted through the shadow less S: " << reference.data()[traced] << " DN/us\n";
        continue;
      }
      if (!polishing && problem && (converged || outer + 3 >= iteration_budget)) {
        polishing = true;
        continue;
      }
      if (converged || polish_iterations >= 2) break;
    }
    progress.Report(options.max_outer_iterations);  // Done (converged iterations end early).
    // The light Eq. 6 leaves out (not in Gu et al. 2007). Light scattered once at a layer point
    // x' is scattered again there with probability ~ albedo (1 - e^{-tau(x')}) (the layer is
    // thin, so both events share x'), and again, so the orders above the first carry r / (1 - r)
    // of it, r = albedo (1 - e^{-tau(x')}); twice-scattered HG light has mean cosine g^2, which
    // stands in for the higher orders too. So the unmodelled light is Eq. 6 again with the source
    // E0 r / (1 - r) and phase g^2, convolved over the layer like S: a thin pixel beside dense
    // ones receives their multiple scattering. (Taking tau at the receiving pixel instead, as
    // before 2026-12-07, left a bright layer's thin pixels with almost no model term: 0.45 within
    // 1 sigma, docs/stability.md.)
    bank.reset();  // One bank in memory at a time.
    TauFitOptions second_order = options;
    second_order.layer_g = Sqr(options.layer_g);
    const ScatterKernelBank multiple_bank =
        LayerScatterKernelBank(second_order, data.board_distance_m, data.pixel_pitch_m, w, h);
    Image source(w, h);
    for (size_t i = 0; i < n; ++i) {
      const double t = std::clamp(tau[i], 0.0, options.tau_max);
      tau_image.data()[i] = static_cast<float>(t);
      const double rescattered = options.layer_albedo * (1 - std::exp(-t));
      source.data()[i] = static_cast<float>(e0.data()[i] * rescattered / (1 - rescattered));
    }
    const Image multiple_board = multiple_bank.Scattered(source, tau_image);
    for (size_t i = 0; i < n; ++i)
      multiply_scattered[i] = std::max(0.0, static_cast<double>(multiple_board.data()[i])) / e0.data()[i];
  }
  const auto t_refine = Clock::now();
  summary->refine_s = Seconds(t_plain, t_refine);

  // Final status codes and sigma_tau. Gu Eq. 5 gives d tau = -d(m - S) / e^{-tau}, with S held
  // fixed (its noise is averaged over the whole kernel). Terms, in quadrature:
  //  - noise: sigma_m / e^{-tau}; above max_sigma_tau the pixel is dark;
  //  - reference (auto / flat): the clean surface's relative misfit (d tau = d I_clean / I_clean);
  //  - model: Eq. 6 is single scattering; the unmodelled light is the multiply scattered light
  //    (above). Not in Gu et al. 2007; on the simulated rig (all orders) the read-low bias of
  //    uniform layers is 1.0-1.26x this term from tau 0.5 to 3.8 (1.5-1.6x at tau 0.1-0.2,
  //    docs/stability.md);
  //  - resolution (below, from the map's gradient).
  std::vector<double> sigma_noise_of(n, 0.0), sigma_model_of(n, 0.0);
  for (size_t i = 0; i < n; ++i) {
    if (status[i] != 0) continue;
    const double transmission = std::max(std::exp(-tau[i]), min_ratio);
    const double sigma_noise = sigma_m[i] / transmission;
    sigma_noise_of[i] = sigma_noise;
    sigma_model_of[i] = multiply_scattered[i] / transmission;
    if (tau[i] >= options.tau_max - 1e-9) {
      status[i] = static_cast<uint8_t>(TauPixelStatus::kClamped);
    } else if (sigma_noise > options.max_sigma_tau) {
      status[i] = static_cast<uint8_t>(TauPixelStatus::kDark);
      ++summary->pixels_dark_noise;
    }
  }
  // Not in Gu et al. 2007: a pixel beside a clamped one is a mix of the dark side and its other
  // neighbours (camera pixels straddle the edge, and the rectifier averages them), and
  // -ln(mean transmission) is dominated by the bright part, so its tau is a lower bound only.
  std::vector<uint8_t> final_status = status;
  const uint8_t clamped_code = static_cast<uint8_t>(TauPixelStatus::kClamped);
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      if (status[i] != 0) continue;
      // 8-neighbourhood: the corner pixel of a dense speck has only diagonal clamped neighbours.
      bool beside_clamped = false;
      for (int dy = -1; dy <= 1 && !beside_clamped; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          const int nx = x + dx, ny = y + dy;
          if (nx < 0 || ny < 0 || nx >= w || ny >= h) continue;
          if (status[static_cast<size_t>(ny) * w + nx] == clamped_code) beside_clamped = true;
        }
      }
      if (beside_clamped) final_status[i] = static_cast<uint8_t>(TauPixelStatus::kNextToClamped);
    }
  }
  // Resolution (issue #24): a map pixel is measured through the camera pixels over it. Where the
  // camera's footprint f on the board exceeds the map pitch p, the camera pixel a map pixel takes
  // is centred up to f / 2 from it (tau error G f / sqrt(12) for a local gradient G, RMS over the
  // offset); and over the larger footprint L = max(f, p), -ln of the mean transmission reads
  // low by about (G L)^2 / 24 (half the variance of tau across it). G is the central difference
  // of the fitted map over measured neighbours (it cannot see texture the camera does not
  // resolve). Beyond G L > max_mixed_tau_step the pixel is mixed.
  const double p = data.pixel_pitch_m;
  auto measured_code = [&](uint8_t c) {
    return c == 0 || c == clamped_code || c == static_cast<uint8_t>(TauPixelStatus::kNextToClamped);
  };
  auto tau_at = [&](int x, int y, double* value) {
    if (x < 0 || y < 0 || x >= w || y >= h) return false;
    const size_t j = static_cast<size_t>(y) * w + x;
    if (!measured_code(final_status[j])) return false;
    *value = final_status[j] == clamped_code ? options.tau_max : tau[j];
    return true;
  };
  auto derivative = [&](int x, int y, int dx, int dy, double centre) {
    double a = 0, b = 0;
    const bool has_a = tau_at(x - dx, y - dy, &a), has_b = tau_at(x + dx, y + dy, &b);
    if (has_a && has_b) return (b - a) / (2 * p);
    if (has_b) return (b - centre) / p;
    if (has_a) return (centre - a) / p;
    return 0.0;
  };
  std::vector<double> sigma_resolution_of(n, 0.0);
  std::vector<float> footprints;
  for (int y = 0; y < h; ++y) {
    for (int x = 0; x < w; ++x) {
      const size_t i = static_cast<size_t>(y) * w + x;
      const double f_raw = data.camera_footprint_m.empty() ? 0.0 : data.camera_footprint_m.data()[i];
      if (f_raw > 0 && status[i] != static_cast<uint8_t>(TauPixelStatus::kOutside)) footprints.push_back(static_cast<float>(f_raw));
      if (!measured_code(final_status[i]) || final_status[i] == clamped_code) continue;
      const double f = f_raw > 0 ? f_raw : p;
      const double gradient = std::hypot(derivative(x, y, 1, 0, tau[i]), derivative(x, y, 0, 1, tau[i]));
      const double step = gradient * std::max(f, p);
      sigma_resolution_of[i] = std::hypot(gradient * f / std::sqrt(12.0), Sqr(step) / 24);
      if (final_status[i] == 0 && step > options.max_mixed_tau_step) {
        final_status[i] = static_cast<uint8_t>(TauPixelStatus::kMixed);
      }
    }
  }
  // sigma_tau of a measured pixel: the four terms in quadrature (written with the maps below).
  auto sigma_tau_of = [&](size_t i) {
    return std::sqrt(Sqr(sigma_noise_of[i]) + Sqr(summary->reference_relative_sigma) + Sqr(sigma_model_of[i]) +
                     Sqr(sigma_resolution_of[i]));
  };
  summary->pixel_pitch_m = p;
  if (!footprints.empty()) {
    std::sort(footprints.begin(), footprints.end());
    summary->camera_footprint_min_m = footprints.front();
    summary->camera_footprint_max_m = footprints.back();
    summary->camera_footprint_median_m = footprints[footprints.size() / 2];
    summary->camera_pixels_per_map_pixel = Sqr(p / summary->camera_footprint_median_m);
    if (summary->camera_footprint_median_m > p) {
      std::ostringstream msg;
      msg.precision(3);
      msg << "the map pitch (" << p * 1e3 << " mm) is finer than the camera resolves: one camera pixel covers "
          << summary->camera_footprint_median_m * 1e3 << " mm of the board (median; "
          << summary->camera_footprint_min_m * 1e3 << " .. " << summary->camera_footprint_max_m * 1e3
          << " mm), so neighbouring map pixels share camera pixels and texture finer than that is not measured; "
             "use rig.sample.pixel_pitch_m >= the footprint or a closer or higher-resolution camera";
      summary->warnings.push_back(msg.str());
    }
  }
  {
    // One term at a time over the status-ok pixels (one float buffer, not three).
    auto median_over_ok = [&](const std::vector<double>& term) {
      std::vector<float> values;
      for (size_t i = 0; i < n; ++i) {
        if (final_status[i] == 0) values.push_back(static_cast<float>(term[i]));
      }
      return Median(std::move(values));
    };
    summary->median_sigma_noise = median_over_ok(sigma_noise_of);
    summary->median_sigma_model = median_over_ok(sigma_model_of);
    summary->median_sigma_resolution = median_over_ok(sigma_resolution_of);
    summary->median_sigma_reference = summary->reference_relative_sigma;
  }

  // Outputs, counts and residuals.
  maps->tau = Image(w, h, {"tau", "tau_eq7", "status", "sigma_tau"});
  maps->sigma_tau_noise = Image(w, h);
  maps->reference = reference;
  double sum_scatter = 0;
  for (size_t i = 0; i < n; ++i) {
    const int x = static_cast<int>(i % w), y = static_cast<int>(i / w);
    const uint8_t code = final_status[i];
    double value = 0, plain = 0, sigma = 0;
    const bool measured = measured_code(code) || code == static_cast<uint8_t>(TauPixelStatus::kMixed);
    if (measured) {
      value = tau[i];
      plain = tau_plain.data()[i];
      sigma = sigma_tau_of(i);
      maps->sigma_tau_noise.data()[i] = static_cast<float>(sigma_noise_of[i]);
      sum_scatter += scattered[i] / std::max(m[i], 1e-6);
    }
    switch (static_cast<TauPixelStatus>(code)) {
      case TauPixelStatus::kOk: ++summary->pixels_fitted; break;
      case TauPixelStatus::kDark: ++summary->pixels_dark; break;
      case TauPixelStatus::kSaturated: ++summary->pixels_saturated; break;
      case TauPixelStatus::kOutside: ++summary->pixels_outside; break;
      case TauPixelStatus::kClamped: ++summary->pixels_clamped; value = plain = options.tau_max; break;
      case TauPixelStatus::kNextToClamped: ++summary->pixels_next_to_clamped; break;
      case TauPixelStatus::kMixed: ++summary->pixels_mixed; break;
    }
    CHECK(std::isfinite(value) && std::isfinite(plain) && std::isfinite(sigma));
    maps->tau.at(x, y, 0) = static_cast<float>(value);
    maps->tau.at(x, y, 1) = static_cast<float>(plain);
    maps->tau.at(x, y, 2) = static_cast<float>(code);
    maps->tau.at(x, y, 3) = static_cast<float>(sigma);
  }
  if (tracing) {
    const int x = options.trace.x, y = options.trace.y;
    *trace << "  result: tau = " << maps->tau.at(x, y, 0) << " +- " << maps->tau.at(x, y, 3) << " (noise "
           << sigma_noise_of[traced] << ", model " << sigma_model_of[traced] << ", resolution "
           << sigma_resolution_of[traced] << "), tau_eq7 = " << maps->tau.at(x, y, 1) << ", status "
           << TauPixelStatusNames()[final_status[traced]] << "\n";
  }
  const int64_t measured =
      summary->pixels_fitted + summary->pixels_clamped + summary->pixels_next_to_clamped + summary->pixels_mixed;
  summary->mean_scattered_fraction = measured > 0 ? sum_scatter / measured : 0;
  summary->total_s = Seconds(t_start, Clock::now());
  if (summary->pixels_fitted == 0) {
    summary->result = TauFitSummary::Result::kFailure;
    std::ostringstream msg;
    msg << "no pixel could be fitted (of " << n << ": " << summary->pixels_dark << " dark, "
        << summary->pixels_saturated << " saturated, " << summary->pixels_outside << " outside the camera view, "
        << summary->pixels_clamped << " clamped at tau_max = " << options.tau_max << ", "
        << summary->pixels_next_to_clamped << " next to clamped, " << summary->pixels_mixed << " mixed)";
    summary->message = msg.str();
    return Status::Error("FitTau: " + summary->message);
  }
  summary->result = TauFitSummary::Result::kSuccess;
  summary->message = "ok";
  return Status::Ok();
}

}  // namespace thinslab
