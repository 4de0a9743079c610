// SPDX-License-Identifier: Apache-2.0
// Issue #22, section 5: a table-driven bad-input corpus through the real `thinslab` binary,
// over every command. SetUpTestSuite makes small inputs with the binary itself (a shadow-map
// capture, a laser lobe, a dot scan, a display-gamma session, a pattern, a synthesized layer,
// fits of them, a copy of the bundled prototype library, a folder of the user's own files).
// Each case copies the inputs it names into its own folder, breaks them (a manifest field, a
// frame file) or passes a bad option or an output path that overlaps an input, runs one command
// and asserts:
//  - a non-zero exit that is neither a signal nor a hang: 1..123 (the command runs under `sh`
//    and `timeout`: a crash is 128 + signal, e.g. 134 abort, 139 segfault; a hang is 124);
//  - exactly one `error: ` line, holding every expected piece (the file, the JSON field or the
//    --option; "a|b" accepts either);
//  - no NaN, raw OpenCV assertion, sanitizer report, or "valid: yes" in the output;
//  - the case's whole input folder unchanged (every path, file type, mode, the bytes of every
//    file, symlink targets), and nothing left at the output path it named ({out}).
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "tests/testing/run_thinslab.h"
#include "tests/testing/temp_dir.h"

namespace thinslab {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// A hang is a failure too; every case's inputs are tiny (Release: < 1 s per case).
constexpr int kTimeoutS = 30;

// ---------------------------------------------------------------------------------------------
// Running the binary.

// Like RunThinslab (tests/testing/run_thinslab.h), in `cwd` (so a default output relative to the
// working directory lands in the case's scratch folder) and under `timeout`.
RunResult RunIn(const std::string& cwd, const std::string& args) {
  const std::string binary = fs::absolute(ThinslabBinary()).string();
  const std::string command = "cd '" + cwd + "' && timeout -k 5 " + std::to_string(kTimeoutS) + " '" + binary + "' " +
                              args + " 2>&1 </dev/null";
  RunResult result;
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return result;
  std::array<char, 4096> buffer;
  while (fgets(buffer.data(), buffer.size(), pipe) != nullptr) result.output += buffer.data();
  const int status = pclose(pipe);
  result.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : WIFSIGNALED(status) ? 128 + WTERMSIG(status) : -1;
  return result;
}

std::string ReadBytes(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream bytes;
  bytes << in.rdbuf();
  return bytes.str();
}

void WriteBytes(const std::string& path, const std::string& bytes) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

std::string Replace(std::string text, const std::string& from, const std::string& to) {
  for (size_t at = text.find(from); at != std::string::npos; at = text.find(from, at + to.size())) {
    text.replace(at, from.size(), to);
  }
  return text;
}

// ---------------------------------------------------------------------------------------------
// The checksum of an input tree: every entry's relative path -> type, mode and content.

std::string Fnv1a(const std::string& bytes) {
  uint64_t hash = 14695981039346656037ULL;
  for (unsigned char c : bytes) hash = (hash ^ c) * 1099511628211ULL;
  char text[17];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(hash));
  return text;
}

std::string DescribeEntry(const fs::path& path) {
  std::error_code ec;
  const fs::file_status st = fs::symlink_status(path, ec);
  if (ec || !fs::exists(st)) return "missing";
  std::ostringstream d;
  d << "mode " << std::oct << (static_cast<unsigned>(st.permissions()) & 07777) << std::dec << " ";
  switch (st.type()) {
    case fs::file_type::directory:
      d << "directory";
      break;
    case fs::file_type::symlink:
      d << "symlink -> " << fs::read_symlink(path, ec).string();
      break;
    case fs::file_type::fifo:
      d << "fifo";  // Never opened: that would block.
      break;
    case fs::file_type::regular: {
      std::ifstream in(path, std::ios::binary);
      if (!in) {
        d << "unreadable file of " << fs::file_size(path, ec) << " bytes";
      } else {
        std::ostringstream bytes;
        bytes << in.rdbuf();
        d << "file of " << bytes.str().size() << " bytes, fnv1a " << Fnv1a(bytes.str());
      }
      break;
    }
    default:
      d << "file type " << static_cast<int>(st.type());
  }
  return d.str();
}

using TreeState = std::map<std::string, std::string>;

