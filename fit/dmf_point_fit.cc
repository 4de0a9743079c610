// SPDX-License-Identifier: Apache-2.0
#include "thinslab/fit/dmf_point_fit.h"

#include <ceres/ceres.h>
#include <glog/logging.h>

#include <Eigen/SparseCholesky>
#include <Eigen/SparseCore>
#include <algorithm>
#include <cmath>
#include <iomanip>
#include <sstream>

#include "thinslab/fit/dmf_equivalent_roughness.h"
#include "thinslab/fit/small_dense_solve.h"
#include "thinslab/optics/dual_microfacet_btdf.h"
#include "thinslab/optics/microfacet.h"

namespace thinslab {
namespace {

// D = 1 and G = 1: DualMicrofacetBtdf::EvalTop/EvalBottom then return A_t and A_b of Eq. 16
// without the shadowing, which the fit varies separately.
struct UnitNdf {
  double D(const Eigen::Vector3d& /*m*/) const { return 1.0; }
};
struct UnitShadowing {
  using Scalar = double;
  double G(const Eigen::Vector3d&, const Eigen::Vector3d&, const Eigen::Vector3d&) const { return 1.0; }
};
using UnitBtdf = DualMicrofacetBtdf<UnitNdf, UnitShadowing>;

// Everything Eq. 16 needs of one usable training measurement.
struct Row {
  DmfNdfGrid::Stencil top, bottom;  // ln D(h_t), ln D(h_b) stencils.
  double log_value;                 // ln(R - rho_d).
  double log_a_top, log_a_bottom;   // ln A_t, ln A_b without shadowing.
  double log_g_top, log_g_bottom;   // ln G at the current smith alpha.
  Eigen::Vector3d i, w, ip, o, h_top, h_bottom;  // For G: G1(i,h_t) G1(w,h_t), G1(i',h_b) G1(o,h_b).
  bool in_core;                     // In the lobe core that Eq. 18 compares.
  double solid_angle;
};

template <typename T>
T LogShadowing(const T& smith_alpha, const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& m) {
  using std::log;
  const GgxDistributionT<T> ggx(smith_alpha);
  return log(ggx.G(a.cast<T>(), b.cast<T>(), m.cast<T>()));
}

void UpdateShadowing(double smith_alpha, std::vector<Row>* rows) {
  for (Row& r : *rows) {
    r.log_g_top = LogShadowing(smith_alpha, r.i, r.w, r.h_top);
    r.log_g_bottom = LogShadowing(smith_alpha, r.ip, r.o, r.h_bottom);
  }
}

// The sparse LDLT of one point's Eq. 16-17 normal equations. Their pattern depends on the rows'
// cells and on `symmetric`, not on alpha (a zero coefficient stays an entry), so the fill-reducing
// ordering and symbolic analysis are done once per point and mode, and every alpha iteration only
// factorizes (the analysis was about a sixth of the paper's workload's point fits).
struct NdfSolver {
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
  bool analyzed = false;
};

// Solves Eqs. 16-17 (and Eq. 19 when `symmetric`) for ln D per cell at the given alpha; `solver`
// is the point's for this mode (the same rows every call).
bool SolveNdf(const std::vector<Row>& rows, const DmfNdfGrid& grid, double alpha, double smoothness, bool symmetric,
              NdfSolver* solver, std::vector<double>* log_d_cells) {
  // Unknown index of a cell: mirror pairs share the smaller index under Eq. 19.
  const int nc = grid.num_cells();
  auto index = [&](int cell) {
    const int u = grid.unknown(cell);
    if (u < 0 || !symmetric) return u;
    return std::min(u, grid.unknown(grid.MirrorCell(cell)));
  };
  const int nu = grid.num_unknowns();
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(rows.size() * 64 + static_cast<size_t>(nu) * 25);
  Eigen::VectorXd rhs = Eigen::VectorXd::Zero(nu);

  // Accumulates one weighted row (coefficients on cells, right-hand side) into AᵀA and Aᵀb.
  std::array<int, 8> idx;
  std::array<double, 8> coef;
  auto add_row = [&](int count, double b, double weight) {
    int m = 0;
    for (int k = 0; k < count; ++k) {
      const int u = index(idx[k]);
      if (u < 0) {
        b -= coef[k] * DmfNdfGrid::kLogEpsilon;  // Fixed boundary cell (Eq. 17).
      } else {
        idx[m] = u;
        coef[m] = coef[k];
        ++m;
      }
    }
    for (int a = 0; a < m; ++a) {
      rhs[idx[a]] += weight * coef[a] * b;
      for (int c = 0; c < m; ++c) triplets.emplace_back(idx[a], idx[c], weight * coef[a] * coef[c]);
    }
  };
  for (const Row& r : rows) {
    for (int k = 0; k < 4; ++k) {
      idx[k] = r.top.cells[k];
      coef[k] = alpha * r.top.weights[k];
      idx[4 + k] = r.bottom.cells[k];
      coef[4 + k] = (1 - alpha) * r.bottom.weights[k];
    }
    const double b =
        r.log_value - alpha * (r.log_a_top + r.log_g_top) - (1 - alpha) * (r.log_a_bottom + r.log_g_bottom);
    add_row(8, b, 1.0);
  }
  // Eq. 17: 4 ln D(h) - sum of the four neighbours = 0 for every unknown cell.
  const int n = grid.n();
  for (int u = 0; u < nu; ++u) {
    const int cell = grid.cell_of_unknown(u);
    const int row = cell / n, col = cell % n;
    idx = {cell, (row - 1) * n + col, (row + 1) * n + col, row * n + col - 1, row * n + col + 1, 0, 0, 0};
    coef = {4, -1, -1, -1, -1, 0, 0, 0};
    add_row(5, 0.0, smoothness);
  }
  // Under Eq. 19 the larger index of each mirror pair is unused: pin it so the system stays definite.
  if (symmetric) {
    for (int u = 0; u < nu; ++u) {
      if (index(grid.cell_of_unknown(u)) != u) triplets.emplace_back(u, u, 1.0);
    }
  }
  Eigen::SparseMatrix<double> normal(nu, nu);
  normal.setFromTriplets(triplets.begin(), triplets.end());
  if (!solver->analyzed) {
    solver->ldlt.analyzePattern(normal);
    solver->analyzed = true;
  }
  solver->ldlt.factorize(normal);
  if (solver->ldlt.info() != Eigen::Success) return false;
  const Eigen::VectorXd x = solver->ldlt.solve(rhs);
  if (solver->ldlt.info() != Eigen::Success || !x.allFinite()) return false;
  log_d_cells->assign(nc, DmfNdfGrid::kLogEpsilon);
  for (int cell = 0; cell < nc; ++cell) {
    const int u = index(cell);
    if (u >= 0) (*log_d_cells)[cell] = x[u];
  }
  return true;
}

double LookupStencil(const DmfNdfGrid::Stencil& s, const std::vector<double>& log_d) {
  double v = 0;
  for (int k = 0; k < 4; ++k) v += s.weights[k] * log_d[s.cells[k]];
  return v;
}

// The cells some row's stencil touches.
std::vector<bool> MeasuredCells(const std::vector<Row>& rows, const DmfNdfGrid& grid) {
  std::vector<bool> measured(grid.num_cells(), false);
  for (const Row& r : rows) {
    for (const DmfNdfGrid::Stencil* s : {&r.top, &r.bottom}) {
      for (int k = 0; k < 4; ++k) {
        if (s->weights[k] > 0) measured[s->cells[k]] = true;
      }
    }
  }
  return measured;
}

// Cells outside the convex hull (Andrew's monotone chain over (col, row)) of the `measured` cells;
// none when the measured cells span no area.
std::vector<bool> OutsideMeasuredHull(const std::vector<bool>& measured, const DmfNdfGrid& grid) {
  using P = std::array<int, 2>;
  std::vector<P> points;
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    if (measured[cell]) points.push_back({cell % grid.n(), cell / grid.n()});
  }
  std::vector<bool> outside(grid.num_cells(), false);
  if (points.size() < 3) return outside;
  std::sort(points.begin(), points.end());
  auto cross = [](const P& o, const P& a, const P& b) {
    return static_cast<int64_t>(a[0] - o[0]) * (b[1] - o[1]) - static_cast<int64_t>(a[1] - o[1]) * (b[0] - o[0]);
  };
  std::vector<P> hull(2 * points.size());
  size_t k = 0;
  for (size_t i = 0; i < points.size(); ++i) {
    while (k >= 2 && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  for (size_t i = points.size() - 1, lower = k + 1; i-- > 0;) {
    while (k >= lower && cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  hull.resize(k - 1);
  if (hull.size() < 3) return outside;
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    const P p{cell % grid.n(), cell / grid.n()};
    for (size_t e = 0; e < hull.size(); ++e) {
      if (cross(hull[e], hull[(e + 1) % hull.size()], p) < 0) {
        outside[cell] = true;
        break;
      }
    }
  }
  return outside;
}

// DmfPointFitOptions::ndf_tail "family": beyond the convex hull of the measured cells, ln D is the
// family fitted to the measured cells (FitFamilyTail) instead of Eq. 17's fill, which falls
// towards the boundary value ln 1e-6 within a few cells and so drops the mass of a long (GGX)
// tail that no dot reaches; k_s, the integral of D, then reads low (issue #24).
// Returns whether it did; *tail is the family fitted, whether used or not.
bool FillTailBeyondMeasured(const std::vector<bool>& measured, const DmfNdfGrid& grid,
                            const EquivalentRoughnessOptions& options, double max_misfit, std::vector<double>* log_d,
                            FamilyTail* tail) {
  *tail = FitFamilyTail(*log_d, grid, measured, options);
  if (!(tail->scale > 0) || tail->misfit > max_misfit) return false;
  const std::vector<bool> outside = OutsideMeasuredHull(measured, grid);
  bool filled = false;
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    if (!grid.InDisk(cell) || !outside[cell]) continue;
    const double d = FamilyTailD(*tail, grid, cell);
    if (d > 0) (*log_d)[cell] = std::max(std::log(d), DmfNdfGrid::kLogEpsilon);
    filled = true;
  }
  return filled;
}

// DmfPointFit::measured_ndf_fraction: the projected integral of D over the cells some row's
// stencil touches, over the whole integral `total`.
double MeasuredNdfFraction(const std::vector<bool>& touched, const DmfNdfGrid& grid, const std::vector<double>& log_d,
                           double total) {
  if (!(total > 0)) return 0;
  std::vector<double> measured(grid.num_cells(), DmfNdfGrid::kLogEpsilon);
  for (int cell = 0; cell < grid.num_cells(); ++cell) {
    if (touched[cell]) measured[cell] = log_d[cell];
  }
  return std::min(1.0, grid.ProjectedIntegral(measured) / total);
}

// ln of the predicted rho of a row (Eq. 11 in logarithms), D unnormalised.
double LogPrediction(const Row& r, const std::vector<double>& log_d, double alpha) {
  return alpha * (r.log_a_top + r.log_g_top + LookupStencil(r.top, log_d)) +
         (1 - alpha) * (r.log_a_bottom + r.log_g_bottom + LookupStencil(r.bottom, log_d));
}

// Eq. 18: squared distance between the measured and the predicted BTDF-weighted mean incident
// direction (integrals as sums over the dots with their solid angles).
double MeanDirectionMismatch(const std::vector<Row>& rows, const std::vector<double>& log_d, double alpha,
                             const Eigen::Vector3d& measured_mean) {
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  double total = 0;
  // Exponents relative to the largest keep the sum finite.
  double max_log = -1e300;
  std::vector<double> logs(rows.size());
  for (size_t k = 0; k < rows.size(); ++k) {
    logs[k] = LogPrediction(rows[k], log_d, alpha);
    max_log = std::max(max_log, logs[k]);
  }
  for (size_t k = 0; k < rows.size(); ++k) {
    if (!rows[k].in_core) continue;
    const double v = std::exp(logs[k] - max_log) * rows[k].solid_angle;
    sum += v * rows[k].i;
    total += v;
  }
  if (!(total > 0)) return 1e300;
  return (sum / total - measured_mean).squaredNorm();
}

double GoldenSectionAlpha(const std::vector<Row>& rows, const std::vector<double>& log_d,
                          const Eigen::Vector3d& measured_mean, double tolerance) {
  constexpr double kInvPhi = 0.6180339887498949;
  double a = 0, b = 1;
  double c = b - kInvPhi * (b - a), d = a + kInvPhi * (b - a);
  double fc = MeanDirectionMismatch(rows, log_d, c, measured_mean);
  double fd = MeanDirectionMismatch(rows, log_d, d, measured_mean);
  while (b - a > tolerance) {
    if (fc < fd) {
      b = d;
      d = c;
      fd = fc;
      c = b - kInvPhi * (b - a);
      fc = MeanDirectionMismatch(rows, log_d, c, measured_mean);
    } else {
      a = c;
      c = d;
      fc = fd;
      d = a + kInvPhi * (b - a);
      fd = MeanDirectionMismatch(rows, log_d, d, measured_mean);
    }
  }
  // The endpoints are legitimate answers (one rough face): take them when they are better.
  double best = 0.5 * (a + b), f_best = MeanDirectionMismatch(rows, log_d, best, measured_mean);
  for (double end : {0.0, 1.0}) {
    const double f = MeanDirectionMismatch(rows, log_d, end, measured_mean);
    if (f < f_best) {
      f_best = f;
      best = end;
    }
  }
  return best;
}

// Residual of Eq. 15 as a function of (ln smith_alpha, level): the shape of D and alpha fixed.
struct SmithResidual {
  const Row* row;
  double alpha;
  double fixed;  // ln(R - rho_d) - alpha (ln A_t + ln D_t) - (1 - alpha) (ln A_b + ln D_b).
  template <typename T>
  bool operator()(const T* log_smith_alpha, const T* level, T* residual) const {
    using std::exp;
    const T a = exp(log_smith_alpha[0]);
    residual[0] = T(fixed) - level[0] - T(alpha) * LogShadowing(a, row->i, row->w, row->h_top) -
                  T(1 - alpha) * LogShadowing(a, row->ip, row->o, row->h_bottom);
    return true;
  }
};

double FitSmithAlpha(const std::vector<Row>& rows, const std::vector<double>& log_d, double alpha, double start) {
  double log_a = std::log(start), level = 0;
  ceres::Problem problem;
  for (const Row& r : rows) {
    const double fixed = r.log_value - alpha * (r.log_a_top + LookupStencil(r.top, log_d)) -
                         (1 - alpha) * (r.log_a_bottom + LookupStencil(r.bottom, log_d));
    problem.AddResidualBlock(
        new ceres::AutoDiffCostFunction<SmithResidual, 1, 1, 1>(new SmithResidual{&r, alpha, fixed}), nullptr,
        &log_a, &level);
  }
  problem.SetParameterLowerBound(&log_a, 0, std::log(0.01));
  problem.SetParameterUpperBound(&log_a, 0, std::log(1.5));
  SolveSmallDenseProblem(&problem, 30);
  return std::exp(log_a);
}

}  // namespace

std::vector<std::string> DmfStatusNames() {
  std::vector<std::string> names;
  for (int k = 0; k <= static_cast<int>(DmfStatus::kUnphysical); ++k) names.push_back(DmfStatusName(static_cast<DmfStatus>(k)));
  return names;
}

const char* DmfStatusName(DmfStatus status) {
  switch (status) {
    case DmfStatus::kOk: return "ok";
    case DmfStatus::kNoLobe: return "no_lobe";
    case DmfStatus::kSpecular: return "specular";
    case DmfStatus::kSaturated: return "saturated";
    case DmfStatus::kOutside: return "outside";
    case DmfStatus::kNotConverged: return "not_converged";
    case DmfStatus::kInterpolated: return "interpolated";
    case DmfStatus::kUndersampled: return "undersampled";
    case DmfStatus::kUnphysical: return "unphysical";
  }
  return "unknown";
}

bool DmfPointFitOptions::Check(std::string* error) const {
  std::ostringstream e;
  if (ndf_resolution < 8 || ndf_resolution > 256) e << "ndf_resolution must be in [8, 256], got " << ndf_resolution;
  else if (!(eta > 1 && eta < 4)) e << "eta must be in (1, 4), got " << eta;
  else if (!(smoothness > 0)) e << "smoothness must be > 0, got " << smoothness;
  else if (!(initial_smith_alpha >= 0.01 && initial_smith_alpha <= 1.5))
    e << "initial_smith_alpha must be in [0.01, 1.5], got " << initial_smith_alpha;
  else if (!(alpha_tolerance > 0 && alpha_tolerance < 0.5)) e << "alpha_tolerance must be in (0, 0.5), got " << alpha_tolerance;
  else if (max_alpha_iterations < 1) e << "max_alpha_iterations must be >= 1, got " << max_alpha_iterations;
  else if (!(max_alpha_residual >= 0)) e << "max_alpha_residual must be >= 0, got " << max_alpha_residual;
  else if (!(min_relative_value > 0 && min_relative_value < 1))
    e << "min_relative_value must be in (0, 1), got " << min_relative_value;
  else if (!(alpha_lobe_fraction >= 0 && alpha_lobe_fraction < 1))
    e << "alpha_lobe_fraction must be in [0, 1), got " << alpha_lobe_fraction;
  else if (min_measurements < 3) e << "min_measurements must be >= 3, got " << min_measurements;
  else if (min_core_measurements < 1) e << "min_core_measurements must be >= 1, got " << min_core_measurements;
  else if (!(min_measured_ndf_fraction >= 0 && min_measured_ndf_fraction <= 1))
    e << "min_measured_ndf_fraction must be in [0, 1], got " << min_measured_ndf_fraction;
  else if (!(max_edge_fraction > 0 && max_edge_fraction <= 1))
    e << "max_edge_fraction must be in (0, 1], got " << max_edge_fraction;
  else if (!(max_transmittance > 0)) e << "max_transmittance must be > 0, got " << max_transmittance;
  else if (!(max_k_s > 0)) e << "max_k_s must be > 0, got " << max_k_s;
  else if (!(roughness.family_ratio >= 1)) e << "roughness.family_ratio must be >= 1, got " << roughness.family_ratio;
  else if (!(roughness.one_face_alpha > 0.5 && roughness.one_face_alpha <= 1))
    e << "roughness.one_face_alpha must be in (0.5, 1], got " << roughness.one_face_alpha;
  else if (!(roughness.min_relative_d >= 0 && roughness.min_relative_d < 1))
    e << "roughness.min_relative_d must be in [0, 1), got " << roughness.min_relative_d;
  else if (ndf_tail != "smooth" && ndf_tail != "family")
    e << "ndf_tail must be 'smooth' or 'family', got '" << ndf_tail << "'";
  else if (!(ndf_tail_max_misfit >= 0))
    e << "ndf_tail_max_misfit must be >= 0, got " << ndf_tail_max_misfit;
  else if (!(min_unit_transmittance >= 0 && min_unit_transmittance < 1))
    e << "min_unit_transmittance must be in [0, 1), got " << min_unit_transmittance;
  *error = e.str();
  return error->empty();
}

double EstimateDiffuse(const DmfSlice& slice, int nx, int ny, double fraction) {
  CHECK_EQ(nx * ny, slice.num_dots());
  double sum = 0;
  int count = 0;
  for (int q = 0; q < slice.num_dots(); ++q) {
    if (slice.train[q]) {
      sum += slice.value[q];
      ++count;
    }
  }
  if (count == 0 || !(sum > 0)) return 0;
  const double threshold = fraction * sum / count;
  auto candidate = [&](int x, int y) {
    if (x < 0 || y < 0 || x >= nx || y >= ny) return false;
    const int q = y * nx + x;
    return slice.train[q] && slice.value[q] > threshold;
  };
  double best = -1;
  for (int y = 0; y < ny; ++y) {
    for (int x = 0; x < nx; ++x) {
      if (!candidate(x, y)) continue;
      double s = 0;
      int n = 0;
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dx = -1; dx <= 1; ++dx) {
          if (candidate(x + dx, y + dy)) {
            s += slice.value[(y + dy) * nx + x + dx];
            ++n;
          }
        }
      }
      const double mean = s / n;
      if (best < 0 || mean < best) best = mean;
    }
  }
  return std::max(0.0, best);
}

