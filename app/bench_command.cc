// SPDX-License-Identifier: Apache-2.0
// `thinslab bench sweep OUTDIR`: speed-against-accuracy sweep of the method knobs (issue #8,
// part 2) on simulated captures made here (app/knob_sweep.h). Writes
//   OUTDIR/knob_sweep_dmf.{csv,png}  dual-microfacet fit: held-out error against fit time
//   OUTDIR/knob_sweep_tau.{csv,png}  tau fit: RMS relative error vs truth against fit time
//   OUTDIR/knob_sweep_phase.{csv,png} laser-lobe g fit: |g - g_true| against fit time
//   OUTDIR/knob_sweep.txt            the rig, and the Pareto front of each method
#include <filesystem>
#include <iostream>
#include <sstream>

#include "thinslab/app/commands.h"
#include "thinslab/app/subcommands.h"
#include "thinslab/app/knob_sweep.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/core/parallel.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/file.h"
#include "thinslab/core/session_io.h"
#include "thinslab/calib/laser_lobe_preparation.h"
#include "thinslab/fit/dmf_processing.h"
#include "thinslab/sim/laser_lobe_rig.h"
#include "thinslab/sim/synthesize_dot_scan_session.h"

namespace thinslab {
namespace {

struct SweepRun {
  bool quick = false;
  std::string methods = "dmf,tau,phase";
  int dots = 30;            // Dot grid per side (quick: 16).
  double pitch_mm = 2;      // Fit grid pitch on the 80 mm sample (quick: 4 mm).
  int camera_width_px = 480;  // Dot-scan camera (quick: 240).
  int shadow_camera_width_px = 1600;  // Shadow-map camera (quick: 640).
  int laser_camera_width_px = 1600;   // Laser-lobe camera (quick: 640).
  int threads = 2;
  bool keep_captures = false;
};

std::string FrontText(const std::vector<SweepPoint>& points, const std::string& method) {
  std::vector<const SweepPoint*> front;
  for (const SweepPoint& p : points) {
    if (p.method == method && p.pareto) front.push_back(&p);
  }
  std::sort(front.begin(), front.end(), [](const SweepPoint* a, const SweepPoint* b) { return a->seconds < b->seconds; });
  std::ostringstream out;
  out << method << " Pareto front (fastest first):\n";
  for (const SweepPoint* p : front) {
    char line[200];
    std::snprintf(line, sizeof(line), "  %-22s %-30s %8.3f s  error %.4f\n", p->knob.c_str(), p->value.c_str(),
                  p->seconds, p->error);
    out << line;
  }
  return out.str();
}

Status SweepDmf(const SweepRun& run, const std::string& capture_dir, const std::string& out_dir,
                std::vector<SweepPoint>* points, std::string* rig_text) {
  SyntheticDotScanOptions sim;
  sim.session.grid_nx = sim.session.grid_ny = run.dots;
  sim.rig.camera_width_px = run.camera_width_px;
  sim.rig.camera_height_px = run.camera_width_px * 3 / 4;
  sim.sample.num_threads = run.threads;
  std::cerr << "bench sweep: simulating a " << run.dots << " x " << run.dots << " dot scan ("
            << sim.rig.camera_width_px << " x " << sim.rig.camera_height_px << " px camera)\n";
  THINSLAB_RETURN_IF_ERROR(SynthesizeDotScanSession(sim, capture_dir));
  DmfProcessingOptions processing;
  processing.pitch_m = run.pitch_mm * 1e-3;
  processing.hold_out = true;
  DmfSliceSet slices;
  DmfProcessingReport report;
  THINSLAB_RETURN_IF_ERROR(PrepareDotScanSlices(capture_dir, processing, &slices, &report));
  std::vector<DmfTruthRegion> truth;
  THINSLAB_RETURN_IF_ERROR(ReadDmfTruth(capture_dir, &truth));
  DmfSweepOptions options;
  options.defaults.num_threads = run.threads;
  if (run.quick) {
    options.ndf_resolutions = {16, 32};
    options.cluster_fractions = {0, 0.3};
    options.alpha_iteration_caps = {1};
    options.smoothness = {0.3};
  }
  std::cerr << "bench sweep: dual-microfacet fit on " << slices.width << " x " << slices.height << " points, "
            << slices.num_dots() << " dots\n";
  THINSLAB_RETURN_IF_ERROR(SweepDmfKnobs(slices, truth, options, points));
  std::ostringstream rig;
  rig << "dmf: simulated " << run.dots << " x " << run.dots << " dot scan, " << sim.rig.camera_width_px << " x "
      << sim.rig.camera_height_px << " px camera, " << slices.width << " x " << slices.height
      << " points (pitch " << run.pitch_mm << " mm), every other dot held out; processing " << report.total_s
      << " s (not in the fit times); " << run.threads << " threads\n";
  *rig_text += rig.str();
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out_dir, "knob_sweep_dmf.csv"), SweepCsv(*points)));
  return WriteSweepChart(JoinPath(out_dir, "knob_sweep_dmf.png"), *points, "dmf",
                         "Dual-microfacet fit: accuracy against time (simulated dot scan)",
                         "median held-out in-lobe relative RMS");
}

