// SPDX-License-Identifier: Apache-2.0
// `thinslab charts OUTDIR`: model-against-Monte-Carlo charts of the optics models, for
// docs/models/ (issue #3):
//   frisvad_vs_tau.{png,csv}        Frisvad 2005 single scattering vs full transport, over tau
//   dual_microfacet_lobes.{png,csv} Dai 2009 dual-microfacet lobes vs two-interface photon tracing
#include <cmath>
#include <cstdio>
#include <iostream>
#include <sstream>

#include "thinslab/app/commands.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/core/file.h"
#include "thinslab/core/math.h"
#include "thinslab/core/plot.h"
#include "thinslab/optics/dual_microfacet_btdf.h"
#include "thinslab/optics/thin_slab.h"
#include "thinslab/sim/layer_path_tracer.h"
#include "thinslab/sim/rough_slab_photon_tracer.h"

namespace thinslab {
namespace {

// Diffuse transmitted flux of the Frisvad slab at normal incidence, by quadrature.
double FrisvadDiffuseTransmission(const ThinSlab<double>& slab) {
  const int n_mu = 2000;
  double sum = 0;
  for (int a = 0; a < n_mu; ++a) {
    const double mu = (a + 0.5) / n_mu;
    // Normal incidence: the lobe is azimuthally symmetric and the scattering cosine is mu.
    sum += slab.TransmittedBsdf(1.0, mu, mu) * mu * (1.0 / n_mu) * 2 * kPi;
  }
  return sum;
}

Status FrisvadChart(const std::string& dir, int paths) {
  std::ostringstream csv;
  csv << "albedo,tau,model_total_T,mc_total_T,total_rel_error,model_diffuse_T,mc_diffuse_T,diffuse_rel_error\n";
  std::vector<PlotSeries> series;
  const int colors[] = {0x1f77b4, 0xd62728};
  int k = 0;
  for (double albedo : {1.0, 0.5}) {
    PlotSeries total, diffuse;
    total.label = "total T (direct + single), albedo " + std::to_string(albedo).substr(0, 3);
    total.line = true;
    total.color_bgr = colors[k];
    diffuse.label = "scattered T only, albedo " + std::to_string(albedo).substr(0, 3);
    diffuse.color_bgr = colors[k++];
    for (double tau : {0.01, 0.02, 0.05, 0.1, 0.2, 0.3, 0.5, 1.0}) {
      LayerPathTracerOptions o;
      o.tau = tau;
      o.albedo = albedo;
      o.g = 0.0;
      o.n1 = o.n2 = o.n3 = 1.0;
      o.num_paths = paths;
      o.num_mu_bins = 4;
      o.num_phi_bins = 2;
      o.seed = 17;
      const LayerPathTracerResult r = TraceLayer(o);
      const ThinSlab<double> slab{tau, albedo, 0.0};
      const double model_diffuse = FrisvadDiffuseTransmission(slab);
      const double model_total = slab.DirectTransmittance(1.0) + model_diffuse;
      const double mc_total = r.transmitted.specular + r.transmitted.scattered_flux;
      const double total_err = model_total / mc_total - 1, diffuse_err = model_diffuse / r.transmitted.scattered_flux - 1;
      csv << albedo << "," << tau << "," << model_total << "," << mc_total << "," << total_err << "," << model_diffuse
          << "," << r.transmitted.scattered_flux << "," << diffuse_err << "\n";
      total.x.push_back(std::log10(tau));
      total.y.push_back(100 * total_err);
      diffuse.x.push_back(std::log10(tau));
      diffuse.y.push_back(100 * diffuse_err);
    }
    series.push_back(total);
    series.push_back(diffuse);
  }
  PlotSeries minus_one;
  minus_one.label = "-1 % (Frisvad's claim for tau <= 0.2)";
  minus_one.line = true;
  minus_one.color_bgr = 0x7f7f7f;
  minus_one.x = {-2, 0};
  minus_one.y = {-1, -1};
  series.push_back(minus_one);
  PlotPanel panel;
  panel.series = series;
  panel.y_label = "model / Monte Carlo - 1 [%]";
  panel.zero_line = true;
  panel.legend_bottom_left = true;
  PlotOptions options;
  options.title = "Frisvad 2005 thin slab (single scattering) vs full transport, normal incidence, g 0";
  options.x_label = "log10 tau";
  options.height_px = 500;
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(dir, "frisvad_vs_tau.csv"), csv.str()));
  return WritePlotPng(JoinPath(dir, "frisvad_vs_tau.png"), {panel}, options);
}