double TrainingPeak(const DmfSlice& slice) {
  double peak = 0;
  for (int q = 0; q < slice.num_dots(); ++q) {
    if (slice.train[q]) peak = std::max(peak, slice.value[q] - slice.rho_d);
  }
  return peak;
}

std::vector<int> UsableTrainingDots(const DmfSlice& slice, const DmfPointFitOptions& options) {
  const double peak = TrainingPeak(slice);
  std::vector<int> usable;
  for (int q = 0; q < slice.num_dots(); ++q) {
    if (!slice.train[q]) continue;
    const double v = slice.value[q] - slice.rho_d;
    const double sigma = slice.sigma.empty() ? 0 : slice.sigma[q];
    if (v > options.noise_sigmas * sigma && v > options.min_relative_value * peak) usable.push_back(q);
  }
  return usable;
}

bool DmfPointFitOptions::Undersampled(double measured_ndf_fraction, const DmfSlice& slice) const {
  return measured_ndf_fraction < min_measured_ndf_fraction || LobeFractionAtOppositeEdges(slice) > max_edge_fraction ||
         LobePeaksOnEdge(slice);
}

double LobeFractionAtOppositeEdges(const DmfSlice& slice) {
  if (static_cast<int>(slice.edge.size()) != slice.num_dots()) return 0;
  const double peak = TrainingPeak(slice);
  if (!(peak > 0)) return 0;
  double border[4] = {0, 0, 0, 0};  // Indexed by the bit of DmfGridBorder.
  for (int q = 0; q < slice.num_dots(); ++q) {
    if (!slice.train[q]) continue;
    for (int b = 0; b < 4; ++b) {
      if (slice.edge[q] & (1 << b)) border[b] = std::max(border[b], slice.value[q] - slice.rho_d);
    }
  }
  return std::max(std::min(border[0], border[1]), std::min(border[2], border[3])) / peak;
}