Status SweepTau(const SweepRun& run, const std::string& capture_dir, const std::string& out_dir,
                std::vector<SweepPoint>* points, std::string* rig_text) {
  SyntheticShadowSessionOptions sim;
  sim.rig.camera_width_px = run.shadow_camera_width_px;
  sim.rig.camera_height_px = run.shadow_camera_width_px * 3 / 4;
  Image tau;
  THINSLAB_RETURN_IF_ERROR(LoadOrGenerateTau("", sim.rig.seed, &tau));
  std::cerr << "bench sweep: simulating a shadow-map capture (" << sim.rig.camera_width_px << " x "
            << sim.rig.camera_height_px << " px camera)\n";
  THINSLAB_RETURN_IF_ERROR(SynthesizeShadowMapSession(sim, tau, capture_dir));
  Session session;
  THINSLAB_RETURN_IF_ERROR(ReadSession(capture_dir, &session));
  RectifiedShadowMaps data;
  THINSLAB_RETURN_IF_ERROR(PrepareShadowMaps(capture_dir, session, ShadowMapPreparationOptions(), &data));
  Image truth;
  const std::string truth_path = JoinPath(JoinPath(capture_dir, "ground_truth"), "tau.exr");
  THINSLAB_RETURN_IF_ERROR(ReadExr(truth_path, &truth));
  TauSweepOptions options;
  options.defaults.layer_albedo = sim.rig.layer_albedo;
  options.defaults.layer_g = sim.rig.layer_g;
  options.defaults.num_threads = run.threads;
  if (run.quick) {
    options.outer_iteration_caps = {1, 4};
    options.smoothness_sigmas = {};
    options.kernel_max_angles_deg = {30};
  }
  std::cerr << "bench sweep: tau fit on " << data.shadow.width() << " x " << data.shadow.height() << " px\n";
  std::vector<SweepPoint> tau_points;
  THINSLAB_RETURN_IF_ERROR(SweepTauKnobs(data, truth, options, &tau_points));
  points->insert(points->end(), tau_points.begin(), tau_points.end());
  std::ostringstream rig;
  rig << "tau: simulated shadow map (layer albedo " << sim.rig.layer_albedo << ", g " << sim.rig.layer_g
      << ", board " << sim.rig.board_distance_m * 1e3 << " mm), " << sim.rig.camera_width_px << " x "
      << sim.rig.camera_height_px << " px camera, " << data.shadow.width() << " x " << data.shadow.height()
      << " px map; error = RMS relative vs truth over tau in [0.05, 1.5]\n";
  *rig_text += rig.str();
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out_dir, "knob_sweep_tau.csv"), SweepCsv(tau_points)));
  return WriteSweepChart(JoinPath(out_dir, "knob_sweep_tau.png"), tau_points, "tau",
                         "tau fit: accuracy against time (simulated shadow map)", "RMS relative error vs truth");
}

Status SweepPhase(const SweepRun& run, const std::string& capture_dir, const std::string& out_dir,
                  std::vector<SweepPoint>* points, std::string* rig_text) {
  SyntheticLaserSessionOptions sim;
  sim.rig.camera_width_px = run.laser_camera_width_px;
  sim.rig.camera_height_px = run.laser_camera_width_px * 3 / 4;
  sim.session.capture_clean = false;
  std::cerr << "bench sweep: simulating a laser-lobe capture (" << sim.rig.camera_width_px << " x "
            << sim.rig.camera_height_px << " px camera)\n";
  THINSLAB_RETURN_IF_ERROR(SynthesizeLaserLobeSession(sim, capture_dir));
  Session session;
  THINSLAB_RETURN_IF_ERROR(ReadSession(capture_dir, &session));
  LaserLobeImages images;
  THINSLAB_RETURN_IF_ERROR(PrepareLaserLobe(capture_dir, session, LaserLobePreparationOptions(), &images));
  PhaseSweepOptions options;
  options.defaults.tau = sim.rig.layer_tau;
  if (run.quick) {
    options.ring_widths_px = {8};
    options.max_thetas_deg = {30, 60};
    options.core_beam_radii = {8};
    options.huber_scales = {};
  }
  std::vector<SweepPoint> phase_points;
  THINSLAB_RETURN_IF_ERROR(SweepPhaseKnobs(images, sim.rig.layer_g, options, &phase_points));
  points->insert(points->end(), phase_points.begin(), phase_points.end());
  std::ostringstream rig;
  rig << "phase: simulated laser lobe (layer tau " << sim.rig.layer_tau << ", albedo " << sim.rig.layer_albedo << ", g "
      << sim.rig.layer_g << ", board " << sim.rig.board_distance_m * 1e3 << " mm), " << sim.rig.camera_width_px
      << " x " << sim.rig.camera_height_px << " px camera; error = |g - g_true|, truth_error column = sigma_g\n";
  *rig_text += rig.str();
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(JoinPath(out_dir, "knob_sweep_phase.csv"), SweepCsv(phase_points)));
  return WriteSweepChart(JoinPath(out_dir, "knob_sweep_phase.png"), phase_points, "phase",
                         "Laser-lobe g fit: accuracy against time (simulated laser lobe)", "|g - g_true|");
}

