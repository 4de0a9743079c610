// SPDX-License-Identifier: Apache-2.0
#include <iostream>

#include "thinslab/app/command_progress.h"
#include "thinslab/app/commands.h"
#include "thinslab/app/subcommands.h"
#include "thinslab/app/data_directory.h"
#include "thinslab/app/option_parser.h"
#include "thinslab/core/file.h"
#include "thinslab/core/output_guard.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/sim/contamination_pattern.h"
#include "thinslab/sim/synthesize_dot_scan_session.h"

namespace thinslab {

void AddSimFrameValueOptions(OptionParser* parser, SimSensorOptions* sensor) {
  parser->AddBool("linear-float-frames", &sensor->linear_float_frames,
                  "write linear float EXR frames (electrons x value scale, no quantisation, clipping or gain in the "
                  "manifest), as an HDR tool or a renderer would");
  parser->AddDouble("value-scale", &sensor->value_scale, "frame values per electron with --linear-float-frames");
}

void AddSimShadowOptions(OptionParser* parser, SyntheticShadowSessionOptions* options, double* board_distance_mm,
                         std::string* tau_path) {
  SimShadowMapOptions& rig = options->rig;
  parser->AddString("tau", tau_path,
                    "contaminant texture EXR (channel 'tau'); default: the bundled demo pattern "
                    "data/patterns/demo_contamination.exr");
  parser->AddDouble("board-distance-mm", board_distance_mm, "layer-to-board distance D [mm]");
  parser->AddDouble("albedo", &rig.layer_albedo, "contaminant single-scattering albedo omega0 [0, 1]");
  parser->AddDouble("g", &rig.layer_g, "contaminant Henyey-Greenstein g (-1, 1)");
  parser->AddDouble("pixel-pitch-m", &rig.pixel_pitch_m, "pitch of the tau texture on the sample [m]");
  parser->AddDouble("projector-falloff", &rig.projector_falloff, "relative projector irradiance loss at the corner");
  parser->AddDouble("camera-tilt-deg", &rig.camera_tilt_deg, "camera tilt from the board normal [deg]");
  parser->AddInt("camera-width-px", &rig.camera_width_px, "camera image width [px]");
  parser->AddInt("camera-height-px", &rig.camera_height_px, "camera image height [px]");
  parser->AddDouble("reference-fill", &rig.reference_fill, "clean-board signal at the image centre / full well");
  parser->AddInt("photons", &rig.monte_carlo.num_photons, "Monte Carlo photons per tau node");
  parser->AddDouble("full-well-e", &rig.sensor.full_well_e, "sensor full well [electrons]");
  parser->AddDouble("read-noise-e", &rig.sensor.read_noise_e, "sensor read noise [electrons RMS]");
  parser->AddInt("bit-depth", &rig.sensor.bit_depth, "sensor bit depth (8..16)");
  parser->AddBool("noise", &rig.sensor.enable_noise, "simulate shot and read noise");
  AddSimFrameValueOptions(parser, &rig.sensor);
  parser->AddUint64("seed", &rig.seed, "seed of every random choice of the simulation");
  parser->AddInt("frames", &options->session.frames_per_state, "frames per state (shadow, reference)");
  parser->AddInt("dark-frames", &options->session.dark_frames, "dark frames (projector off)");
  parser->AddInt("validation-frames", &options->session.validation_frames,
                 "further shadow frames marked validation (not fitted; fit tau reports how well it predicts them)");
  parser->AddString("name", &options->name, "session name");
}

Status LoadOrGenerateTau(const std::string& tau_path, uint64_t seed, Image* tau) {
  const std::string path = tau_path.empty() ? DataDirectory() + "/patterns/demo_contamination.exr" : tau_path;
  Image image;
  Status status = ReadExr(path, &image);
  if (!status.ok()) {
    if (!tau_path.empty()) return status;
    // The bundled pattern is generated from a seed; regenerate it if the data folder is absent.
    ContaminationPatternOptions pattern;
    pattern.seed = seed;
    *tau = GenerateContaminationPattern(pattern);
    return Status::Ok();
  }
  int channel = image.ChannelIndex("tau");
  if (channel < 0 && image.num_channels() == 1) channel = 0;
  if (channel < 0) return Status::Error(path + ": no channel 'tau'");
  *tau = image.Channel(channel);
  return Status::Ok();
}

namespace {

int RunSimShadowMaps(int argc, char** argv) {
  SyntheticShadowSessionOptions options;
  double board_distance_mm = options.rig.board_distance_m * 1e3;
  std::string tau_path, out_dir;
  OptionParser parser("sim shadow-maps");
  parser.AddPositional("OUT", &out_dir, "new session folder to write");
  AddSimShadowOptions(&parser, &options, &board_distance_mm, &tau_path);
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  options.rig.board_distance_m = board_distance_mm * 1e-3;
  Image tau;
  NewFolderGuard new_output(out_dir);
  if (status.ok()) status = LoadOrGenerateTau(tau_path, options.rig.seed, &tau);
  options.progress = CommandProgress();
  if (status.ok()) status = SynthesizeShadowMapSession(options, tau, out_dir);
  if (!status.ok()) return CommandFailed(status);
  new_output.Keep();
  std::cout << "wrote shadow-map session " << out_dir << "\n";
  return 0;
}

int RunSimPattern(int argc, char** argv) {
  ContaminationPatternOptions options;
  std::string out_path;
  OptionParser parser("sim pattern");
  parser.AddPositional("OUT", &out_path, "EXR file to write (channel 'tau')");
  parser.AddInt("width-px", &options.width_px, "texture width");
  parser.AddInt("height-px", &options.height_px, "texture height");
  parser.AddDouble("max-tau", &options.max_tau, "densest dust speck");
  parser.AddInt("dust-specks", &options.num_dust_specks, "number of dust specks");
  parser.AddUint64("seed", &options.seed, "random seed");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  if (status.ok() && (options.width_px < 8 || options.height_px < 8 || options.width_px > 16384 ||
                      options.height_px > 16384)) {
    status = Status::Error("thinslab sim pattern: --width-px/--height-px must be in [8, 16384]");
  }
  if (status.ok() && !(options.max_tau > 0 && options.max_tau <= 100)) {
    status = Status::Error("thinslab sim pattern: --max-tau " + std::to_string(options.max_tau) + ": must be in (0, 100]");
  }
  if (status.ok() && !(options.num_dust_specks >= 0 && options.num_dust_specks <= 1000000)) {
    status = Status::Error("thinslab sim pattern: --dust-specks " + std::to_string(options.num_dust_specks) +
                           ": must be in 0..1000000");
  }
  if (status.ok()) status = CheckReplaceableFile(out_path);
  if (status.ok()) {
    Image tau = GenerateContaminationPattern(options);
    tau.attributes()["generator"] = "thinslab sim pattern, seed " + std::to_string(options.seed);
    status = WriteExr(out_path, tau, ExrPixelType::kHalf);
  }
  if (!status.ok()) return CommandFailed(status);
  std::cout << "wrote " << out_path << "\n";
  return 0;
}

// `thinslab sim dot-scan OUT`: the CRT dot rig with the region sample in the path
// (sim/synthesize_dot_scan_session.h, docs/models/dot_scan_rig.md).
int RunSimDotScan(int argc, char** argv) {
  SyntheticDotScanOptions options;
  // The paper's scan (Dai et al. Table 1: 40 x 40 dots); the C++ defaults are test-sized.
  options.session.grid_nx = 40;
  options.session.grid_ny = 40;
  std::string out_dir, exposures;
  int photons_k = static_cast<int>(options.sample.photons_per_region / 1000);
  OptionParser parser("sim dot-scan");
  parser.AddPositional("OUT", &out_dir, "new session folder to write");
  parser.AddInt("grid-nx", &options.session.grid_nx, "dots per row");
  parser.AddInt("grid-ny", &options.session.grid_ny, "dot rows");
  parser.AddDouble("margin-fraction", &options.session.margin_fraction, "monitor fraction left free on each side");
  parser.AddString("exposures-us", &exposures, "exposures of every frame, comma-separated [us]");
  parser.AddInt("camera-width-px", &options.rig.camera_width_px, "camera image width [px]");
  parser.AddInt("camera-height-px", &options.rig.camera_height_px, "camera image height [px]");
  parser.AddDouble("camera-view-width-m", &options.rig.camera_view_width_m, "width the image spans at the sample [m]");
  parser.AddDouble("camera-tilt-deg", &options.rig.camera_tilt_deg, "camera tilt from the sample normal [deg]");
  parser.AddInt("supersample", &options.rig.render_supersample, "n x n render sub-samples per camera pixel");
  parser.AddDouble("monitor-distance-m", &options.rig.monitor_distance_m, "sample-to-monitor distance d [m]");
  parser.AddDouble("dot-radiance", &options.rig.dot_radiance, "radiance of a lit monitor pixel (relative)");
  parser.AddDouble("dot-radius-px", &options.rig.dot_radius_px, "radius of a displayed dot [monitor px]");
  parser.AddInt("photons-k", &photons_k, "Monte Carlo photons per rough region, thousands");
  parser.AddInt("table-bins", &options.sample.table_bins, "N x N cells of each region's BTDF table");
  parser.AddInt("validation-dots", &options.validation_dots,
                "dots between the grid's captured as validation frames (not fitted; fit dmf reports them)");
  double glass_thickness_mm = 0;
  parser.AddDouble("glass-thickness-mm", &glass_thickness_mm,
                   "slab thickness [mm]: moves where each dot's light enters (traced mean path offsets); 0 = thin");
  parser.AddInt("threads", &options.sample.num_threads, "threads tracing the region tables");
  parser.AddDouble("truth-pitch-m", &options.truth_pitch_m, "pitch of ground_truth/regions.exr and the sample grid [m]");
  parser.AddBool("noise", &options.rig.sensor.enable_noise, "simulate shot and read noise");
  AddSimFrameValueOptions(&parser, &options.rig.sensor);
  parser.AddUint64("seed", &options.rig.seed, "seed of the sensor noise");
  parser.AddUint64("sample-seed", &options.sample.seed, "seed of the Monte Carlo tables");
  parser.AddString("name", &options.name, "session name");
  int exit_code = 0;
  if (!parser.ParseCommandLine(argc, argv, &exit_code)) return exit_code;
  Status status;
  if (status.ok() && !exposures.empty()) {
    status = ParseExposureList(exposures, "exposures-us", &options.session.bracket.exposures_us);
  }
  if (status.ok() && photons_k < 1) status = Status::Error("--photons-k: must be >= 1 (thousands of photons)");
  options.sample.photons_per_region = static_cast<int64_t>(photons_k) * 1000;
  options.sample.thickness_m = glass_thickness_mm * 1e-3;
  SyntheticDotScanResult result;
  NewFolderGuard new_output(out_dir);
  options.progress = CommandProgress();
  if (status.ok()) status = SynthesizeDotScanSession(options, out_dir, &result);
  if (!status.ok()) return CommandFailed(status);
  new_output.Keep();
  std::cout << "wrote dot-scan session " << out_dir << " (" << result.frames << " frames; tables " << result.tracing_s
            << " s, acquisition " << result.acquisition_s << " s)\n";
  return 0;
}

}  // namespace

const std::vector<Subcommand>& SimSubcommands() {
  static const std::vector<Subcommand> table = {
      {"shadow-maps", RunSimShadowMaps, "OUT", "shadow-map capture of a contaminated pane (Gu et al. 2007)"},
      {"laser", RunSimLaser, "OUT", "laser-lobe capture of a layer (Gu et al. 2007 Eq. 8)"},
      {"dot-scan", RunSimDotScan, "OUT", "CRT dot-scan capture of a rough slab (Dai et al. 2009)"},
      {"pattern", RunSimPattern, "OUT.exr", "a contamination tau pattern as EXR"},
  };
  return table;
}

int RunSim(int argc, char** argv) { return DispatchSubcommand("sim", SimSubcommands(), argc, argv); }

}  // namespace thinslab