bool LobePeaksOnEdge(const DmfSlice& slice) {
  if (static_cast<int>(slice.edge.size()) != slice.num_dots()) return false;
  int peak_dot = -1;
  for (int q = 0; q < slice.num_dots(); ++q) {
    if (slice.train[q] && (peak_dot < 0 || slice.value[q] > slice.value[peak_dot])) peak_dot = q;
  }
  return peak_dot >= 0 && slice.edge[peak_dot] != 0;
}

DmfStatus PrecheckSlice(const DmfSlice& slice, const DmfPointFitOptions& options) {
  const std::vector<int> usable = UsableTrainingDots(slice, options);
  if (usable.empty()) return DmfStatus::kNoLobe;
  const double peak = TrainingPeak(slice);
  const int core = static_cast<int>(std::count_if(usable.begin(), usable.end(), [&](int q) {
    return slice.value[q] - slice.rho_d > options.alpha_lobe_fraction * peak;
  }));
  if (static_cast<int>(usable.size()) < options.min_measurements || core < options.min_core_measurements) {
    return DmfStatus::kSpecular;
  }
  return DmfStatus::kOk;
}

DmfPointFit FitDualMicrofacetPoint(const DmfSlice& slice, const DmfNdfGrid& grid, const DmfPointFitOptions& options) {
  CHECK_EQ(grid.n(), options.ndf_resolution);
  DmfPointFit fit;
  fit.rho_d = slice.rho_d;
  fit.smith_alpha = options.initial_smith_alpha;

  // Usable training measurements (UsableTrainingDots) with both virtual configurations
  // transmitting.
  const double peak = TrainingPeak(slice);
  const std::vector<int> usable = UsableTrainingDots(slice, options);
  const UnitBtdf unit(UnitNdf{}, UnitShadowing{}, options.eta);
  std::vector<Row> rows;
  Eigen::Vector3d measured_mean = Eigen::Vector3d::Zero();
  double measured_total = 0;
  for (int q : usable) {
    const double v = slice.value[q] - slice.rho_d;
    const Eigen::Vector3d& i = slice.i[q];
    const Eigen::Vector3d& o = slice.o;
    const double a_top = unit.EvalTop(i, o), a_bottom = unit.EvalBottom(i, o);
    if (!(a_top > 0) || !(a_bottom > 0)) continue;
    Row r;
    r.h_top = unit.TopHalfVector(i, o);
    r.h_bottom = unit.BottomHalfVector(i, o);
    r.top = grid.Lookup(r.h_top);
    r.bottom = grid.Lookup(r.h_bottom);
    r.log_value = std::log(v);
    r.log_a_top = std::log(a_top);
    r.log_a_bottom = std::log(a_bottom);
    r.i = i;
    r.w = unit.OutgoingMomentum(o) / options.eta;
    r.ip = unit.IncidentMomentum(i) / options.eta;
    r.o = o;
    r.solid_angle = slice.solid_angle[q];
    r.in_core = v > options.alpha_lobe_fraction * peak;
    if (r.in_core) {
      measured_mean += v * r.solid_angle * i;
      measured_total += v * r.solid_angle;
    }
    rows.push_back(r);
  }
  fit.num_used = static_cast<int>(rows.size());
  const int core = static_cast<int>(std::count_if(rows.begin(), rows.end(), [](const Row& r) { return r.in_core; }));
  std::ostream* trace = options.trace;
  if (trace != nullptr) {
    *trace << std::setprecision(6) << "  " << slice.value.size() << " dots, rho_d " << slice.rho_d
           << " (Eq. 14), lobe peak " << peak << "; " << usable.size() << " usable training dots, " << rows.size()
           << " in Eq. 16 (" << core << " in the lobe core, above " << options.alpha_lobe_fraction << " of the peak)\n";
    for (const Row& r : rows) {
      *trace << "    i = (" << r.i.x() << ", " << r.i.y() << ", " << r.i.z() << "): R - rho_d = " << std::exp(r.log_value)
             << (r.in_core ? " (core)" : "") << "\n";
    }
  }
  if (static_cast<int>(rows.size()) < options.min_measurements || core < options.min_core_measurements) {
    fit.status = usable.empty() ? DmfStatus::kNoLobe : DmfStatus::kSpecular;
    return fit;
  }
  measured_mean /= measured_total;
  UpdateShadowing(fit.smith_alpha, &rows);

  // Eqs. 15-19: alternate NDF and alpha, first with polar symmetry, then one unconstrained pass.
  // step(a) = Eq. 18's alpha with D solved at a, minus a: alpha is a fixed point where it is 0.
  std::vector<double> log_d;
  bool solved = true;
  NdfSolver symmetric_solver, free_solver;
  auto step = [&](double a) {
    solved = solved && SolveNdf(rows, grid, a, options.smoothness, true, &symmetric_solver, &log_d);
    if (!solved) return 0.0;
    const double next = GoldenSectionAlpha(rows, log_d, measured_mean, options.golden_tolerance);
    ++fit.alpha_iterations;
    if (trace != nullptr) {
      *trace << "  iteration " << fit.alpha_iterations << ": NDF solved (Eqs. 15-17) at alpha " << a
             << ", golden-section alpha (Eq. 18) -> " << next << " (change " << std::abs(next - a) << ")\n";
    }
    return next - a;
  };
  double alpha = 0.5, previous_alpha = 0.5, previous_change = 0;
  for (int it = 0; it < options.max_alpha_iterations; ++it) {
    const double change = step(alpha);
    if (!solved) break;
    fit.alpha_residual = std::abs(change);
    // A cycle that does not contract (alpha jumping between two values, seen on rough-top
    // lobes): the fixed point lies between the two iterates, where step changes sign; bisect.
    if (it > 0 && change * previous_change < 0 && std::abs(change) > 0.5 * std::abs(previous_change)) {
      double rising = change > 0 ? alpha : previous_alpha, falling = change > 0 ? previous_alpha : alpha;
      double rising_change = std::abs(change > 0 ? change : previous_change);
      double falling_change = std::abs(change > 0 ? previous_change : change);
      for (int b = 0; b < 2 * options.max_alpha_iterations && std::abs(rising - falling) > options.alpha_tolerance; ++b) {
        const double middle = 0.5 * (rising + falling), c = step(middle);
        if (!solved) break;
        (c > 0 ? rising : falling) = middle;
        (c > 0 ? rising_change : falling_change) = std::abs(c);
      }
      alpha = 0.5 * (rising + falling);
      // Continuous step: both ends' changes shrink to the bracket; a jump keeps them large.
      fit.alpha_residual = std::min(rising_change, falling_change);
      if (trace != nullptr) {
        *trace << "  alpha cycle: bisection to [" << std::min(rising, falling) << ", " << std::max(rising, falling)
               << "], alpha " << alpha << ", residual " << fit.alpha_residual << "\n";
      }
      break;
    }
    previous_alpha = alpha;
    previous_change = change;
    alpha += change;
    if (std::abs(change) < options.alpha_tolerance) break;
  }
  if (!solved) {
    fit.status = DmfStatus::kNoLobe;
    return fit;
  }
  if (!SolveNdf(rows, grid, alpha, options.smoothness, false, &free_solver, &log_d)) {
    fit.status = DmfStatus::kNoLobe;
    return fit;
  }
  if (options.fit_smith_alpha) {
    fit.smith_alpha = FitSmithAlpha(rows, log_d, alpha, fit.smith_alpha);
    UpdateShadowing(fit.smith_alpha, &rows);
    if (!SolveNdf(rows, grid, alpha, options.smoothness, false, &free_solver, &log_d)) {
      fit.status = DmfStatus::kNoLobe;
      return fit;
    }
  }
  double sum_sq = 0;
  for (const Row& r : rows) sum_sq += Sqr(r.log_value - LogPrediction(r, log_d, alpha));
  fit.log_rms_residual = std::sqrt(sum_sq / rows.size());

  // k_s: the level D absorbed (Eq. 13), D normalised to unit projected area.
  auto normalise = [&grid](const std::vector<double>& log_unnormalised, double k_s) {
    const double log_k = std::log(k_s);
    std::vector<double> log_ndf(grid.num_cells(), DmfNdfGrid::kLogEpsilon);
    for (int cell = 0; cell < grid.num_cells(); ++cell) {
      if (grid.InDisk(cell)) log_ndf[cell] = log_unnormalised[cell] - log_k;
    }
    return log_ndf;
  };
  fit.k_s = grid.ProjectedIntegral(log_d);
  // The measured share and the equivalent roughness are judged on Eq. 17's fill: the share is a
  // sampling diagnostic (how much of the lobe the dots cover), and a family tail would only
  // restate the family to the roughness fit.
  const std::vector<bool> measured = MeasuredCells(rows, grid);
  fit.measured_ndf_fraction = MeasuredNdfFraction(measured, grid, log_d, fit.k_s);
  fit.log_ndf = normalise(log_d, fit.k_s);
  fit.roughness = FitEquivalentRoughness(fit.log_ndf, grid, options.roughness);
  if (options.ndf_tail == "family") {
    FamilyTail tail;
    const double k_s_smooth = fit.k_s;
    const bool filled =
        FillTailBeyondMeasured(measured, grid, options.roughness, options.ndf_tail_max_misfit, &log_d, &tail);
    fit.family_tail = filled;
    if (filled) {
      fit.k_s = grid.ProjectedIntegral(log_d);
      fit.log_ndf = normalise(log_d, fit.k_s);
    }
    if (trace != nullptr) {
      *trace << "  tail beyond the measured cells' hull: " << NdfFamilyName(tail.family) << " " << tail.alpha
             << " fitted to the measured cells (misfit " << tail.misfit << ", limit " << options.ndf_tail_max_misfit
             << ")" << (filled ? "" : ", not used: Eq. 17's fill stays") << "; k_s " << k_s_smooth << " -> " << fit.k_s
             << "\n";
    }
  }
  fit.alpha = alpha;
  fit.transmittance = DirectionalTransmittance(fit, grid, options.eta, slice.o);
  if (trace != nullptr) {
    *trace << "  result: top_face_weight (alpha) " << fit.alpha << ", smith_alpha " << fit.smith_alpha << ", k_s "
           << fit.k_s << ", log RMS residual " << fit.log_rms_residual << ", measured NDF fraction "
           << fit.measured_ndf_fraction << ", transmittance " << fit.transmittance
           << ", alpha residual (Eq. 18 change at the result) " << fit.alpha_residual
           << "\n";
  }
  if (fit.alpha_residual > options.max_alpha_residual) {
    fit.status = DmfStatus::kNotConverged;
  } else if (options.Undersampled(fit.measured_ndf_fraction, slice)) {
    fit.status = DmfStatus::kUndersampled;
  } else if (options.Unphysical(fit.transmittance, fit.k_s)) {
    fit.status = DmfStatus::kUnphysical;
  } else {
    fit.status = DmfStatus::kOk;
  }
  return fit;
}

