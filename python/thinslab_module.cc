// SPDX-License-Identifier: Apache-2.0
// thinslab._thinslab: the Python bindings (issue #25, pybind11). The pure-Python package
// (python/thinslab/__init__.py) builds the user-facing functions on these:
//   run_command(args)           a thinslab command run in-process, its stdout/stderr captured, so
//                               every fit, calibration, simulation and predict takes exactly the
//                               CLI's options, defaults and error messages
//   read_exr(path)              {channel: float32 array (height, width)}, {attribute: text}
//   read_capture(path)          the validated manifest (kind, cameras, frames) as a dict
//   read_frame(path, index)     one frame as a float32 array (DN, or linear values)
//   optics functions            numpy-vectorised models: Henyey-Greenstein, the Gu et al. 2007
//                               layer (Eqs. 5, 6, 8), Frisvad et al. 2005 thin slab, Walter et al.
//                               2007 GGX/Beckmann rough dielectric, Dai et al. 2009 dual microfacet
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <iostream>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include "thinslab/app/command_progress.h"
#include "thinslab/app/verbosity.h"
#include "thinslab/core/provenance.h"
#include "thinslab/app/commands.h"
#include "thinslab/core/exr_io.h"
#include "thinslab/core/session_io.h"
#include "thinslab/core/session_recovery.h"
#include "thinslab/core/version.h"
#include "thinslab/optics/dirty_glass.h"
#include "thinslab/optics/dual_microfacet_btdf.h"
#include "thinslab/optics/henyey_greenstein.h"
#include "thinslab/optics/microfacet.h"
#include "thinslab/optics/thin_slab.h"
#include "thinslab/optics/walter_btdf.h"

namespace py = pybind11;

namespace thinslab {
namespace {

using CommandFn = int (*)(int, char**);

// The commands the bindings run (thinslab_cli: no device; `acquire` is not bound).
CommandFn FindCommand(const std::string& name) {
  if (name == "fit") return RunFit;
  if (name == "calib") return RunCalib;
  if (name == "sim") return RunSim;
  if (name == "predict") return RunPredict;
  if (name == "info") return RunInfo;
  if (name == "synth") return RunSynth;
  return nullptr;
}

// Restores std::cout / std::cerr even when the command throws.
class CapturedStreams {
 public:
  CapturedStreams() : old_out_(std::cout.rdbuf(out_.rdbuf())), old_err_(std::cerr.rdbuf(err_.rdbuf())) {}
  ~CapturedStreams() {
    std::cout.rdbuf(old_out_);
    std::cerr.rdbuf(old_err_);
  }
  std::string out() const { return out_.str(); }
  std::string err() const { return err_.str(); }