Status DualMicrofacetChart(const std::string& dir, int64_t photons) {
  const double eta = 1.5, theta_i = 30 * kPi / 180;
  const Eigen::Vector3d wi(std::sin(theta_i), 0, std::cos(theta_i));
  struct Case {
    const char* name;
    double top, bottom;
    double model_rough;
  };
  const Case cases[] = {{"rough top 0.3, flat bottom", 0.3, 0.001, 0.3},
                        {"flat top, rough bottom 0.3", 0.001, 0.3, 0.3},
                        {"both faces rough 0.2 (model GGX 0.35)", 0.2, 0.2, 0.35}};
  std::vector<PlotPanel> panels;
  std::ostringstream csv;
  csv << "case,theta_o_deg,mc_btdf,mc_std_error,rho_t,rho_b,rho_alpha_0.5\n";
  for (const Case& c : cases) {
    RoughSlabPhotonTracerOptions o;
    o.eta = eta;
    o.alpha_top = c.top;
    o.alpha_bottom = c.bottom;
    o.wi = wi;
    o.num_photons = photons;
    o.num_bins = 64;
    o.seed = 29;
    const RoughSlabPhotonTracerResult r = TraceRoughSlab(o);
    const auto btdf = MakeDualMicrofacetBtdf(GgxDistribution(c.model_rough), GgxDistribution(c.model_rough), eta);
    PlotSeries mc, rho_t, rho_b, rho_mid;
    mc.label = "photon tracing (in-plane cells)";
    mc.color_bgr = 0x000000;
    rho_t.label = "dual microfacet alpha = 1 (rho_t)";
    rho_t.line = true;
    rho_t.color_bgr = 0x1f77b4;
    rho_b.label = "alpha = 0 (rho_b)";
    rho_b.line = true;
    rho_b.color_bgr = 0xd62728;
    rho_mid.label = "alpha = 0.5";
    rho_mid.line = true;
    rho_mid.color_bgr = 0x2ca02c;
    // The cells straddling o.y = 0 in the plane of incidence (rows n/2 - 1 and n/2 averaged).
    const int n = r.num_bins;
    for (int col = 0; col < n; ++col) {
      const double x = r.CellCentre(col);
      if (std::abs(x) > 0.97) continue;
      const double value = 0.5 * (r.Btdf(n / 2 - 1, col) + r.Btdf(n / 2, col));
      const double error = 0.5 * std::hypot(r.BtdfStdError(n / 2 - 1, col), r.BtdfStdError(n / 2, col));
      const Eigen::Vector3d wo(x, 0, -std::sqrt(1 - x * x));
      const double theta_o = std::asin(x) * 180 / kPi;
      const double t = btdf.Eval(wi, wo, 1.0), b = btdf.Eval(wi, wo, 0.0), m = btdf.Eval(wi, wo, 0.5);
      csv << "\"" << c.name << "\"," << theta_o << "," << value << "," << error << "," << t << "," << b << "," << m
          << "\n";
      if (value > 0) {
        mc.x.push_back(theta_o);
        mc.y.push_back(value);
        mc.y_error.push_back(error);
      }
      for (auto [series, v] : {std::pair<PlotSeries*, double>{&rho_t, t}, {&rho_b, b}, {&rho_mid, m}}) {
        if (v > 0) {
          series->x.push_back(theta_o);
          series->y.push_back(v);
        }
      }
    }
    PlotPanel panel;
    panel.series = {mc, rho_t, rho_b, rho_mid};
    panel.log_y = true;
    panel.y_label = std::string(c.name) + ": BTDF [1/sr]";
    panels.push_back(panel);
  }
  PlotOptions options;
  options.title = "Dai 2009 dual microfacet vs photon tracing, eta 1.5, theta_i 30 deg";
  options.x_label = "signed exit angle in the plane of incidence [deg]";
  options.height_px = 1000;
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(dir, "dual_microfacet_lobes.csv"), csv.str()));
  return WritePlotPng(JoinPath(dir, "dual_microfacet_lobes.png"), panels, options);
}

}  // namespace

int RunCharts(int argc, char** argv) {
  std::string out_dir;
  int paths = 400000;
  int photons = 4000000;
  OptionParser parser("charts");
  parser.AddPositional("OUTDIR", &out_dir, "folder for the PNG and CSV files (e.g. docs/models)");
  parser.AddInt("paths", &paths, "Monte Carlo paths per tau for the Frisvad chart");
  parser.AddInt("photons", &photons, "photons per case for the dual-microfacet chart");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  if (status.ok() && (paths < 1000 || photons < 1000)) status = Status::Error("thinslab charts: --paths/--photons >= 1000");
  if (status.ok()) status = CreateDirectories(out_dir);
  if (status.ok()) status = FrisvadChart(out_dir, paths);
  if (status.ok()) status = DualMicrofacetChart(out_dir, photons);
  if (!status.ok()) return CommandFailed(status);
  std::cout << "wrote frisvad_vs_tau.png/.csv and dual_microfacet_lobes.png/.csv to " << out_dir << "\n";
  return 0;
}

}  // namespace thinslab