namespace {

// Eq. 11 of a fit with k_s 1 and no diffuse term: the lobe's shape at (i, o); log_ndf not empty.
double DualMicrofacetShape(const DmfPointFit& fit, const DmfNdfGrid& grid, double eta, const Eigen::Vector3d& i,
                           const Eigen::Vector3d& o) {
  const UnitBtdf unit(UnitNdf{}, UnitShadowing{}, eta);
  const double a_top = unit.EvalTop(i, o), a_bottom = unit.EvalBottom(i, o);
  const Eigen::Vector3d h_top = unit.TopHalfVector(i, o), h_bottom = unit.BottomHalfVector(i, o);
  const Eigen::Vector3d w = unit.OutgoingMomentum(o) / eta, ip = unit.IncidentMomentum(i) / eta;
  const GgxDistribution smith(fit.smith_alpha);
  const double top = a_top * smith.G(i, w, h_top) * std::exp(grid.Interpolate(fit.log_ndf, h_top));
  const double bottom = a_bottom * smith.G(ip, o, h_bottom) * std::exp(grid.Interpolate(fit.log_ndf, h_bottom));
  double rho = 0;
  if (fit.alpha >= 1) rho = top;
  else if (fit.alpha <= 0) rho = bottom;
  else if (top > 0 && bottom > 0) rho = std::exp(fit.alpha * std::log(top) + (1 - fit.alpha) * std::log(bottom));
  return rho;
}

}  // namespace