 private:
  std::ostringstream out_, err_;
  std::streambuf* old_out_;
  std::streambuf* old_err_;
};

// args = [command, subcommand..., positional..., "--option", "value", ...] as on the command
// line. Returns (exit code, stdout, stderr). The streams are process-wide: one command at a time
// (the GIL is held).
py::tuple RunCommand(const std::vector<std::string>& args, const py::object& progress) {
  if (args.empty()) throw py::value_error("run_command: no command given");
  const CommandFn fn = FindCommand(args[0]);
  if (fn == nullptr) throw py::value_error("run_command: '" + args[0] + "' is not a command the bindings run "
                                           "(fit, calib, sim, predict, info, synth)");
  std::vector<std::string> rest(args.begin() + 1, args.end());
  std::vector<char*> argv;
  for (std::string& a : rest) argv.push_back(a.data());
  // progress(dict) -> False cancels; it runs on this thread, which holds the GIL (core/progress.h).
  // An exception it raises cancels the command and is raised again after it.
  std::shared_ptr<py::error_already_set> raised;
  if (!progress.is_none()) {
    SetCommandProgress([&](const ProgressUpdate& u) {
      try {
        const py::object answer = progress(py::dict(py::arg("stage") = u.stage, py::arg("done") = u.done,
                                                    py::arg("total") = u.total, py::arg("elapsed_s") = u.elapsed_s,
                                                    py::arg("eta_s") = u.eta_s));
        return answer.is_none() || answer.cast<bool>();
      } catch (py::error_already_set& e) {
        raised = std::make_shared<py::error_already_set>(std::move(e));
        return false;
      }
    });
  }
  int code = 0;
  std::string out, err;
  {
    CapturedStreams streams;
    std::string command_line = "thinslab";  // As the provenance's command_line (python: same options).
    for (const std::string& a : args) command_line += " " + a;
    SetCommandLine(command_line);
    const VerbosityScope verbosity;  // quiet=True mutes this command only.
    try {
      code = fn(static_cast<int>(argv.size()), argv.data());
    } catch (...) {
      SetCommandProgress({});
      SetCommandLine("");
      throw;
    }
    out = streams.out();
    err = streams.err();
  }
  SetCommandProgress({});
  SetCommandLine("");
  if (raised) throw *raised;
  return py::make_tuple(code, out, err);
}

py::array_t<float> ChannelArray(const Image& image, int c) {
  py::array_t<float> a({image.height(), image.width()});
  auto m = a.mutable_unchecked<2>();
  for (int y = 0; y < image.height(); ++y) {
    for (int x = 0; x < image.width(); ++x) m(y, x) = image.at(x, y, c);
  }
  return a;
}

py::tuple ReadExrArrays(const std::string& path) {
  Image image;
  const Status status = ReadExr(path, &image);
  if (!status.ok()) throw py::value_error(status.message());
  py::dict channels;
  for (int c = 0; c < image.num_channels(); ++c) channels[py::str(image.channel_names()[c])] = ChannelArray(image, c);
  py::dict attributes;
  for (const auto& [key, value] : image.attributes()) attributes[py::str(key)] = value;
  // Numeric header attributes (docs/format.md "Output maps"): a float, or a list of floats.
  for (const auto& [key, values] : image.numeric_attributes()) {
    if (values.size() == 1) {
      attributes[py::str(key)] = values[0];
    } else {
      attributes[py::str(key)] = py::cast(values);
    }
  }
  return py::make_tuple(channels, attributes);
}

Session ReadValidCapture(const std::string& path, bool allow_incomplete) {
  Session session;
  const Status status =
      ReadCapture(path, allow_incomplete ? IncompleteCapture::kAccept : IncompleteCapture::kRefuse, &session, nullptr);
  if (!status.ok()) throw py::value_error(status.message());
  return session;
}

py::dict ReadCaptureDict(const std::string& path, bool allow_incomplete) {
  const Session session = ReadValidCapture(path, allow_incomplete);
  py::dict d;
  d["name"] = session.name;
  d["kind"] = session.kind;
  d["format_version"] = std::to_string(session.format_major) + "." + std::to_string(session.format_minor);
  py::list cameras;
  for (const CameraInfo& c : session.rig.cameras) {
    py::dict cam;
    cam["id"] = c.id;
    cam["width_px"] = c.width_px;
    cam["height_px"] = c.height_px;
    cam["bit_depth"] = c.bit_depth;
    cam["frame_values"] = c.frame_values;
    cam["black_level_dn"] = c.black_level_dn;
    cam["saturation_dn"] = c.saturation_dn;
    cam["gain_e_per_dn"] = c.gain_e_per_dn;
    cam["intrinsics_px"] = py::make_tuple(c.fx_px, c.fy_px, c.cx_px, c.cy_px);
    cameras.append(cam);
  }
  d["cameras"] = cameras;
  d["sample"] = py::dict(py::arg("pixel_pitch_m") = session.rig.sample.pixel_pitch_m,
                         py::arg("glass_thickness_m") = session.rig.sample.glass_thickness_m,
                         py::arg("glass_ior") = session.rig.sample.glass_ior);
  if (session.rig.board.present) d["board_distance_m"] = session.rig.board.distance_m;
  py::list frames;
  for (const FrameRecord& f : session.frames) {
    py::dict fr;
    fr["index"] = f.index;
    fr["camera_id"] = f.camera_id;
    fr["kind"] = f.kind;
    fr["sample_state"] = f.sample_state;
    fr["file"] = f.file;
    fr["exposure_time_us"] = f.exposure_time_us;
    fr["validation"] = f.validation;
    fr["usable"] = f.status == FrameStatus::kOk;
    fr["projector_pattern"] = f.light.projector_pattern;
    fr["laser_on"] = f.light.laser_on;
    if (f.light.dot_px) fr["dot_px"] = py::make_tuple(f.light.dot_px->x(), f.light.dot_px->y());
    frames.append(fr);
  }
  d["frames"] = frames;
  return d;
}

py::array_t<float> ReadFrameArray(const std::string& path, int index, bool allow_incomplete) {
  const Session session = ReadValidCapture(path, allow_incomplete);
  for (const FrameRecord& f : session.frames) {
    if (f.index != index) continue;
    if (f.status != FrameStatus::kOk) throw py::value_error(path + ": frames[" + std::to_string(index) + "] failed: " + f.error);
    Image image;
    const Status status = LoadFrame(path, session, f, &image);
    if (!status.ok()) throw py::value_error(status.message());
    return ChannelArray(image, 0);
  }
  throw py::index_error(path + ": no frame with index " + std::to_string(index));
}

// Directions as (..., 3) arrays; the model evaluated per row, broadcasting wi against wo.
template <typename F>
py::array_t<double> PerDirectionPair(const py::array_t<double, py::array::c_style | py::array::forcecast>& wi,
                                     const py::array_t<double, py::array::c_style | py::array::forcecast>& wo, F f) {
  if (wi.ndim() < 1 || wi.shape(wi.ndim() - 1) != 3 || wo.ndim() < 1 || wo.shape(wo.ndim() - 1) != 3) {
    throw py::value_error("directions must be arrays of shape (..., 3)");
  }
  const py::ssize_t ni = wi.size() / 3, no = wo.size() / 3;
  if (ni != no && ni != 1 && no != 1) {
    throw py::value_error("wi and wo must hold the same number of directions (or one of them a single direction)");
  }
  const py::ssize_t n = std::max(ni, no);
  std::vector<py::ssize_t> shape;
  const auto& longer = ni >= no ? wi : wo;
  for (py::ssize_t k = 0; k + 1 < longer.ndim(); ++k) shape.push_back(longer.shape(k));
  py::array_t<double> out(shape);
  const double* a = wi.data();
  const double* b = wo.data();
  double* o = out.mutable_data();
  for (py::ssize_t k = 0; k < n; ++k) {
    const double* p = a + 3 * (ni == 1 ? 0 : k);
    const double* q = b + 3 * (no == 1 ? 0 : k);
    o[k] = f(Eigen::Vector3d(p[0], p[1], p[2]).normalized(), Eigen::Vector3d(q[0], q[1], q[2]).normalized());
  }
  return out;
}

void CheckRoughness(double alpha, const char* what) {
  if (!(alpha > 0 && alpha <= 4)) throw py::value_error(std::string(what) + " must be in (0, 4], got " + std::to_string(alpha));
}

void CheckEta(double eta) {
  if (!(eta > 1 && eta <= 4)) throw py::value_error("eta must be in (1, 4], got " + std::to_string(eta));
}

template <typename Distribution>
py::array_t<double> WalterEval(const py::array_t<double, py::array::c_style | py::array::forcecast>& wi,
                               const py::array_t<double, py::array::c_style | py::array::forcecast>& wo, double alpha,
                               double eta) {
  const WalterRoughDielectric<Distribution> bsdf(Distribution(alpha), eta);
  return PerDirectionPair(wi, wo, [&](const Eigen::Vector3d& i, const Eigen::Vector3d& o) { return bsdf.Eval(i, o); });
}

template <typename Distribution>
py::array_t<double> DaiEval(const py::array_t<double, py::array::c_style | py::array::forcecast>& wi,
                            const py::array_t<double, py::array::c_style | py::array::forcecast>& wo, double roughness,
                            double smith_roughness, double top_weight, double eta) {
  const auto btdf = MakeDualMicrofacetBtdf(Distribution(roughness), Distribution(smith_roughness), eta);
  return PerDirectionPair(wi, wo, [&](const Eigen::Vector3d& i, const Eigen::Vector3d& o) {
    // Dai's convention: light from above (i.z > 0) leaves through the bottom (o.z < 0).
    if (!(i.z() > 0 && o.z() < 0)) return 0.0;
    return btdf.Eval(i, o, top_weight);
  });
}

}  // namespace
}  // namespace thinslab