TreeState StateOf(const std::string& root) {
  TreeState state;
  state["."] = DescribeEntry(root);
  std::error_code ec;
  if (!fs::is_directory(fs::symlink_status(root, ec))) return state;
  for (auto it = fs::recursive_directory_iterator(root, fs::directory_options::skip_permission_denied, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    state[it->path().lexically_relative(root).string()] = DescribeEntry(it->path());
  }
  return state;
}

std::string DescribeChanges(const TreeState& before, const TreeState& after) {
  std::ostringstream out;
  int shown = 0;
  auto show = [&](const std::string& path, const std::string& was, const std::string& is) {
    if (++shown <= 12) out << "\n  " << path << ": " << was << "  ->  " << is;
  };
  for (const auto& [path, was] : before) {
    const auto it = after.find(path);
    const std::string is = it == after.end() ? "missing" : it->second;
    if (is != was) show(path, was, is);
  }
  for (const auto& [path, is] : after) {
    if (before.count(path) == 0) show(path, "absent", is);
  }
  if (shown > 12) out << "\n  ... " << shown - 12 << " more";
  return out.str();
}

void MakeWritable(const std::string& root) {
  std::error_code ec;
  fs::permissions(root, fs::perms::owner_all, fs::perm_options::add, ec);
  for (auto it = fs::recursive_directory_iterator(root, fs::directory_options::skip_permission_denied, ec);
       !ec && it != fs::recursive_directory_iterator(); it.increment(ec)) {
    if (!fs::is_symlink(it->symlink_status()))
      fs::permissions(it->path(), fs::perms::owner_all, fs::perm_options::add, ec);
  }
}

// ---------------------------------------------------------------------------------------------
// The base inputs, made once by the binary itself.

struct Bases {
  std::unique_ptr<TempDir> dir;
  std::string root;   // dir/bases
  std::string error;  // "" when every base was made
  std::string Path(const std::string& name) const { return root + "/" + name; }
};

// Options of the simulations below, repeated by the cases whose command simulates (so that an
// option a defect lets through still runs small).
constexpr const char* kSmallShadow =
    " --tau {pattern}/pattern.exr --camera-width-px 160 --camera-height-px 120"
    " --photons 2000 --frames 1 --dark-frames 1";
constexpr const char* kSmallLaser =
    " --camera-width-px 160 --camera-height-px 120 --capture-clean false --photons 20000";
constexpr const char* kSmallDots =
    " --grid-nx 4 --grid-ny 4 --photons-k 2 --camera-width-px 120 --camera-height-px 90 --table-bins 16";
constexpr const char* kSmallMonitor =
    " --quiet --camera-width-px 80 --camera-height-px 60";  // acquire dot-scan|bracket|gamma
constexpr const char* kSmallLayer = " --prototypes dust_specks_a --width 32 --height 32 --preview false";

const Bases& GetBases() {
  static const std::unique_ptr<Bases> bases = [] {
    auto b = std::make_unique<Bases>();
    b->dir = std::make_unique<TempDir>();
    b->root = *b->dir / "bases";
    fs::create_directories(b->root + "/pattern");
    const std::string src = std::getenv("THINSLAB_SOURCE_DIR") ? std::getenv("THINSLAB_SOURCE_DIR") : ".";
    auto run = [&](const std::string& args) {
      if (!b->error.empty()) return;
      const std::string expanded = Replace(Replace(args, "{b}", b->root), "{pattern}", b->root + "/pattern");
      const RunResult r = RunIn(b->root, expanded);
      if (r.exit_code != 0)
        b->error = "thinslab " + expanded + " -> exit " + std::to_string(r.exit_code) + ": " + r.output;
    };
    auto copy = [&](const std::string& from, const std::string& to) {
      std::error_code ec;
      fs::copy(from, to, fs::copy_options::recursive | fs::copy_options::copy_symlinks, ec);
      if (ec && b->error.empty()) b->error = "copy " + from + " -> " + to + ": " + ec.message();
    };
    run("sim pattern {b}/pattern/pattern.exr --width-px 16 --height-px 16");
    run("sim shadow-maps {b}/shadow" + std::string(kSmallShadow));
    copy(b->root + "/shadow", b->root + "/shadow_fit");
    run("fit tau {b}/shadow_fit");
    run("sim laser {b}/laser" + std::string(kSmallLaser));
    copy(b->root + "/laser", b->root + "/laser_fit");
    run("fit phase {b}/laser_fit");
    run("sim dot-scan {b}/dots" + std::string(kSmallDots));
    run("acquire gamma" + std::string(kSmallMonitor) + " --steps 2 --repeats 1 --dark-frames 1 {b}/gamma");
    run("synth layer {b}/layer" + std::string(kSmallLayer));
    copy(src + "/data/prototypes", b->root + "/library");
    // Photographs for `calib camera` (frames of the shadow capture: valid PNGs, no chessboard).
    fs::create_directories(b->root + "/images");
    copy(b->root + "/shadow/frames/cam0/reference/0001.png", b->root + "/images/a.png");
    copy(b->root + "/shadow/frames/cam0/shadow/0002.png", b->root + "/images/b.png");
    // A folder of the user's own files that thinslab did not write.
    fs::create_directories(b->root + "/mine/raw");
    WriteBytes(b->root + "/mine/notes.txt", "my notes: glass 7, measured on Tuesday\n");
    WriteBytes(b->root + "/mine/raw/data.bin", std::string("\x01\x02\x03\x04 raw bytes", 15));
    return b;
  }();
  return *bases;
}

// ---------------------------------------------------------------------------------------------
// The cases.

// The folders of one case. Placeholders in arguments, expected pieces and mutation paths:
// {case} the case's input folder (all of it is checksummed), {<base>} the copy of a base in it,
// {in} the first base's copy, {out} an output path outside it (absent).
struct Dirs {
  std::string root, in, out;
  std::map<std::string, std::string> bases;
  std::string Expand(std::string text) const {
    for (const auto& [name, path] : bases) text = Replace(text, "{" + name + "}", path);
    return Replace(Replace(Replace(text, "{case}", root), "{in}", in), "{out}", out);
  }
};

using Mutation = std::function<void(const Dirs&)>;
using Check = std::function<void(const Dirs&)>;

struct Case {
  std::string name;
  std::string bases;  // comma-separated base inputs copied into the case folder ("" = none)
  Mutation mutate;    // applied to the copies before the checksum (may be empty)
  std::string args;
  std::vector<std::string> expect;  // pieces of the error line; "a|b" = a or b
  Check extra;                      // a further check after the run (may be empty)
  bool needs_permissions = false;   // chmod-based: meaningless as root
  bool may_leave_record = false;    // acquire: a failed session may record its failure at {out}
};

Case C(std::string name, std::string bases, Mutation mutate, std::string args, std::vector<std::string> expect) {
  Case c;
  c.name = std::move(name);
  c.bases = std::move(bases);
  c.mutate = std::move(mutate);
  c.args = std::move(args);
  c.expect = std::move(expect);
  return c;
}

// --- mutations --------------------------------------------------------------------------------

// Edits {in}/session.json.
Mutation Manifest(std::function<void(json&)> edit) {
  return [edit](const Dirs& d) {
    const std::string path = d.in + "/session.json";
    json j = json::parse(ReadBytes(path));
    edit(j);
    WriteBytes(path, j.dump(2));
  };
}
Mutation Set(const std::string& pointer, json value) {
  return Manifest([pointer, value](json& j) { j[json::json_pointer(pointer)] = value; });
}
Mutation Erase(const std::string& pointer) {
  return Manifest([pointer](json& j) {
    const json::json_pointer p(pointer);
    j[p.parent_pointer()].erase(p.back());
  });
}
// A literal written as is, e.g. a number that overflows a double (1e999).
Mutation SetRaw(const std::string& pointer, const std::string& text) {
  return [pointer, text](const Dirs& d) {
    const std::string path = d.in + "/session.json";
    json j = json::parse(ReadBytes(path));
    j[json::json_pointer(pointer)] = "@@raw@@";
    WriteBytes(path, Replace(j.dump(2), "\"@@raw@@\"", text));
  };
}
// Edits the first frame of `kind` (or every one).
Mutation FirstFrame(const std::string& kind, std::function<void(json&)> edit) {
  return Manifest([kind, edit](json& j) {
    for (auto& f : j["frames"]) {
      if (f["kind"] == kind) {
        edit(f);
        return;
      }
    }
    ADD_FAILURE() << "no frame of kind " << kind;
  });
}
Mutation EveryFrame(const std::string& kind, std::function<void(json&)> edit) {
  return Manifest([kind, edit](json& j) {
    for (auto& f : j["frames"]) {
      if (f["kind"] == kind) edit(f);
    }
  });
}
Mutation SetFrame(const std::string& kind, const std::string& pointer, json value) {
  return FirstFrame(kind, [pointer, value](json& f) { f[json::json_pointer(pointer)] = value; });
}

Mutation Write(const std::string& path, const std::string& bytes) {
  return [path, bytes](const Dirs& d) {
    fs::create_directories(fs::path(d.Expand(path)).parent_path());
    WriteBytes(d.Expand(path), bytes);
  };
}
Mutation Truncate(const std::string& path, uintmax_t size) {
  return [path, size](const Dirs& d) { fs::resize_file(d.Expand(path), size); };
}
Mutation Remove(const std::string& path) {
  return [path](const Dirs& d) { fs::remove_all(d.Expand(path)); };
}
Mutation MakeDir(const std::string& path) {
  return [path](const Dirs& d) { fs::create_directories(d.Expand(path)); };
}
Mutation ByDirectory(const std::string& path) {
  return [path](const Dirs& d) {
    fs::remove_all(d.Expand(path));
    fs::create_directories(d.Expand(path) + "/inside");
  };
}
Mutation ByFifo(const std::string& path) {
  return [path](const Dirs& d) {
    fs::remove_all(d.Expand(path));
    ASSERT_EQ(mkfifo(d.Expand(path).c_str(), 0644), 0) << path;
  };
}
Mutation Symlink(const std::string& link, const std::string& target) {
  return [link, target](const Dirs& d) { fs::create_symlink(d.Expand(target), d.Expand(link)); };
}

enum class FrameFault {
  kMissing,
  kTruncated,
  kEmpty,
  kGarbage,
  kDirectory,
  kFifo,
  kSymlinkOutside,
  kUnreadable,
  kOtherSize
};

// Breaks the file of the first usable frame of `kind` in {in}.
Mutation BreakFrame(const std::string& kind, FrameFault fault) {
  return [kind, fault](const Dirs& d) {
    const json j = json::parse(ReadBytes(d.in + "/session.json"));
    std::string file;
    for (const auto& f : j["frames"]) {
      if (f["kind"] == kind && f["status"] != "failed") {
        file = d.in + "/" + f["file"].get<std::string>();
        break;
      }
    }
    ASSERT_FALSE(file.empty()) << "no frame of kind " << kind;
    switch (fault) {
      case FrameFault::kMissing:
        fs::remove(file);
        break;
      case FrameFault::kTruncated:
        fs::resize_file(file, 100);
        break;
      case FrameFault::kEmpty:
        fs::resize_file(file, 0);
        break;
      case FrameFault::kGarbage:
        WriteBytes(file, "this is not an image\n");
        break;
      case FrameFault::kDirectory:
        ByDirectory(file)(d);
        break;
      case FrameFault::kFifo:
        ByFifo(file)(d);
        break;
      case FrameFault::kSymlinkOutside: {
        // The bytes are a valid frame, but the file lies outside the session folder.
        const std::string outside = d.root + "/outside_" + fs::path(file).filename().string();
        fs::rename(file, outside);
        fs::create_symlink(outside, file);
        break;
      }
      case FrameFault::kUnreadable:
        fs::permissions(file, fs::perms::none);
        break;
      case FrameFault::kOtherSize:
        // A valid 12-bit frame of another camera (80 x 60: the gamma session's).
        fs::copy_file(GetBases().Path("gamma") + "/frames/cam0/dark/0000.png", file,
                      fs::copy_options::overwrite_existing);
        break;
    }
  };
}

// --- further checks ---------------------------------------------------------------------------

// A refused acquisition leaves no session that claims to be capturing.
Check NoRunningSession() {
  return [](const Dirs& d) {
    const std::string manifest = d.out + "/session.json";
    if (!fs::is_regular_file(manifest)) return;
    const json j = json::parse(ReadBytes(manifest), nullptr, false);
    ASSERT_FALSE(j.is_discarded()) << manifest << " is not JSON";
    if (j.contains("acquisition")) {
      EXPECT_NE(j["acquisition"].value("state", ""), "running") << manifest;
    }
  };
}

Case NeedsPermissions(Case c) {
  c.needs_permissions = true;
  return c;
}
Case Acquisition(Case c) {
  c.may_leave_record = true;
  c.extra = NoRunningSession();
  return c;
}

// ---------------------------------------------------------------------------------------------
// The table.

std::vector<Case> Cases() {
  using F = FrameFault;
  const std::string shadow_sim = kSmallShadow, laser_sim = kSmallLaser, dots_sim = kSmallDots, monitor = kSmallMonitor,
                    layer = kSmallLayer;
  const Mutation none;
  // calib pose: the clean frame relabelled as a chessboard target, so that the option is what is wrong.
  const Mutation target = EveryFrame("reference", [](json& f) { f["kind"] = "target"; });
  const std::string spec_head =
      R"({"format": "thinslab-synth-spec", "format_version": "1.0", "width_px": 32, "height_px": 32, )";
  std::vector<Case> t = {
      // ---- thinslab info: the manifest validator, frames included ----
      C("info_no_such_folder", "", none, "info {case}/nothing", {"{case}/nothing"}),
      C("info_capture_is_a_file", "pattern", none, "info {pattern}/pattern.exr", {"pattern.exr"}),
      C("info_manifest_missing", "shadow", Remove("{in}/session.json"), "info {in}", {"session.json"}),
      C("info_manifest_empty", "shadow", Write("{in}/session.json", ""), "info {in}", {"session.json"}),
      C("info_manifest_not_json", "shadow", Write("{in}/session.json", "{\"format\": "), "info {in}", {"session.json"}),
      C("info_manifest_is_directory", "shadow", ByDirectory("{in}/session.json"), "info {in}", {"session.json"}),
      C("info_manifest_is_fifo", "shadow", ByFifo("{in}/session.json"), "info {in}", {"session.json"}),
      C("info_format_other", "shadow", Set("/format", "other-session"), "info {in}", {"session.json", "format"}),
      C("info_format_version_2", "shadow", Set("/format_version", "2.0"), "info {in}",
        {"session.json", "format_version"}),
      C("info_rig_missing", "shadow", Erase("/rig"), "info {in}", {"session.json", "rig"}),
      C("info_cameras_empty", "shadow", Set("/rig/cameras", json::array()), "info {in}",
        {"session.json", "rig.cameras"}),
      C("info_camera_width_zero", "shadow", Set("/rig/cameras/0/width_px", 0), "info {in}",
        {"rig.cameras[0].width_px"}),
      C("info_camera_width_1e10", "shadow", Set("/rig/cameras/0/width_px", 1e10), "info {in}",
        {"rig.cameras[0].width_px"}),
      // Issue #22: info must not say "valid: yes" when the frames are not the manifest's size.
      C("info_camera_width_differs_from_frames", "shadow", Set("/rig/cameras/0/width_px", 161), "info {in}",
        {"frames/cam0/", "161"}),
      C("info_camera_fx_infinite", "shadow", SetRaw("/rig/cameras/0/fx_px", "1e999"), "info {in}",
        {"session.json", "1e999"}),
      C("info_camera_bit_depth_7", "shadow", Set("/rig/cameras/0/bit_depth", 7), "info {in}",
        {"rig.cameras[0].bit_depth"}),
      C("info_camera_rotation_zero", "shadow", Set("/rig/cameras/0/cam_from_sample/rotation_wxyz", {0, 0, 0, 0}),
        "info {in}", {"rotation_wxyz"}),
      C("info_camera_duplicate_id", "shadow",
        Manifest([](json& j) { j["rig"]["cameras"].push_back(j["rig"]["cameras"][0]); }), "info {in}",
        {"rig.cameras[1].id"}),
      C("info_sample_pitch_zero", "shadow", Set("/rig/sample/pixel_pitch_m", 0), "info {in}",
        {"rig.sample.pixel_pitch_m"}),
      C("info_region_inverted", "shadow", Set("/rig/sample/region_max_m", {-0.001, -0.001}), "info {in}",
        {"rig.sample.region_max_m"}),
      C("info_frames_not_an_array", "shadow", Set("/frames", "all of them"), "info {in}", {"session.json", "frames"}),
      C("info_frame_index_gap", "shadow", Set("/frames/1/index", 7), "info {in}", {"session.json", "index"}),
      C("info_frame_camera_unknown", "shadow", Set("/frames/0/camera", "cam9"), "info {in}", {"frames[0].camera"}),
      C("info_frame_kind_empty", "shadow", Set("/frames/0/kind", ""), "info {in}", {"frames[0].kind"}),
      C("info_frame_file_absolute", "shadow", Set("/frames/0/file", "/etc/passwd"), "info {in}", {"frames[0].file"}),
      C("info_frame_file_dotdot", "shadow", Set("/frames/0/file", "../shadow/frames/cam0/dark/0000.png"), "info {in}",
        {"frames[0].file"}),
      C("info_frame_exposure_zero", "shadow", Set("/frames/0/exposure_time_us", 0), "info {in}",
        {"frames[0].exposure_time_us"}),
      C("info_frame_missing", "shadow", BreakFrame("shadow", F::kMissing), "info {in}", {"frames/cam0/shadow/"}),
      C("info_frame_truncated", "shadow", BreakFrame("shadow", F::kTruncated), "info {in}", {"frames/cam0/shadow/"}),
      // ---- thinslab check (issue #28): the same reader, its options and its JSON output ----
      C("check_no_such_folder", "", none, "check {case}/nothing", {"{case}/nothing"}),
      C("check_manifest_not_json", "shadow", Write("{in}/session.json", "{\"format\": "), "check {in}",
        {"session.json"}),
      C("check_frame_truncated", "shadow", BreakFrame("shadow", F::kTruncated), "check {in}", {"frames/cam0/shadow/"}),
      C("check_fraction_above_1", "shadow", none, "check {in} --max-saturated-fraction 1.5",
        {"max_saturated_fraction", "1.5"}),
      C("check_json_over_the_manifest", "shadow", none, "check {in} --json {in}/session.json", {"session.json"}),
      C("info_frame_empty", "shadow", BreakFrame("shadow", F::kEmpty), "info {in}", {"frames/cam0/shadow/"}),
      C("info_frame_is_directory", "shadow", BreakFrame("shadow", F::kDirectory), "info {in}", {"frames/cam0/shadow/"}),
      C("info_frame_symlink_outside", "shadow", BreakFrame("shadow", F::kSymlinkOutside), "info {in}",
        {"frames/cam0/shadow/"}),
      C("info_unknown_option", "shadow", none, "info {in} --verbosity", {"--verbosity"}),

      // ---- thinslab fit tau ----
      C("fit_tau_albedo_above_1", "shadow", none, "fit tau {in} --albedo 1.7", {"--albedo|layer_albedo"}),
      C("fit_tau_albedo_nan", "shadow", none, "fit tau {in} --albedo nan", {"--albedo"}),
      C("fit_tau_albedo_not_a_number", "shadow", none, "fit tau {in} --albedo thick", {"--albedo"}),
      C("fit_tau_albedo_missing_value", "shadow", none, "fit tau {in} --albedo", {"--albedo"}),
      C("fit_tau_g_1", "shadow", none, "fit tau {in} --g 1", {"--g|layer_g"}),
      C("fit_tau_g_infinite", "shadow", none, "fit tau {in} --g inf", {"--g"}),
      C("fit_tau_tau_max_zero", "shadow", none, "fit tau {in} --tau-max 0", {"--tau-max|tau_max"}),
      C("fit_tau_kernel_angle_200", "shadow", none, "fit tau {in} --kernel-max-angle-deg 200",
        {"--kernel-max-angle-deg|kernel_max_angle_deg"}),
      C("fit_tau_threads_100000", "shadow", none, "fit tau {in} --threads 100000", {"--threads|num_threads"}),
      C("fit_tau_threads_overflow", "shadow", none, "fit tau {in} --threads 99999999999", {"--threads"}),
      C("fit_tau_supersample_100000", "shadow", none, "fit tau {in} --supersample 100000",
        {"--supersample|supersample"}),
      C("fit_tau_board_distance_option_1e308", "shadow", none, "fit tau {in} --board-distance-m 1e308",
        {"--board-distance-m"}),
      C("fit_tau_max_memory_negative", "shadow", none, "fit tau {in} --max-memory -1", {"--max-memory"}),
      // Issue #29: a map over the budget is refused before any frame is read, naming its need.
      C("fit_tau_max_memory_below_the_need", "shadow", none, "fit tau {in} --max-memory 0.01",
        {"needs about", "more than --max-memory 0.01 GiB", "--split-half-check false"}),
      C("fit_tau_reference_unknown", "shadow", none, "fit tau {in} --reference mirror",
        {"--reference|TauFitOptions::reference"}),
      C("fit_tau_reference_flat_without_flat_field", "shadow", none, "fit tau {in} --reference flat",
        {"flat_field.exr"}),
      C("fit_tau_calibration_unknown", "shadow", none, "fit tau {in} --calibration maybe", {"--calibration"}),
      C("fit_tau_rig_missing", "shadow", none, "fit tau {in} --rig {case}/none.json", {"none.json"}),
      C("fit_tau_rig_not_json", "shadow", Write("{case}/rig.json", "camera: yes\n"),
        "fit tau {in} --rig {case}/rig.json", {"rig.json"}),
      C("fit_tau_calib_response_corrupt", "shadow", Write("{in}/calib/response.json", "{\"format\": \"thinslab-resp"),
        "fit tau {in}", {"response.json"}),
      C("fit_tau_phase_missing", "shadow", none, "fit tau {in} --phase {case}/nothing", {"{case}/nothing"}),
      C("fit_tau_phase_and_g", "shadow,laser_fit", none, "fit tau {in} --phase {laser_fit}/fit/phase --g 0.5",
        {"--phase", "--g"}),
      C("fit_tau_unknown_option", "shadow", none, "fit tau {in} --albdo 0.3", {"--albdo"}),
      C("fit_tau_no_capture", "", none, "fit tau", {"CAPTURE"}),
      // Manifest fields the fit uses. Issue #22: a board at 1e308 m must not crash the fit.
      C("fit_tau_board_distance_1e308", "shadow", Set("/rig/board/distance_m", 1e308), "fit tau {in}",
        {"session.json", "distance_m|board"}),
      C("fit_tau_board_missing", "shadow", Erase("/rig/board"), "fit tau {in}", {"session.json", "rig.board"}),
      C("fit_tau_pixel_pitch_1e-12", "shadow", Set("/rig/sample/pixel_pitch_m", 1e-12), "fit tau {in}",
        {"session.json", "pixel_pitch_m"}),
      C("fit_tau_region_max_1e300", "shadow", Set("/rig/sample/region_max_m", {1e300, 1e300}), "fit tau {in}",
        {"session.json", "region_max_m"}),
      C("fit_tau_camera_width_differs_from_frames", "shadow", Set("/rig/cameras/0/width_px", 161), "fit tau {in}",
        {"frames/cam0/", "161"}),
      C("fit_tau_camera_height_100000", "shadow", Set("/rig/cameras/0/height_px", 100000), "fit tau {in}",
        {"frames/cam0/", "100000"}),
      C("fit_tau_exposure_zero", "shadow", SetFrame("shadow", "/exposure_time_us", 0), "fit tau {in}",
        {"session.json", "exposure_time_us"}),
      C("fit_tau_shadow_kind_unknown", "shadow", EveryFrame("shadow", [](json& f) { f["kind"] = "holograms"; }),
        "fit tau {in}", {"session.json", "shadow"}),
      C("fit_tau_projector_parallel_to_sample", "shadow", Set("/rig/projector/direction_in_sample", {1, 0, 0}),
        "fit tau {in}", {"rig.projector.direction_in_sample"}),
      // Frame files.
      C("fit_tau_shadow_frame_missing", "shadow", BreakFrame("shadow", F::kMissing), "fit tau {in}",
        {"frames/cam0/shadow/"}),
      C("fit_tau_shadow_frame_truncated", "shadow", BreakFrame("shadow", F::kTruncated), "fit tau {in}",
        {"frames/cam0/shadow/"}),
      C("fit_tau_shadow_frame_empty", "shadow", BreakFrame("shadow", F::kEmpty), "fit tau {in}",
        {"frames/cam0/shadow/"}),
      C("fit_tau_shadow_frame_not_an_image", "shadow", BreakFrame("shadow", F::kGarbage), "fit tau {in}",
        {"frames/cam0/shadow/"}),
      C("fit_tau_shadow_frame_is_directory", "shadow", BreakFrame("shadow", F::kDirectory), "fit tau {in}",
        {"frames/cam0/shadow/"}),
      C("fit_tau_shadow_frame_is_fifo", "shadow", BreakFrame("shadow", F::kFifo), "fit tau {in}",
        {"frames/cam0/shadow/"}),
      C("fit_tau_shadow_frame_symlink_outside", "shadow", BreakFrame("shadow", F::kSymlinkOutside), "fit tau {in}",
        {"frames/cam0/shadow/"}),
      NeedsPermissions(C("fit_tau_shadow_frame_unreadable", "shadow", BreakFrame("shadow", F::kUnreadable),
                         "fit tau {in}", {"frames/cam0/shadow/"})),
      C("fit_tau_shadow_frame_other_size", "shadow", BreakFrame("shadow", F::kOtherSize), "fit tau {in}",
        {"frames/cam0/shadow/", "80x60", "160x120"}),
      // Outputs that overlap the inputs: refused, nothing of the input touched.
      C("fit_tau_out_is_capture", "shadow", none, "fit tau {in} --out {in}", {"{in}"}),
      C("fit_tau_out_is_frames", "shadow", none, "fit tau {in} --out {in}/frames", {"{in}/frames"}),
      C("fit_tau_out_is_manifest", "shadow", none, "fit tau {in} --out {in}/session.json", {"{in}/session.json"}),
      C("fit_tau_out_is_frame_file", "shadow", none, "fit tau {in} --out {in}/frames/cam0/shadow/0002.png",
        {"{in}/frames/cam0/shadow/0002.png"}),
      C("fit_tau_out_is_ground_truth", "shadow", none, "fit tau {in} --out {in}/ground_truth", {"{in}/ground_truth"}),
      C("fit_tau_out_contains_capture", "shadow", none, "fit tau {in} --out {case}", {"{case}"}),
      C("fit_tau_out_is_capture_via_dotdot", "shadow", none, "fit tau {in} --out {in}/frames/..", {"{in}"}),
      C("fit_tau_out_is_capture_via_symlink", "shadow", Symlink("{case}/link", "{in}"),
        "fit tau {in} --out {case}/link", {"link"}),
      C("fit_tau_out_is_users_folder", "shadow,mine", none, "fit tau {in} --out {mine}", {"{mine}"}),
      C("fit_tau_out_is_users_file", "shadow,mine", none, "fit tau {in} --out {mine}/notes.txt", {"{mine}/notes.txt"}),
      C("fit_tau_out_is_whole_fit_folder", "shadow_fit", none, "fit tau {in} --out {in}/fit", {"{in}/fit"}),
      C("fit_tau_out_is_phase_input", "shadow,laser_fit", none,
        "fit tau {in} --phase {laser_fit}/fit/phase --out {laser_fit}/fit/phase", {"{laser_fit}/fit/phase"}),

      // ---- thinslab fit phase ----
      C("fit_phase_tau_negative", "laser", none, "fit phase {in} --tau -1", {"--tau|PhaseFitOptions::tau"}),
      C("fit_phase_tau_nan", "laser", none, "fit phase {in} --tau nan", {"--tau"}),
      C("fit_phase_tau_map_missing", "laser", none, "fit phase {in} --tau-map {case}/none.exr", {"none.exr"}),
      C("fit_phase_tau_map_not_a_fit", "laser,pattern", none, "fit phase {in} --tau-map {pattern}/pattern.exr",
        {"pattern.exr"}),
      C("fit_phase_tau_map_truncated", "laser,shadow_fit", Truncate("{shadow_fit}/fit/tau/tau.exr", 200),
        "fit phase {in} --tau-map {shadow_fit}/fit/tau/tau.exr", {"tau.exr"}),
      C("fit_phase_ring_width_zero", "laser", none, "fit phase {in} --ring-width-px 0",
        {"--ring-width-px|ring_width_px"}),
      C("fit_phase_core_beam_radii_negative", "laser", none, "fit phase {in} --core-beam-radii -1",
        {"--core-beam-radii|core_beam_radii"}),
      C("fit_phase_max_theta_100", "laser", none, "fit phase {in} --max-theta-deg 100",
        {"--max-theta-deg|max_theta_deg"}),
      C("fit_phase_huber_scale_zero", "laser", none, "fit phase {in} --huber-scale 0", {"--huber-scale|huber_scale"}),
      C("fit_phase_supersample_100000", "laser", none, "fit phase {in} --supersample 100000",
        {"--supersample|supersample"}),
      C("fit_phase_unknown_option", "laser", none, "fit phase {in} --g 0.5", {"--g"}),
      C("fit_phase_board_distance_1e308", "laser", Set("/rig/board/distance_m", 1e308), "fit phase {in}",
        {"session.json", "distance_m|board"}),
      C("fit_phase_laser_direction_zero", "laser", Set("/rig/laser/direction_in_sample", {0, 0, 0}), "fit phase {in}",
        {"rig.laser.direction_in_sample"}),
      C("fit_phase_beam_radius_negative", "laser", Set("/rig/laser/beam_radius_m", -0.0005), "fit phase {in}",
        {"rig.laser.beam_radius_m"}),
      C("fit_phase_lobe_exposure_zero", "laser", SetFrame("laser", "/exposure_time_us", 0), "fit phase {in}",
        {"session.json", "exposure_time_us"}),
      C("fit_phase_camera_width_differs_from_frames", "laser", Set("/rig/cameras/0/width_px", 161), "fit phase {in}",
        {"frames/cam0/", "161"}),
      C("fit_phase_pixel_pitch_1e-12", "laser", Set("/rig/sample/pixel_pitch_m", 1e-12), "fit phase {in}",
        {"session.json", "pixel_pitch_m"}),
      C("fit_phase_lobe_frame_truncated", "laser", BreakFrame("laser", F::kTruncated), "fit phase {in}",
        {"frames/cam0/laser/"}),
      C("fit_phase_flat_frame_is_directory", "laser", BreakFrame("flat", F::kDirectory), "fit phase {in}",
        {"frames/cam0/flat/"}),
      C("fit_phase_out_is_capture", "laser", none, "fit phase {in} --out {in}", {"{in}"}),
      C("fit_phase_out_is_frames", "laser", none, "fit phase {in} --out {in}/frames", {"{in}/frames"}),
      C("fit_phase_out_is_manifest", "laser", none, "fit phase {in} --out {in}/session.json", {"{in}/session.json"}),
      C("fit_phase_out_is_tau_map_folder", "laser,shadow_fit", none,
        "fit phase {in} --tau-map {shadow_fit}/fit/tau/tau.exr --out {shadow_fit}/fit/tau", {"{shadow_fit}/fit/tau"}),
      // ---- thinslab fit dmf ----
      C("fit_dmf_eta_negative", "dots", none, "fit dmf {in} --pitch-mm 8 --eta -1", {"--eta"}),
      C("fit_dmf_atlas_stride_negative", "dots", none, "fit dmf {in} --pitch-mm 8 --atlas-stride -3",
        {"--atlas-stride"}),
      C("fit_dmf_threads_100000", "dots", none, "fit dmf {in} --pitch-mm 8 --threads 100000", {"--threads"}),
      C("fit_dmf_pitch_negative", "dots", none, "fit dmf {in} --pitch-mm -1", {"--pitch-mm"}),
      C("fit_dmf_pitch_1e-9", "dots", none, "fit dmf {in} --pitch-mm 1e-9", {"--pitch-mm"}),
      C("fit_dmf_ndf_resolution_100000", "dots", none, "fit dmf {in} --pitch-mm 8 --ndf-resolution 100000",
        {"--ndf-resolution|ndf_resolution"}),
      C("fit_dmf_smoothness_negative", "dots", none, "fit dmf {in} --pitch-mm 8 --smoothness -1",
        {"--smoothness|smoothness"}),
      C("fit_dmf_ndf_tail_unknown", "dots", none, "fit dmf {in} --pitch-mm 8 --ndf-tail spline",
        {"--ndf-tail|ndf_tail", "'smooth' or 'family'"}),
      C("fit_dmf_ndf_tail_max_misfit_negative", "dots", none, "fit dmf {in} --pitch-mm 8 --ndf-tail-max-misfit -1",
        {"--ndf-tail-max-misfit|ndf_tail_max_misfit"}),
      C("fit_dmf_cluster_fraction_2", "dots", none, "fit dmf {in} --pitch-mm 8 --cluster-fraction 2",
        {"--cluster-fraction"}),
      C("fit_dmf_neighbors_zero", "dots", none, "fit dmf {in} --pitch-mm 8 --neighbors 0",
        {"--neighbors|num_neighbors"}),
      C("fit_dmf_dot_radius_zero", "dots", none, "fit dmf {in} --pitch-mm 8 --dot-radius-px 0", {"--dot-radius-px"}),
      C("fit_dmf_glass_thickness_100mm", "dots", none, "fit dmf {in} --pitch-mm 8 --glass-thickness-mm 100",
        {"--glass-thickness-mm"}),
      C("fit_dmf_peak_separation_1", "dots", none, "fit dmf {in} --pitch-mm 8 --peak-separation-fraction 1",
        {"--peak-separation-fraction|peak_separation_fraction"}),
      C("fit_dmf_max_edge_fraction_negative", "dots", none, "fit dmf {in} --pitch-mm 8 --max-edge-fraction -1",
        {"--max-edge-fraction|max_edge_fraction"}),
      C("fit_dmf_ndf_pixels_outside_map", "dots", none, "fit dmf {in} --pitch-mm 8 --ndf-pixels '1000,1000'",
        {"--ndf-pixels"}),
      C("fit_dmf_ladder_tile_zero", "dots", none,
        "fit dmf {in} --pitch-mm 8 --hold-out true --ladder true --ladder-tile 0", {"--ladder-tile"}),
      C("fit_dmf_monitor_missing", "dots", Erase("/rig/monitor"), "fit dmf {in} --pitch-mm 8",
        {"session.json", "rig.monitor"}),
      C("fit_dmf_glass_ior_below_1", "dots", Set("/rig/sample/glass_ior", 0.5), "fit dmf {in} --pitch-mm 8",
        {"rig.sample.glass_ior"}),
      C("fit_dmf_dot_position_text", "dots", SetFrame("dot", "/light/dot_px", "centre"), "fit dmf {in} --pitch-mm 8",
        {"light.dot_px"}),
      C("fit_dmf_camera_width_differs_from_frames", "dots", Set("/rig/cameras/0/width_px", 121),
        "fit dmf {in} --pitch-mm 8", {"frames/cam0/", "121"}),
      C("fit_dmf_manifest_pitch_1e-12", "dots", Set("/rig/sample/pixel_pitch_m", 1e-12), "fit dmf {in}",
        {"session.json", "pixel_pitch_m"}),
      C("fit_dmf_all_dots_frame_truncated", "dots", BreakFrame("all_dots", F::kTruncated), "fit dmf {in} --pitch-mm 8",
        {"frames/cam0/all_dots/"}),
      C("fit_dmf_dot_frame_missing", "dots", BreakFrame("dot", F::kMissing), "fit dmf {in} --pitch-mm 8",
        {"frames/cam0/dot/"}),
      C("fit_dmf_out_is_capture", "dots", none, "fit dmf {in} --pitch-mm 8 --out {in}", {"{in}"}),
      C("fit_dmf_out_is_frames", "dots", none, "fit dmf {in} --pitch-mm 8 --out {in}/frames", {"{in}/frames"}),
      C("fit_dmf_out_is_manifest", "dots", none, "fit dmf {in} --pitch-mm 8 --out {in}/session.json",
        {"{in}/session.json"}),
      C("fit_dmf_hold_out_pattern_unknown", "dots", none,
        "fit dmf {in} --pitch-mm 8 --hold-out true --hold-out-pattern stripes", {"--hold-out-pattern", "stripes"}),
      C("fit_dmf_hold_out_fraction_1", "dots", none,
        "fit dmf {in} --pitch-mm 8 --hold-out true --hold-out-pattern random --hold-out-fraction 1",
        {"--hold-out-fraction"}),
      C("fit_unknown_model", "shadow", none, "fit holography {in}", {"holography"}),

      // ---- thinslab predict ----
      C("predict_without_fit", "dots", none, "predict {in}", {"fit/dmf"}),
      C("predict_dots_text", "dots", none, "predict {in} --dots abc", {"--dots"}),
      C("predict_fit_of_shadow_capture", "dots,shadow", none, "predict {in} --fit {shadow}",
        {"{shadow}", "not an output"}),
      C("predict_dots_with_tau_fit", "shadow_fit", none, "predict {in} --dots 1,1", {"--dots", "fit dmf"}),
      C("predict_tau_without_reference", "shadow_fit", SetFrame("reference", "/kind", "unused"), "predict {in}",
        {"session.json", "reference"}),
      C("predict_tau_other_grid", "shadow_fit", Set("/rig/sample/pixel_pitch_m", 1.6e-4), "predict {in}",
        {"rig.sample", "tau.exr"}),
      C("predict_out_is_capture", "dots", none, "predict {in} --out {in}", {"{in}"}),

      // ---- thinslab export ----
      C("export_unknown_renderer", "shadow_fit", none, "export povray {in}/fit/tau {out}", {"povray"}),
      C("export_not_a_fit", "shadow", none, "export mitsuba {in} {out}", {"{in}", "holds no maps.exr"}),
      C("export_tau_truncated", "shadow_fit", Truncate("{in}/fit/tau/tau.exr", 200), "export pbrt {in}/fit/tau {out}",
        {"tau.exr"}),
      C("export_tau_summary_without_layer", "shadow_fit", Write("{in}/fit/tau/summary.json", "{}"),
        "export blender {in}/fit/tau {out}", {"summary.json", "layer.g"}),
      C("export_phase_of_shadow", "shadow_fit,laser_fit", none,
        "export mitsuba {in}/fit/tau {out} --phase {laser_fit}/fit", {"--phase", "summary.json"}),
      C("export_min_alpha_zero", "shadow_fit", none, "export pbrt {in}/fit/tau {out} --min-alpha 0", {"--min-alpha"}),
      C("export_albedo_above_one", "layer", none, "export mitsuba {layer} {out} --albedo 2", {"--albedo"}),
      C("export_out_inside_fit", "shadow_fit", none, "export pbrt {in}/fit/tau {in}/fit/tau/scene", {"{in}/fit/tau"}),

      // ---- thinslab preview ----
      C("preview_not_a_fit", "shadow", none, "preview {in} {out}", {"{in}", "holds no maps.exr"}),
      C("preview_n2_above_three", "layer", none, "preview {layer} {out} --n2 9", {"--n2"}),
      C("preview_panel_scale_negative", "shadow_fit", none, "preview {in}/fit/tau {out} --panel-scale -1",
        {"--panel-scale"}),
      C("preview_tau_truncated", "shadow_fit", Truncate("{in}/fit/tau/tau.exr", 200), "preview {in}/fit/tau {out}",
        {"tau.exr"}),
      C("preview_out_inside_fit", "shadow_fit", none, "preview {in}/fit/tau {in}/fit/tau/preview", {"{in}/fit/tau"}),

      // ---- thinslab roundtrip ----
      C("roundtrip_laser_without_fit", "laser", none, "roundtrip {in} --out {out}", {"fit/phase", "fit phase"}),
      C("roundtrip_dot_scan_without_fit", "dots", none, "roundtrip {in} --out {out}", {"fit/dmf", "fit dmf"}),
      C("roundtrip_without_fit", "shadow", none, "roundtrip {in} --out {out}", {"fit/tau", "fit tau"}),
      C("roundtrip_tau_truncated", "shadow_fit", Truncate("{in}/fit/tau/tau.exr", 200), "roundtrip {in} --out {out}",
        {"tau.exr"}),
      C("roundtrip_samples_negative", "shadow_fit", none, "roundtrip {in} --out {out} --samples -1", {"--samples"}),
      C("roundtrip_blender_missing", "shadow_fit", none, "roundtrip {in} --out {out} --blender {case}/no_blender",
        {"--blender", "{case}/no_blender"}),
      C("roundtrip_out_inside_fit", "shadow_fit", none, "roundtrip {in} --out {in}/fit/tau/rt", {"{in}/fit/tau"}),

      // ---- thinslab calib camera ----
      C("calib_camera_no_images", "", none, "calib camera --out {out}", {"IMAGES|--images"}),
      C("calib_camera_images_folder_empty", "", MakeDir("{case}/empty"),
        "calib camera --images {case}/empty --out {out}", {"{case}/empty"}),
      C("calib_camera_image_truncated", "images", Truncate("{images}/a.png", 100),
        "calib camera {images}/a.png {images}/b.png --min-views 1 --out {out}", {"a.png"}),
      C("calib_camera_image_is_directory", "images", none, "calib camera {images} --out {out}", {"{images}"}),
      C("calib_camera_board_without_x", "images", none, "calib camera --images {images} --board 9 --out {out}",
        {"--board"}),
      C("calib_camera_square_zero", "images", none, "calib camera --images {images} --square-mm 0 --out {out}",
        {"--square-mm"}),
      C("calib_camera_distortion_7", "images", none, "calib camera --images {images} --distortion-coeffs 7 --out {out}",
        {"--distortion-coeffs|num_distortion"}),
      C("calib_camera_min_views_zero", "images", none, "calib camera --images {images} --min-views 0 --out {out}",
        {"--min-views|min_views"}),
      C("calib_camera_subpix_negative", "images", none,
        "calib camera --images {images} --subpix-window-px -1 --out {out}",
        {"--subpix-window-px|subpix_half_window_px"}),
      // ---- thinslab calib pose ----
      C("calib_pose_board_even", "shadow", target, "calib pose {in} --board 8x6", {"--board"}),
      C("calib_pose_square_negative", "shadow", target, "calib pose {in} --square-mm -5", {"--square-mm"}),
      C("calib_pose_offset_two_values", "shadow", target, "calib pose {in} --board-offset-mm 1,2",
        {"--board-offset-mm"}),
      C("calib_pose_no_target_frames", "shadow", none, "calib pose {in}", {"session.json", "target"}),
      C("calib_pose_kind_missing", "shadow", none, "calib pose {in} --kind nothing", {"nothing"}),
      C("calib_pose_rig_missing", "shadow", target, "calib pose {in} --rig {case}/none.json", {"none.json"}),
      C("calib_pose_rig_not_json", "shadow,mine", target, "calib pose {in} --rig {mine}/notes.txt", {"notes.txt"}),

      // ---- thinslab calib dots ----
      C("calib_dots_radius_zero", "dots", none, "calib dots {in} --dot-radius-px 0", {"--dot-radius-px|dot_radius_px"}),
      C("calib_dots_threshold_negative", "dots", none, "calib dots {in} --threshold-sigma -1",
        {"--threshold-sigma|threshold_sigma"}),
      C("calib_dots_kind_missing", "dots", none, "calib dots {in} --kind nothing", {"nothing"}),
      C("calib_dots_on_shadow_capture", "shadow", none, "calib dots {in}", {"session.json", "rig.monitor"}),
      C("calib_dots_all_dots_frame_truncated", "dots", BreakFrame("all_dots", F::kTruncated), "calib dots {in}",
        {"frames/cam0/all_dots/"}),
      C("calib_dots_monitor_width_zero", "dots", Set("/rig/monitor/width_px", 0), "calib dots {in}",
        {"rig.monitor.width_px"}),
      C("calib_dots_manifest_dot_radius_negative", "dots", Set("/rig/monitor/dot_radius_px", -2), "calib dots {in}",
        {"rig.monitor.dot_radius_px"}),
      C("fit_dmf_manifest_dot_radius_text", "dots", Set("/rig/monitor/dot_radius_px", "two"),
        "fit dmf {in} --pitch-mm 8", {"rig.monitor.dot_radius_px"}),

      // ---- thinslab calib response ----
      C("calib_response_method_unknown", "laser", none, "calib response {in} --method mitsunaga", {"--method"}),
      C("calib_response_samples_zero", "laser", none, "calib response {in} --samples 0", {"--samples|num_samples"}),
      C("calib_response_knots_100000", "laser", none, "calib response {in} --knots 100000", {"--knots|max_knots"}),
      C("calib_response_min_exposures_1", "laser", none, "calib response {in} --min-exposures 1",
        {"--min-exposures|min_exposures"}),
      C("calib_response_kind_missing", "laser", none, "calib response {in} --kind nothing", {"nothing"}),
      C("calib_response_camera_unknown", "laser", none, "calib response {in} --camera cam9", {"cam9"}),
      C("calib_response_single_exposure", "shadow", none, "calib response {in}", {"session.json", "exposure"}),
      C("calib_response_out_is_manifest", "laser", none, "calib response {in} --out {in}/session.json",
        {"{in}/session.json"}),
      C("calib_response_out_is_capture", "laser", none, "calib response {in} --out {in}", {"{in}"}),
      C("calib_response_out_is_users_file", "laser,mine", none, "calib response {in} --out {mine}/notes.txt",
        {"{mine}/notes.txt"}),

      // ---- thinslab calib hdr ----
      C("calib_hdr_read_noise_negative", "laser", none, "calib hdr {in} --read-noise-dn -1", {"--read-noise-dn"}),
      C("calib_hdr_weighting_unknown", "laser", none, "calib hdr {in} --weighting median", {"--weighting"}),
      C("calib_hdr_threads_100000", "laser", none, "calib hdr {in} --threads 100000", {"--threads|num_threads"}),
      C("calib_hdr_exposures_unknown", "laser", none, "calib hdr {in} --exposures guessed", {"--exposures"}),
      C("calib_hdr_response_missing", "laser", none, "calib hdr {in} --response {case}/none.json", {"none.json"}),
      C("calib_hdr_lobe_frame_truncated", "laser", BreakFrame("laser", F::kTruncated), "calib hdr {in}",
        {"frames/cam0/laser/"}),
      C("calib_hdr_out_is_capture", "laser", none, "calib hdr {in} --out {in}", {"{in}"}),
      C("calib_hdr_out_is_manifest", "laser", none, "calib hdr {in} --out {in}/session.json", {"{in}/session.json"}),
      C("calib_hdr_out_is_users_folder", "laser,mine", none, "calib hdr {in} --out {mine}", {"{mine}"}),

      // ---- thinslab calib flat ----
      C("calib_flat_sigma_negative", "shadow", none, "calib flat {in} --sigma-px -1",
        {"--sigma-px|smoothing_sigma_px"}),
      C("calib_flat_min_relative_2", "shadow", none, "calib flat {in} --min-relative 2",
        {"--min-relative|min_relative"}),
      C("calib_flat_response_missing", "shadow", none, "calib flat {in} --response {case}/none.json", {"none.json"}),
      C("calib_flat_reference_frame_empty", "shadow", BreakFrame("reference", F::kEmpty), "calib flat {in}",
        {"frames/cam0/reference/"}),
      C("calib_flat_out_is_manifest", "shadow", none, "calib flat {in} --out {in}/session.json", {"{in}/session.json"}),
      C("calib_flat_out_is_capture", "shadow", none, "calib flat {in} --out {in}", {"{in}"}),
      C("calib_flat_out_is_frame", "shadow", none, "calib flat {in} --out {in}/frames/cam0/reference/0001.png",
        {"{in}/frames/cam0/reference/0001.png"}),
      C("calib_flat_out_is_users_file", "shadow,mine", none, "calib flat {in} --out {mine}/notes.txt",
        {"{mine}/notes.txt"}),

      // ---- thinslab calib gamma ----
      C("calib_gamma_lit_fraction_zero", "gamma", none, "calib gamma {in} --lit-fraction 0",
        {"--lit-fraction|lit_fraction"}),
      C("calib_gamma_max_saturated_2", "gamma", none, "calib gamma {in} --max-saturated-fraction 2",
        {"--max-saturated-fraction|max_saturated_fraction"}),
      C("calib_gamma_read_noise_negative", "gamma", none, "calib gamma {in} --read-noise-dn -1",
        {"--read-noise-dn|fallback_read_noise_dn"}),
      C("calib_gamma_response_missing", "gamma", none, "calib gamma {in} --response {case}/none.json", {"none.json"}),
      C("calib_gamma_on_shadow_capture", "shadow", none, "calib gamma {in}", {"session.json", "level"}),
      C("calib_gamma_level_frame_truncated", "gamma", BreakFrame("level", F::kTruncated), "calib gamma {in}",
        {"frames/cam0/level/"}),
      C("calib_gamma_out_is_manifest", "gamma", none, "calib gamma {in} --out {in}/session.json",
        {"{in}/session.json"}),
      C("calib_gamma_o_is_capture", "gamma", none, "calib gamma {in} -o {in}", {"{in}"}),
      C("calib_gamma_out_is_users_file", "gamma,mine", none, "calib gamma {in} --out {mine}/notes.txt",
        {"{mine}/notes.txt"}),
      C("calib_unknown_kind", "shadow", none, "calib holography {in}", {"holography"}),

      // ---- thinslab sim shadow-maps ----
      C("sim_shadow_tau_missing", "pattern", none, "sim shadow-maps {out}" + shadow_sim + " --tau {case}/none.exr",
        {"none.exr"}),
      C("sim_shadow_tau_truncated", "pattern", Truncate("{pattern}/pattern.exr", 300),
        "sim shadow-maps {out}" + shadow_sim, {"pattern.exr"}),
      C("sim_shadow_tau_is_directory", "pattern", none, "sim shadow-maps {out}" + shadow_sim + " --tau {pattern}",
        {"{pattern}"}),
      C("sim_shadow_board_distance_negative", "pattern", none,
        "sim shadow-maps {out}" + shadow_sim + " --board-distance-mm -1", {"--board-distance-mm"}),
      C("sim_shadow_board_distance_1e308", "pattern", none,
        "sim shadow-maps {out}" + shadow_sim + " --board-distance-mm 1e308", {"--board-distance-mm"}),
      C("sim_shadow_albedo_2", "pattern", none, "sim shadow-maps {out}" + shadow_sim + " --albedo 2",
        {"--albedo|layer_albedo"}),
      C("sim_shadow_camera_width_zero", "pattern", none, "sim shadow-maps {out}" + shadow_sim + " --camera-width-px 0",
        {"--camera-width-px|camera_width_px"}),
      C("sim_shadow_camera_100000_squared", "pattern", none,
        "sim shadow-maps {out}" + shadow_sim + " --camera-width-px 100000 --camera-height-px 100000",
        {"--camera-width-px|--camera-height-px|camera_width_px|camera_height_px"}),
      C("sim_shadow_photons_negative", "pattern", none, "sim shadow-maps {out}" + shadow_sim + " --photons -5",
        {"--photons"}),
      C("sim_shadow_bit_depth_7", "pattern", none, "sim shadow-maps {out}" + shadow_sim + " --bit-depth 7",
        {"--bit-depth|bit_depth"}),
      C("sim_shadow_frames_zero", "pattern", none, "sim shadow-maps {out}" + shadow_sim + " --frames 0",
        {"--frames|frames_per_state"}),
      C("sim_shadow_falloff_2", "pattern", none, "sim shadow-maps {out}" + shadow_sim + " --projector-falloff 2",
        {"--projector-falloff|projector_falloff"}),
      C("sim_shadow_tilt_90", "pattern", none, "sim shadow-maps {out}" + shadow_sim + " --camera-tilt-deg 90",
        {"--camera-tilt-deg|camera_tilt_deg"}),
      C("sim_shadow_out_is_capture", "pattern,shadow", none, "sim shadow-maps {shadow}" + shadow_sim, {"{shadow}"}),
      C("sim_shadow_out_is_users_folder", "pattern,mine", none, "sim shadow-maps {mine}" + shadow_sim, {"{mine}"}),
      C("sim_shadow_no_out", "pattern", none, "sim shadow-maps" + shadow_sim, {"OUT"}),

      // ---- thinslab sim laser ----
      C("sim_laser_tau_negative", "", none, "sim laser {out}" + laser_sim + " --tau -1", {"--tau|layer_tau"}),
      C("sim_laser_board_distance_zero", "", none, "sim laser {out}" + laser_sim + " --board-distance-mm 0",
        {"--board-distance-mm"}),
      C("sim_laser_board_distance_1e308", "", none, "sim laser {out}" + laser_sim + " --board-distance-mm 1e308",
        {"--board-distance-mm"}),
      C("sim_laser_exposures_zero", "", none, "sim laser {out}" + laser_sim + " --exposures-us 0,200",
        {"--exposures-us"}),
      C("sim_laser_exposures_infinite", "", none, "sim laser {out}" + laser_sim + " --exposures-us 20,inf",
        {"--exposures-us"}),
      C("sim_laser_camera_width_zero", "", none, "sim laser {out}" + laser_sim + " --camera-width-px 0",
        {"--camera-width-px"}),
      C("sim_laser_camera_100000_squared", "", none,
        "sim laser {out}" + laser_sim + " --camera-width-px 100000 --camera-height-px 100000",
        {"--camera-width-px|--camera-height-px"}),
      C("sim_laser_photons_zero", "", none, "sim laser {out}" + laser_sim + " --photons 0", {"--photons"}),
      C("sim_laser_spike_fill_negative", "", none, "sim laser {out}" + laser_sim + " --spike-fill -1",
        {"--spike-fill|spike_fill"}),
      C("sim_laser_out_is_capture", "laser", none, "sim laser {laser}" + laser_sim, {"{laser}"}),

      // ---- thinslab sim dot-scan ----
      C("sim_dots_grid_zero", "", none, "sim dot-scan {out}" + dots_sim + " --grid-nx 0", {"--grid-nx|grid_nx"}),
      C("sim_dots_grid_100000_squared", "", none,
        "sim dot-scan {out}" + dots_sim + " --grid-nx 100000 --grid-ny 100000",
        {"--grid-nx|--grid-ny|grid_nx|grid_ny"}),
      C("sim_dots_margin_half", "", none, "sim dot-scan {out}" + dots_sim + " --margin-fraction 0.5",
        {"--margin-fraction|margin_fraction"}),
      C("sim_dots_camera_100000_squared", "", none,
        "sim dot-scan {out}" + dots_sim + " --camera-width-px 100000 --camera-height-px 100000",
        {"--camera-width-px|--camera-height-px|camera_width_px|camera_height_px"}),
      C("sim_dots_monitor_distance_zero", "", none, "sim dot-scan {out}" + dots_sim + " --monitor-distance-m 0",
        {"--monitor-distance-m|monitor_distance_m"}),
      C("sim_dots_photons_zero", "", none, "sim dot-scan {out}" + dots_sim + " --photons-k 0", {"--photons-k"}),
      C("sim_dots_threads_100000", "", none, "sim dot-scan {out}" + dots_sim + " --threads 100000",
        {"--threads|num_threads"}),
      C("sim_dots_glass_thickness_negative", "", none, "sim dot-scan {out}" + dots_sim + " --glass-thickness-mm -1",
        {"--glass-thickness-mm|thickness_m"}),
      C("sim_dots_truth_pitch_zero", "", none, "sim dot-scan {out}" + dots_sim + " --truth-pitch-m 0",
        {"--truth-pitch-m|truth_pitch_m"}),
      C("sim_dots_out_is_capture", "dots", none, "sim dot-scan {dots}" + dots_sim, {"{dots}"}),

      // ---- thinslab sim pattern ----
      C("sim_pattern_width_100000", "", none, "sim pattern {out}.exr --width-px 100000", {"--width-px"}),
      C("sim_pattern_max_tau_negative", "", none, "sim pattern {out}.exr --width-px 16 --height-px 16 --max-tau -1",
        {"--max-tau"}),
      C("sim_pattern_dust_specks_negative", "", none,
        "sim pattern {out}.exr --width-px 16 --height-px 16 --dust-specks -1", {"--dust-specks"}),
      C("sim_pattern_out_is_directory", "mine", none, "sim pattern {mine} --width-px 16 --height-px 16", {"{mine}"}),
      C("sim_pattern_out_is_users_file", "mine", none, "sim pattern {mine}/notes.txt --width-px 16 --height-px 16",
        {"{mine}/notes.txt"}),
      C("sim_unknown_kind", "", none, "sim holograms {out}", {"holograms"}),

      // ---- thinslab synth add-prototype | list ----
      C("synth_add_no_fit_tau", "shadow_fit", none, "synth add-prototype {out} --name x --category dust",
        {"--fit-tau|fit_tau_dir"}),
      C("synth_add_fit_tau_missing", "", none,
        "synth add-prototype {out} --fit-tau {case}/none --name x --category dust", {"{case}/none"}),
      C("synth_add_fit_tau_is_capture", "shadow_fit", none,
        "synth add-prototype {out} --fit-tau {in} --name x --category dust", {"{in}"}),
      C("synth_add_name_bad", "shadow_fit", none,
        "synth add-prototype {out} --fit-tau {in}/fit/tau --name 'Bad Name' --category dust",
        {"--name|PrototypeFromFitOptions::name"}),
      C("synth_add_category_unknown", "shadow_fit", none,
        "synth add-prototype {out} --fit-tau {in}/fit/tau --name x --category soot",
        {"--category|PrototypeFromFitOptions::category"}),
      C("synth_add_g_1_5", "shadow_fit", none,
        "synth add-prototype {out} --fit-tau {in}/fit/tau --name x --category dust --g 1.5",
        {"--g|PrototypeFromFitOptions::g"}),
      C("synth_add_crop_outside_map", "shadow_fit", none,
        "synth add-prototype {out} --fit-tau {in}/fit/tau --name x --category dust --crop 0,0,10000,10000", {"--crop"}),
      C("synth_add_max_masked_2", "shadow_fit", none,
        "synth add-prototype {out} --fit-tau {in}/fit/tau --name x --category dust --max-masked-fraction 2",
        {"--max-masked-fraction|max_masked_fraction"}),
      C("synth_add_tau_map_truncated", "shadow_fit", Truncate("{in}/fit/tau/tau.exr", 200),
        "synth add-prototype {out} --fit-tau {in}/fit/tau --name x --category dust", {"tau.exr"}),
      C("synth_add_library_is_fit_folder", "shadow_fit", none,
        "synth add-prototype {in}/fit/tau --fit-tau {in}/fit/tau --name x --category dust", {"{in}/fit/tau"}),
      C("synth_add_library_is_capture", "shadow_fit", none,
        "synth add-prototype {in} --fit-tau {in}/fit/tau --name x --category dust", {"{in}"}),
      C("synth_add_library_is_users_file", "shadow_fit,mine", none,
        "synth add-prototype {mine}/notes.txt --fit-tau {in}/fit/tau --name x --category dust", {"{mine}/notes.txt"}),
      C("synth_list_is_file", "mine", none, "synth list {mine}/notes.txt", {"{mine}/notes.txt"}),
      C("synth_list_prototype_json_corrupt", "library", Write("{library}/dust_specks_a/prototype.json", "{\"name\": "),
        "synth list {library}", {"prototype.json"}),

      // ---- thinslab synth layer ----
      C("synth_layer_out_is_library", "library", none, "synth layer {library} --library {library}" + layer,
        {"{library}"}),
      C("synth_layer_out_is_prototype", "library", none,
        "synth layer {library}/dust_specks_a --library {library}" + layer, {"{library}/dust_specks_a"}),
      C("synth_layer_out_is_users_folder", "mine", none, "synth layer {mine}" + layer, {"{mine}"}),
      C("synth_layer_out_is_layer_file", "layer", none, "synth layer {layer}/layer.exr" + layer, {"{layer}/layer.exr"}),
      C("synth_layer_unknown_prototype", "", none, "synth layer {out}" + layer + " --prototypes dust_specks_z",
        {"dust_specks_z"}),
      C("synth_layer_no_prototypes", "", none, "synth layer {out} --width 32 --height 32 --preview false",
        {"--prototypes|--spec"}),
      C("synth_layer_spec_and_prototypes", "",
        Write("{case}/spec.json", spec_head + R"("layers": [{"prototype": "dust_specks_a"}]})"),
        "synth layer {out}" + layer + " --spec {case}/spec.json", {"--spec", "--prototypes"}),
      C("synth_layer_width_20000", "", none, "synth layer {out}" + layer + " --width 20000", {"--width"}),
      C("synth_layer_too_many_pixels", "", none, "synth layer {out}" + layer + " --width 16384 --height 16384",
        {"--width|--height"}),
      C("synth_layer_preview_px_4", "", none, "synth layer {out}" + layer + " --preview true --preview-px 4",
        {"--preview-px"}),
      C("synth_layer_density_negative", "", none, "synth layer {out}" + layer + " --density -2", {"--density"}),
      C("synth_layer_pixel_pitch_negative", "", none, "synth layer {out}" + layer + " --pixel-pitch-m -1",
        {"--pixel-pitch-m|pixel_pitch_m"}),
      C("synth_layer_spec_bad_patch", "",
        Write("{case}/spec.json", spec_head + R"("layers": [{"prototype": "dust_specks_a", "patch_px": -4}]})"),
        "synth layer {out} --spec {case}/spec.json --preview false", {"spec.json", "layers[0]", "patch_px"}),
      C("synth_layer_spec_misspelt_key", "",
        Write("{case}/spec.json", spec_head + R"("layers": [{"prototype": "dust_specks_a", "densty": 0.5}]})"),
        "synth layer {out} --spec {case}/spec.json --preview false", {"spec.json", "densty"}),
      C("synth_layer_spec_width_zero", "",
        Write("{case}/spec.json", R"({"format": "thinslab-synth-spec", "format_version": "1.0", "width_px": 0, )"
                                  R"("layers": [{"prototype": "dust_specks_a"}]})"),
        "synth layer {out} --spec {case}/spec.json --preview false", {"spec.json", "width_px"}),

      // ---- thinslab synth preview ----
      C("synth_preview_out_is_layer", "layer", none, "synth preview {layer}/layer.exr --out {layer}/layer.exr",
        {"{layer}/layer.exr"}),
      C("synth_preview_out_is_folder", "layer", none, "synth preview {layer}/layer.exr --out {layer}", {"{layer}"}),
      C("synth_preview_layer_truncated", "layer", Truncate("{layer}/layer.exr", 300),
        "synth preview {layer}/layer.exr --out {out}.png", {"layer.exr"}),
      C("synth_preview_layer_is_fifo", "layer", ByFifo("{layer}/layer.exr"),
        "synth preview {layer}/layer.exr --out {out}.png", {"layer.exr"}),
      C("synth_preview_max_size_zero", "layer", none, "synth preview {layer}/layer.exr --out {out}.png --max-size-px 0",
        {"--max-size-px|max_size_px"}),
      C("synth_preview_background_truncated", "layer,images", Truncate("{images}/a.png", 100),
        "synth preview {layer}/layer.exr --out {out}.png --background {images}/a.png", {"a.png"}),
      C("synth_unknown_command", "", none, "synth blend {out}", {"blend"}),

      // ---- thinslab acquire (simulated rigs only) ----
      // Issue #22: refused before allocating, with the memory it would need; no "running" session.
      Acquisition(C("acquire_dot_scan_camera_100000_squared", "", none,
                    "acquire dot-scan" + monitor +
                        " --grid-nx 4 --grid-ny 4 --camera-width-px 100000 "
                        "--camera-height-px 100000 {out}",
                    {"--camera-width-px|--camera-height-px", "GiB|GB|MiB|bytes|memory"})),
      Acquisition(
          C("acquire_shadow_camera_100000_squared", "pattern", none,
            "acquire shadow-maps --quiet" + shadow_sim + " --camera-width-px 100000 --camera-height-px 100000 {out}",
            {"--camera-width-px|--camera-height-px|camera_width_px|camera_height_px"})),
      Acquisition(C("acquire_shadow_frames_zero", "pattern", none,
                    "acquire shadow-maps --quiet" + shadow_sim + " --frames 0 {out}", {"--frames|frames_per_state"})),
      Acquisition(C("acquire_shadow_exposure_zero", "pattern", none,
                    "acquire shadow-maps --quiet" + shadow_sim + " --exposure-us 0 {out}",
                    {"--exposure-us|exposure_time_us"})),
      Acquisition(C("acquire_shadow_display_negative", "pattern", none,
                    "acquire shadow-maps --quiet" + shadow_sim + " --display -5 {out}", {"--display"})),
      Acquisition(C("acquire_shadow_settle_captures_zero", "pattern", none,
                    "acquire shadow-maps --quiet" + shadow_sim + " --settle-captures 0 {out}",
                    {"--settle-captures|settle_captures"})),
      Acquisition(C("acquire_shadow_camera_unknown", "", none, "acquire shadow-maps --quiet --camera gopro:1 {out}",
                    {"--camera"})),
      Acquisition(C("acquire_shadow_gamma_table_missing", "pattern", none,
                    "acquire shadow-maps --quiet" + shadow_sim + " --gamma-table {case}/none.txt {out}", {"none.txt"})),
      C("acquire_shadow_into_capture", "pattern,shadow", none, "acquire shadow-maps --quiet" + shadow_sim + " {shadow}",
        {"{shadow}"}),
      Acquisition(C("acquire_dot_scan_grid_zero", "", none,
                    "acquire dot-scan" + monitor + " --grid-nx 0 --grid-ny 4 {out}", {"--grid-nx|grid_nx"})),
      Acquisition(C("acquire_dot_scan_margin_half", "", none,
                    "acquire dot-scan" + monitor + " --grid-nx 4 --grid-ny 4 --margin-fraction 0.5 {out}",
                    {"--margin-fraction|margin_fraction"})),
      Acquisition(C("acquire_dot_scan_exposures_zero", "", none,
                    "acquire dot-scan" + monitor + " --grid-nx 4 --grid-ny 4 --exposures-us 0 {out}",
                    {"--exposures-us"})),
      Acquisition(C(
          "acquire_dot_scan_min_exposure_above_max", "", none,
          "acquire dot-scan" + monitor + " --grid-nx 4 --grid-ny 4 --min-exposure-us 100000 --max-exposure-us 10 {out}",
          {"--min-exposure-us|--max-exposure-us|min_exposure_us|max_exposure_us"})),
      Acquisition(C("acquire_dot_scan_sim_photons_zero", "", none,
                    "acquire dot-scan" + monitor + " --grid-nx 4 --grid-ny 4 --sim-sample true --sim-photons-k 0 {out}",
                    {"--sim-photons-k"})),
      Acquisition(C("acquire_gamma_steps_zero", "", none, "acquire gamma" + monitor + " --steps 0 {out}",
                    {"--steps|DisplayGammaSessionOptions::steps"})),
      Acquisition(C("acquire_bracket_frames_zero", "", none,
                    "acquire bracket" + monitor + " --frames-per-exposure 0 {out}",
                    {"--frames-per-exposure|frames_per_exposure"})),
      Acquisition(C("acquire_bracket_pattern_unknown", "", none, "acquire bracket" + monitor + " --pattern plaid {out}",
                    {"--pattern|BracketSessionOptions::pattern"})),
      C("acquire_resume_users_folder", "mine", none,
        "acquire dot-scan" + monitor + " --grid-nx 4 --grid-ny 4 --resume {mine}", {"{mine}"}),
      C("acquire_fold_journal_users_folder", "mine", none, "acquire fold-journal {mine}", {"{mine}"}),
      C("acquire_unknown_kind", "", none, "acquire holograms {out}", {"holograms"}),

      // ---- thinslab bench, charts, demo: bad options refused before any work ----
      C("bench_sweep_methods_unknown", "", none, "bench sweep {out} --quick --methods wavelets", {"--methods"}),
      C("bench_sweep_dots_zero", "", none, "bench sweep {out} --quick --methods dmf --dots 0", {"--dots"}),
      C("bench_sweep_threads_zero", "", none, "bench sweep {out} --quick --methods tau --threads 0", {"--threads"}),
      C("bench_sweep_existing_captures", "mine", Write("{mine}/captures/keep.txt", "mine\n"),
        "bench sweep {mine} --quick --methods tau", {"captures"}),
      C("bench_unknown_command", "", none, "bench sprint {out}", {"sprint"}),
      C("charts_paths_zero", "", none, "charts {out} --paths 0 --photons 1000", {"--paths"}),
      C("demo_albedo_2", "pattern", none, "demo --out {out}" + shadow_sim + " --albedo 2", {"--albedo|layer_albedo"}),
      C("demo_out_is_users_folder", "pattern,mine", none, "demo --out {mine}" + shadow_sim, {"{mine}"}),
  };
  return t;
}

// ---------------------------------------------------------------------------------------------
// The test.

std::vector<std::string> Split(const std::string& text, char separator) {
  std::vector<std::string> parts;
  std::stringstream in(text);
  std::string part;
  while (std::getline(in, part, separator)) {
    if (!part.empty()) parts.push_back(part);
  }
  return parts;
}

// gtest prints a failing case's parameter: its name.
void PrintTo(const Case& c, std::ostream* os) { *os << c.name; }

class CliBadInputCorpus : public ::testing::TestWithParam<Case> {
 protected:
  static void SetUpTestSuite() { GetBases(); }
};

TEST_P(CliBadInputCorpus, RefusedByNameWithoutTouchingTheInputs) {
  const Case& c = GetParam();
  const Bases& bases = GetBases();
  ASSERT_TRUE(bases.error.empty()) << "a base input could not be made: " << bases.error;
  if (c.needs_permissions && geteuid() == 0) GTEST_SKIP() << "root reads files of mode 000";

  // The case's folders: inputs (checksummed) and a scratch folder (working directory, {out}).
  Dirs d;
  d.root = bases.dir->path() + "/cases/" + c.name;
  const std::string scratch = bases.dir->path() + "/scratch/" + c.name;
  d.out = scratch + "/out";
  fs::create_directories(d.root);
  fs::create_directories(scratch);
  for (const std::string& base : Split(c.bases, ',')) {
    const std::string copy = d.root + "/" + base;
    fs::copy(bases.Path(base), copy, fs::copy_options::recursive | fs::copy_options::copy_symlinks);
    d.bases[base] = copy;
    if (d.in.empty()) d.in = copy;
  }
  if (c.mutate) c.mutate(d);
  if (HasFatalFailure()) return;

  const TreeState before = StateOf(d.root);
  const std::string args = d.Expand(c.args);
  const RunResult r = RunIn(scratch, args);
  const TreeState after = StateOf(d.root);
  const std::string context =
      "thinslab " + args + "\n-> exit " + std::to_string(r.exit_code) + ", output:\n" + r.output;

  // Exit: non-zero, not a signal (128 + n), not a hang (124) nor a shell failure (125-127).
  EXPECT_GE(r.exit_code, 1) << context;
  EXPECT_LE(r.exit_code, 123) << (r.exit_code == 124  ? "hung (killed after " + std::to_string(kTimeoutS) + " s)"
                                  : r.exit_code > 128 ? "killed by signal " + std::to_string(r.exit_code - 128)
                                                      : "shell failure")
                              << "\n"
                              << context;

  // One error line naming every expected piece.
  std::vector<std::string> error_lines;
  for (const std::string& line : Split(r.output, '\n')) {
    if (line.rfind("error: ", 0) == 0) error_lines.push_back(line);
  }
  EXPECT_EQ(error_lines.size(), 1u) << "expected one line 'error: ...'\n" << context;
  const std::string error = error_lines.empty() ? std::string() : error_lines.front();
  for (const std::string& piece : c.expect) {
    bool found = false;
    for (const std::string& alternative : Split(d.Expand(piece), '|'))
      found = found || error.find(alternative) != std::string::npos;
    EXPECT_TRUE(found) << "'" << d.Expand(piece) << "' not in the error line\n" << context;
  }

  // No NaN (unless the argument was one), no raw library assertion, no sanitizer report.
  const std::string output = Replace(r.output, bases.dir->path(), "<tmp>");
  if (!std::regex_search(c.args, std::regex("nan", std::regex::icase))) {
    EXPECT_FALSE(std::regex_search(output, std::regex("(^|[^A-Za-z])[-+]?nan([^A-Za-z]|$)", std::regex::icase)))
        << "NaN in the message\n"
        << context;
  }
  for (const char* forbidden :
       {"OpenCV(", "Assertion failed", "Sanitizer", "runtime error:", "valid: yes", "terminate called"}) {
    EXPECT_EQ(output.find(forbidden), std::string::npos) << "'" << forbidden << "' in the output\n" << context;
  }

  // The inputs are exactly as they were, and nothing was written to {out}.
  EXPECT_TRUE(before == after) << "the input folder changed:" << DescribeChanges(before, after) << "\n" << context;
  if (!c.may_leave_record) {
    std::error_code ec;
    EXPECT_FALSE(fs::exists(fs::symlink_status(d.out, ec))) << "output left at " << d.out << "\n" << context;
    for (const auto& entry : fs::directory_iterator(scratch, ec)) {
      if (entry.path().filename().string().rfind("out", 0) == 0) {
        ADD_FAILURE() << "output left behind: " << entry.path() << "\n" << context;
      }
    }
  }
  if (c.extra) c.extra(d);

  MakeWritable(d.root);
  std::error_code ec;
  fs::remove_all(d.root, ec);
  fs::remove_all(scratch, ec);
}

INSTANTIATE_TEST_SUITE_P(Corpus, CliBadInputCorpus, ::testing::ValuesIn(Cases()),
                         [](const ::testing::TestParamInfo<Case>& param_info) {
                           std::string name = param_info.param.name;
                           for (char& ch : name) {
                             if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
                           }
                           return name;
                         });

// The base inputs are valid: a case fails because of what it breaks, not because of its base.
TEST(CliBadInputCorpusBases, AreValidAndTheTableIsLargeAndUnique) {
  const Bases& bases = GetBases();
  ASSERT_TRUE(bases.error.empty()) << bases.error;
  for (const char* base : {"shadow", "shadow_fit", "laser", "laser_fit", "dots", "gamma"}) {
    const RunResult info = RunIn(bases.root, "info " + bases.Path(base));
    EXPECT_EQ(info.exit_code, 0) << base << ": " << info.output;
    EXPECT_NE(info.output.find("valid: yes"), std::string::npos) << base << ": " << info.output;
  }
  const std::vector<Case> cases = Cases();
  EXPECT_GE(cases.size(), 150u);
  std::map<std::string, int> names;
  for (const Case& c : cases) EXPECT_EQ(++names[c.name], 1) << "duplicate case name " << c.name;
}

}  // namespace
}  // namespace thinslab