double PredictDualMicrofacet(const DmfPointFit& fit, const DmfNdfGrid& grid, double eta, const Eigen::Vector3d& i,
                             const Eigen::Vector3d& o) {
  if (fit.log_ndf.empty() || !(fit.k_s > 0)) return fit.rho_d;
  return fit.rho_d + fit.k_s * DualMicrofacetShape(fit, grid, eta, i, o);
}

double DirectionalTransmittance(const DmfPointFit& fit, const DmfNdfGrid& grid, double eta, const Eigen::Vector3d& o) {
  if (fit.log_ndf.empty()) return 0;
  constexpr int kSide = 64;
  const double h = 2.0 / kSide;
  double sum = 0;
  for (int row = 0; row < kSide; ++row) {
    for (int col = 0; col < kSide; ++col) {
      const double x = -1 + (col + 0.5) * h, y = -1 + (row + 0.5) * h;
      const double r2 = x * x + y * y;
      if (r2 >= 1) continue;
      sum += PredictDualMicrofacet(fit, grid, eta, Eigen::Vector3d(x, y, std::sqrt(1 - r2)), o);
    }
  }
  return sum * h * h;
}

int ScaleShapeToSlice(const DmfSlice& slice, const DmfNdfGrid& grid, const DmfPointFitOptions& options,
                      DmfPointFit* fit) {
  const std::vector<int> usable = UsableTrainingDots(slice, options);
  const bool has_ndf = !fit->log_ndf.empty();
  std::vector<double> shape(usable.size(), 0.0);
  if (has_ndf) {
    for (size_t k = 0; k < usable.size(); ++k) {
      shape[k] = DualMicrofacetShape(*fit, grid, options.eta, slice.i[usable[k]], slice.o);
    }
  }
  // ln k_s: the mean log ratio of measurement to the unit-scale prediction, which is the shape.
  double sum = 0;
  int used = 0;
  for (size_t k = 0; k < usable.size(); ++k) {
    if (!has_ndf || !(shape[k] > 0)) continue;
    sum += std::log((slice.value[usable[k]] - slice.rho_d) / shape[k]);
    ++used;
  }
  fit->k_s = std::exp(used > 0 ? sum / used : 0);
  // The residual of the scaled prediction (PredictDualMicrofacet's arithmetic, less rho_d).
  const bool scaled = has_ndf && fit->k_s > 0;
  double sum_sq = 0;
  int n = 0;
  for (size_t k = 0; k < usable.size(); ++k) {
    const double pred = (scaled ? fit->rho_d + fit->k_s * shape[k] : fit->rho_d) - fit->rho_d;
    if (!(pred > 0)) continue;
    sum_sq += Sqr(std::log((slice.value[usable[k]] - slice.rho_d) / pred));
    ++n;
  }
  fit->log_rms_residual = n > 0 ? std::sqrt(sum_sq / n) : 0;
  return used;
}