PYBIND11_MODULE(_thinslab, m) {
  using namespace thinslab;
  m.doc() = "thinslab C++ bindings; use the `thinslab` package.";
  m.attr("__version__") = THINSLAB_VERSION_STRING;
  m.attr("git_hash") = THINSLAB_GIT_HASH;
  m.def("run_command", &RunCommand, py::arg("args"), py::arg("progress") = py::none(),
        "Runs a thinslab command in-process; returns (exit_code, stdout, stderr). progress(dict) is called "
        "with stage, done, total, elapsed_s, eta_s; returning False cancels.");
  m.def("read_exr", &ReadExrArrays, py::arg("path"), "({channel: float32 (h, w) array}, {attribute: str})");
  m.def("read_capture", &ReadCaptureDict, py::arg("path"), py::arg("allow_incomplete") = false,
        "The validated capture manifest as a dict.");
  m.def("read_frame", &ReadFrameArray, py::arg("path"), py::arg("index"), py::arg("allow_incomplete") = false,
        "Frame `index` of a capture as a float32 (h, w) array.");

  // Optics, vectorised over numpy arrays (broadcasting as numpy does).
  m.def("hg_phase", py::vectorize([](double cos_theta, double g) { return HenyeyGreenstein(cos_theta, g); }),
        py::arg("cos_theta"), py::arg("g"), "Henyey-Greenstein phase function [1/sr] (Gu et al. 2007, Sec. 3.1).");
  m.def("gu_direct_transmittance", py::vectorize([](double tau) { return LayerDirectTransmittance(tau); }),
        py::arg("tau"), "Gu et al. 2007, Eq. 5 at normal incidence: e^-tau.");
  m.def("gu_scattered_radiance",
        py::vectorize([](double tau, double mu, double albedo, double g) {
          return LayerSingleScatterRadiance(tau, mu, albedo, g);
        }),
        py::arg("tau"), py::arg("mu"), py::arg("albedo"), py::arg("g"),
        "Gu et al. 2007, Eq. 6: single-scattered radiance per unit irradiance [1/sr] at exit cosine mu.");
  m.def("gu_laser_lobe", py::vectorize([](double cos_theta, double g, double tau) {
          return LaserLobeProfile(cos_theta, g, tau);
        }),
        py::arg("cos_theta"), py::arg("g"), py::arg("tau"), "Gu et al. 2007, Eq. 8 up to the scale beta.");
  m.def("frisvad_reflected_bsdf",
        py::vectorize([](double mu0, double mu, double cos_scatter, double tau1, double albedo, double g) {
          return ThinSlab<double>{tau1, albedo, g}.ReflectedBsdf(mu0, mu, cos_scatter);
        }),
        py::arg("mu0"), py::arg("mu"), py::arg("cos_scatter"), py::arg("tau1"), py::arg("albedo"), py::arg("g") = 0.0,
        "Frisvad et al. 2005, Eq. 4 as a BSDF [1/sr] (single scattering, lit face).");
  m.def("frisvad_transmitted_bsdf",
        py::vectorize([](double mu0, double mu, double cos_scatter, double tau1, double albedo, double g) {
          return ThinSlab<double>{tau1, albedo, g}.TransmittedBsdf(mu0, mu, cos_scatter);
        }),
        py::arg("mu0"), py::arg("mu"), py::arg("cos_scatter"), py::arg("tau1"), py::arg("albedo"), py::arg("g") = 0.0,
        "Frisvad et al. 2005, Eq. 5 as a BSDF [1/sr] (single scattering, far face).");
  m.def("frisvad_direct_transmittance", py::vectorize([](double mu, double tau1) {
          return ThinSlab<double>{tau1, 0.0, 0.0}.DirectTransmittance(mu);
        }),
        py::arg("mu"), py::arg("tau1"), "Unscattered transmittance e^(-tau1 / mu) of the thin slab.");
  m.def(
      "walter_bsdf",
      [](const py::array_t<double, py::array::c_style | py::array::forcecast>& wi,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& wo, double alpha, double eta,
         const std::string& distribution) {
        CheckRoughness(alpha, "alpha");
        if (!(eta > 0 && eta != 1 && eta <= 4)) throw py::value_error("eta must be in (0, 4] and != 1");
        if (distribution == "ggx") return WalterEval<GgxDistribution>(wi, wo, alpha, eta);
        if (distribution == "beckmann") return WalterEval<BeckmannDistribution>(wi, wo, alpha, eta);
        throw py::value_error("distribution must be 'ggx' or 'beckmann', got '" + distribution + "'");
      },
      py::arg("wi"), py::arg("wo"), py::arg("alpha"), py::arg("eta") = 1.5, py::arg("distribution") = "ggx",
      "Walter et al. 2007 rough dielectric BSDF [1/sr] (reflection and transmission, cosine excluded) for unit "
      "directions wi, wo of shape (..., 3) in the local frame (normal +z, eta below / above).");
  m.def(
      "dai_btdf",
      [](const py::array_t<double, py::array::c_style | py::array::forcecast>& wi,
         const py::array_t<double, py::array::c_style | py::array::forcecast>& wo, double roughness, double top_weight,
         double eta, double smith_roughness, const std::string& distribution) {
        CheckRoughness(roughness, "roughness");
        if (smith_roughness <= 0) smith_roughness = roughness;
        CheckRoughness(smith_roughness, "smith_roughness");
        CheckEta(eta);
        if (!(top_weight >= 0 && top_weight <= 1)) throw py::value_error("top_weight must be in [0, 1]");
        if (distribution == "ggx") return DaiEval<GgxDistribution>(wi, wo, roughness, smith_roughness, top_weight, eta);
        if (distribution == "beckmann") {
          return DaiEval<BeckmannDistribution>(wi, wo, roughness, smith_roughness, top_weight, eta);
        }
        throw py::value_error("distribution must be 'ggx' or 'beckmann', got '" + distribution + "'");
      },
      py::arg("wi"), py::arg("wo"), py::arg("roughness"), py::arg("top_weight") = 0.5, py::arg("eta") = 1.5,
      py::arg("smith_roughness") = 0.0, py::arg("distribution") = "ggx",
      "Dai et al. 2009 dual-microfacet BTDF [1/sr] of a slab with one rough face (Eqs. 2-8) and the analytic NDF "
      "`roughness`: ln f = top_weight ln f_top + (1 - top_weight) ln f_bottom (Eq. 11, Dai's alpha); light "
      "enters from +z (wi.z > 0) and leaves through the bottom (wo.z < 0).");
}