int RunBenchSweep(int argc, char** argv) {
  SweepRun run;
  std::string out_dir;
  OptionParser parser("bench sweep");
  parser.AddPositional("OUTDIR", &out_dir, "folder for the CSV files, charts and summary (created)");
  parser.AddBool("quick", &run.quick, "CI size: small rigs, fewer knob values");
  parser.AddString("methods", &run.methods, "comma-separated: dmf, tau, phase");
  parser.AddInt("dots", &run.dots, "dot grid per side of the simulated dot scan");
  parser.AddDouble("pitch-mm", &run.pitch_mm, "fit grid pitch on the 80 mm dot-scan sample [mm]");
  parser.AddInt("camera-width-px", &run.camera_width_px, "dot-scan camera width [px] (height 3/4 of it)");
  parser.AddInt("shadow-camera-width-px", &run.shadow_camera_width_px, "shadow-map camera width [px]");
  parser.AddInt("laser-camera-width-px", &run.laser_camera_width_px, "laser-lobe camera width [px]");
  parser.AddInt("threads", &run.threads, "threads of the fits and the Monte Carlo");
  parser.AddBool("keep-captures", &run.keep_captures, "keep the simulated captures in OUTDIR/captures");
  // Quick defaults apply unless the option is given explicitly: parse twice.
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  if (run.quick) {
    run.dots = 16;
    run.pitch_mm = 4;
    run.camera_width_px = 240;
    run.shadow_camera_width_px = 640;
    run.laser_camera_width_px = 640;
    if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  }
  const bool do_dmf = run.methods.find("dmf") != std::string::npos;
  const bool do_tau = run.methods.find("tau") != std::string::npos;
  const bool do_phase = run.methods.find("phase") != std::string::npos;
  for (std::stringstream list(run.methods); list.good();) {
    std::string m;
    std::getline(list, m, ',');
    if (m != "dmf" && m != "tau" && m != "phase") {
      std::cerr << "error: thinslab bench sweep: --methods: unknown method '" << m << "' (dmf, tau, phase)\n";
      return 2;
    }
  }
  if (run.dots < 4 || run.pitch_mm <= 0 || run.camera_width_px < 64 || run.shadow_camera_width_px < 64 ||
      run.laser_camera_width_px < 64 || run.threads < 1 || run.threads > kMaxThreads) {
    std::cerr << "error: thinslab bench sweep: --dots must be >= 4, --pitch-mm > 0, camera widths >= 64 px, --threads in 1..256\n";
    return 2;
  }
  std::error_code ec;
  std::filesystem::create_directories(out_dir, ec);
  if (ec) {
    std::cerr << "error: thinslab bench sweep: " << out_dir << ": cannot create: " << ec.message() << "\n";
    return 1;
  }
  const std::string captures = JoinPath(out_dir, "captures");
  if (std::filesystem::exists(captures)) {
    std::cerr << "error: thinslab bench sweep: " << captures << ": exists; remove it or choose another OUTDIR\n";
    return 1;
  }
  Status status;
  std::vector<SweepPoint> dmf_points, tau_points, phase_points;
  std::string rig_text;
  if (do_dmf) status = SweepDmf(run, JoinPath(captures, "dot_scan"), out_dir, &dmf_points, &rig_text);
  if (status.ok() && do_tau) status = SweepTau(run, JoinPath(captures, "shadow_map"), out_dir, &tau_points, &rig_text);
  if (status.ok() && do_phase) {
    status = SweepPhase(run, JoinPath(captures, "laser_lobe"), out_dir, &phase_points, &rig_text);
  }
  if (!run.keep_captures) std::filesystem::remove_all(captures, ec);
  if (!status.ok()) {
    std::cerr << "error: thinslab bench sweep: " << status.message() << "\n";
    return 1;
  }
  std::string text = "thinslab bench sweep " + std::string(run.quick ? "(quick)" : "") + "\n" + rig_text + "\n";
  if (do_dmf) text += FrontText(dmf_points, "dmf") + "\n";
  if (do_tau) text += FrontText(tau_points, "tau") + "\n";
  if (do_phase) text += FrontText(phase_points, "phase");
  status = WriteFileAtomically(JoinPath(out_dir, "knob_sweep.txt"), text);
  if (!status.ok()) {
    std::cerr << "error: thinslab bench sweep: " << status.message() << "\n";
    return 1;
  }
  std::cout << text;
  return 0;
}

}  // namespace

const std::vector<Subcommand>& BenchSubcommands() {
  static const std::vector<Subcommand> table = {
      {"sweep", RunBenchSweep, "OUTDIR", "speed-against-accuracy sweep of the fit knobs, with Pareto fronts"},
  };
  return table;
}

int RunBench(int argc, char** argv) { return DispatchSubcommand("bench", BenchSubcommands(), argc, argv); }

}  // namespace thinslab
