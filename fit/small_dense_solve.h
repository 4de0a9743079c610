// SPDX-License-Identifier: Apache-2.0
// The per-point fits with one to three parameters (single interface, analytic dual-microfacet,
// Smith roughness) solve the same way: dense QR (a few columns), silent, a capped number of
// iterations.
#pragma once

#include <ceres/ceres.h>

#include <cmath>

namespace thinslab {

// Solves `problem` in place; returns its final cost, 1e300 when that is not finite.
inline double SolveSmallDenseProblem(ceres::Problem* problem, int max_iterations) {
  ceres::Solver::Options options;
  options.linear_solver_type = ceres::DENSE_QR;
  options.max_num_iterations = max_iterations;
  options.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(options, problem, &summary);
  return std::isfinite(summary.final_cost) ? summary.final_cost : 1e300;
}

}  // namespace thinslab