void PackDmfPointFit(const DmfPointFit& f, ByteWriter* out) {
  out->Put(f.status);
  out->Put(f.alpha);
  out->Put(f.smith_alpha);
  out->Put(f.k_s);
  out->Put(f.rho_d);
  out->PutVector(f.log_ndf);
  out->Put(f.ndf_interpolated);
  out->Put(f.alpha_iterations);
  out->Put(f.alpha_residual);
  out->Put(f.num_used);
  out->Put(f.log_rms_residual);
  out->Put(f.measured_ndf_fraction);
  out->Put(f.family_tail);
  out->Put(f.transmittance);
  out->Put(f.roughness);
  out->Put(f.split_fitted);
  out->Put(f.split_alpha_difference);
  out->Put(f.split_roughness_difference);
  out->Put(f.sigma_alpha);
  out->Put(f.sigma_roughness);
}

bool UnpackDmfPointFit(ByteReader* in, DmfPointFit* f) {
  return in->Get(&f->status) && in->Get(&f->alpha) && in->Get(&f->smith_alpha) && in->Get(&f->k_s) &&
         in->Get(&f->rho_d) && in->GetVector(&f->log_ndf) && in->Get(&f->ndf_interpolated) &&
         in->Get(&f->alpha_iterations) && in->Get(&f->alpha_residual) && in->Get(&f->num_used) &&
         in->Get(&f->log_rms_residual) && in->Get(&f->measured_ndf_fraction) && in->Get(&f->family_tail) &&
         in->Get(&f->transmittance) && in->Get(&f->roughness) && in->Get(&f->split_fitted) &&
         in->Get(&f->split_alpha_difference) && in->Get(&f->split_roughness_difference) && in->Get(&f->sigma_alpha) &&
         in->Get(&f->sigma_roughness);
}

}  // namespace thinslab
