// SPDX-License-Identifier: Apache-2.0
#include "thinslab/app/batch_refit.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include "thinslab/core/file.h"
#include "thinslab/core/manifest_io.h"
#include "thinslab/core/output_guard.h"
#include "thinslab/core/process.h"
#include "thinslab/core/session.h"

namespace thinslab {

namespace fs = std::filesystem;

namespace {

constexpr char kStateFormat[] = "thinslab-batch-state";

// The fit a capture kind takes ("" = none).
std::string FitOfKind(const std::string& kind) {
  if (kind == "shadow_map") return "tau";
  if (kind == "laser_lobe") return "phase";
  if (kind == "dot_scan") return "dmf";
  return "";
}

std::vector<std::string> SplitWords(const std::string& text) {
  std::istringstream in(text);
  std::vector<std::string> words;
  for (std::string w; in >> w;) words.push_back(w);
  return words;
}

struct Row {
  std::string capture;  // Folder name under ROOT.
  std::string kind, fit, args;
  std::string status;  // "fitted", "current", "failed", "no fit".
  double seconds = 0;
  std::string note;  // The fit's error line, or why nothing ran.
  std::string options_digest;
  std::string capture_digest;  // CaptureDigest when the fit started.
};

// The last "error: ..." line of a fit's output (or its last line).
std::string ErrorLine(const std::string& output) {
  std::string last, error;
  std::istringstream in(output);
  for (std::string line; std::getline(in, line);) {
    if (line.empty()) continue;
    last = line;
    if (line.rfind("error: ", 0) == 0) error = line.substr(7);
  }
  return error.empty() ? last : error;
}

std::string CsvField(const std::string& text) {
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char c : text) {
    if (c == '"') quoted += '"';
    quoted += c == '\n' ? ' ' : c;
  }
  return quoted + "\"";
}

std::string Table(const std::vector<Row>& rows, bool csv) {
  std::ostringstream out;
  if (csv) {
    out << "# thinslab batch table\ncapture,kind,fit,status,seconds,note\n";
    for (const Row& r : rows) {
      char seconds[32];
      std::snprintf(seconds, sizeof(seconds), "%.1f", r.seconds);
      out << CsvField(r.capture) << "," << r.kind << "," << r.fit << "," << r.status << "," << seconds << ","
          << CsvField(r.note) << "\n";
    }
    return out.str();
  }
  size_t width = 7;
  for (const Row& r : rows) width = std::max(width, r.capture.size());
  char line[512];
  std::snprintf(line, sizeof(line), "%-*s  %-10s  %-5s  %-7s  %8s  %s\n", static_cast<int>(width), "capture", "kind",
                "fit", "status", "seconds", "note");
  out << line;
  for (const Row& r : rows) {
    std::snprintf(line, sizeof(line), "%-*s  %-10s  %-5s  %-7s  %8.1f  ", static_cast<int>(width), r.capture.c_str(),
                  r.kind.c_str(), r.fit.c_str(), r.status.c_str(), r.seconds);
    out << line << r.note << "\n";
  }
  return out.str();
}

Status ReadState(const std::string& path, nlohmann::json* state) {
  *state = {{"format", kStateFormat}, {"captures", nlohmann::json::object()}};
  if (!FileExists(path)) return Status::Ok();
  std::string text;
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(path, &text));
  nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object() || j.value("format", "") != kStateFormat || !j.contains("captures") ||
      !j["captures"].is_object()) {
    return Status::Error(path + ": not a thinslab batch state (\"format\": \"" + std::string(kStateFormat) +
                         "\" with a \"captures\" object); remove it or give another --state");
  }
  *state = std::move(j);
  return Status::Ok();
}

std::string OptionsDigest(const std::string& fit_dir) {
  std::string ini;
  if (!ReadFileToString(JoinPath(fit_dir, "options.ini"), &ini).ok()) return "";
  return Digest(ini);
}

// What a fit reads from a capture: its manifest (content), every file under calib/ and every
// frame and variance file it lists (path, size and modification time: re-taken frames, a new
// calibration or a resumed session change it; reading every frame's bytes would cost a fit's
// worth of I/O). A file that cannot be stat'ed enters as missing.
std::string CaptureDigest(const std::string& dir, const Session& session) {
  std::ostringstream text;
  auto add_file = [&text](const std::string& path, const std::string& name) {
    std::error_code ec;
    const auto size = fs::file_size(path, ec);
    if (ec) {
      text << name << " missing\n";
      return;
    }
    const auto time = fs::last_write_time(path, ec);
    text << name << " " << size << " " << (ec ? 0 : time.time_since_epoch().count()) << "\n";
  };
  std::string manifest;
  if (ReadFileToString(JoinPath(dir, kSessionManifestName), &manifest).ok()) text << Digest(manifest) << "\n";
  std::vector<std::string> calibration;
  std::error_code ec;
  for (fs::recursive_directory_iterator it(JoinPath(dir, "calib"), ec), end; !ec && it != end; it.increment(ec)) {
    if (it->is_regular_file(ec)) calibration.push_back(fs::relative(it->path(), dir, ec).string());
  }
  std::sort(calibration.begin(), calibration.end());
  for (const std::string& name : calibration) add_file(JoinPath(dir, name), name);
  for (const FrameRecord& frame : session.frames) {
    if (!frame.file.empty()) add_file(JoinPath(dir, frame.file), frame.file);
    if (!frame.variance_file.empty()) add_file(JoinPath(dir, frame.variance_file), frame.variance_file);
  }
  return Digest(text.str());
}

}  // namespace

Status ParseShard(const std::string& text, int* index, int* count) {
  int k = -1, n = -1;
  char rest = 0;
  if (std::sscanf(text.c_str(), "%d/%d%c", &k, &n, &rest) != 2 || n < 1 || k < 0 || k >= n) {
    return Status::Error("--shard: '" + text + "' is not K/N with 0 <= K < N (e.g. 0/4)");
  }
  *index = k;
  *count = n;
  return Status::Ok();
}

Status RunBatchRefit(const BatchRun& run, std::ostream& log, int* failures) {
  *failures = 0;
  if (!(run.jobs >= 1 && run.jobs <= 256)) return Status::Error("--jobs: must be 1 to 256");
  if (!(run.shard_count >= 1 && run.shard_index >= 0 && run.shard_index < run.shard_count)) {
    return Status::Error("--shard: K/N needs 0 <= K < N");
  }
  for (const auto& [fit, options] : run.fit_options) {
    for (const std::string& word : SplitWords(options)) {
      if (word == "--out" || word.rfind("--out=", 0) == 0) {
        return Status::Error("--" + fit + "-options: --out is the batch's to choose (CAPTURE/fit/" + fit + ")");
      }
    }
  }
  std::error_code ec;
  if (!fs::is_directory(run.root, ec)) return Status::Error("ROOT: " + run.root + " is not a folder");
  std::vector<std::string> captures;
  for (const fs::directory_entry& entry : fs::directory_iterator(run.root, ec)) {
    if (entry.is_directory(ec) && FileExists(JoinPath(entry.path().string(), kSessionManifestName))) {
      captures.push_back(entry.path().filename().string());
    }
  }
  if (ec) return Status::Error("ROOT: " + run.root + ": " + ec.message());
  std::sort(captures.begin(), captures.end());
  if (captures.empty()) {
    return Status::Error("ROOT: " + run.root + " holds no capture folder (a folder with " +
                         std::string(kSessionManifestName) + ")");
  }
  std::vector<std::string> shard;
  for (size_t i = 0; i < captures.size(); ++i) {
    if (static_cast<int>(i % run.shard_count) == run.shard_index) shard.push_back(captures[i]);
  }

  const std::string shard_tag =
      run.shard_count > 1 ? "_" + std::to_string(run.shard_index) + "of" + std::to_string(run.shard_count) : "";
  const std::string state_path =
      run.state_path.empty() ? JoinPath(run.root, "thinslab_batch" + shard_tag + ".json") : run.state_path;
  std::string table_path = run.table_path;
  if (table_path.empty()) {
    table_path = state_path.size() > 5 && state_path.substr(state_path.size() - 5) == ".json"
                     ? state_path.substr(0, state_path.size() - 5) + ".csv"
                     : state_path + ".csv";
  }
  const std::string logs_dir = table_path.substr(0, table_path.size() - (table_path.size() > 4 ? 4 : 0)) + "_logs";
  for (const std::string& path : {state_path, table_path}) THINSLAB_RETURN_IF_ERROR(CheckReplaceableFile(path));
  nlohmann::json state;
  THINSLAB_RETURN_IF_ERROR(ReadState(state_path, &state));
  THINSLAB_RETURN_IF_ERROR(CreateDirectories(logs_dir));

  // Which captures need a fit.
  std::vector<Row> rows;
  std::vector<size_t> queue;
  for (const std::string& name : shard) {
    Row row;
    row.capture = name;
    const std::string dir = JoinPath(run.root, name);
    Session session;
    const Status read = ReadSession(dir, &session);
    if (!read.ok()) {
      row.status = "failed";
      row.note = read.message();
      ++*failures;
      rows.push_back(row);
      continue;
    }
    row.kind = session.kind;
    row.fit = FitOfKind(session.kind);
    if (row.fit.empty()) {
      row.status = "no fit";
      row.note = "kind " + session.kind + " has no fit";
      rows.push_back(row);
      continue;
    }
    const auto options = run.fit_options.find(row.fit);
    row.args = options == run.fit_options.end() ? "" : options->second;
    const std::string fit_dir = JoinPath(JoinPath(dir, "fit"), row.fit);
    const nlohmann::json& recorded = state["captures"].contains(name) ? state["captures"][name] : nlohmann::json();
    const std::string digest = OptionsDigest(fit_dir);
    row.capture_digest = CaptureDigest(dir, session);
    const bool same_fit = recorded.is_object() && recorded.value("status", "") != "failed" &&
                          recorded.value("fit", "") == row.fit && recorded.value("args", "") == row.args &&
                          !digest.empty() && recorded.value("options_digest", "") == digest &&
                          FileExists(JoinPath(fit_dir, "summary.json"));
    if (!run.force && same_fit && recorded.value("capture_digest", "") == row.capture_digest) {
      row.status = "current";
      row.options_digest = digest;
      row.note = "fit/" + row.fit + " has these options";
    } else {
      // A fit of other options, or of the capture before it changed (frames, calibration).
      if (!run.force && same_fit) row.note = "the capture changed since its fit";
      queue.push_back(rows.size());
    }
    rows.push_back(row);
  }
  log << "thinslab batch: " << shard.size() << " of " << captures.size() << " captures under " << run.root
      << (run.shard_count > 1
              ? " (shard " + std::to_string(run.shard_index) + "/" + std::to_string(run.shard_count) + ")"
              : std::string())
      << ", " << queue.size() << " to fit, " << run.jobs << " at a time\n";

  auto save_state = [&]() -> Status {
    for (const Row& r : rows) {
      if (r.status.empty()) continue;
      state["captures"][r.capture] = {{"kind", r.kind},
                                      {"fit", r.fit},
                                      {"args", r.args},
                                      {"status", r.status},
                                      {"seconds", r.seconds},
                                      {"note", r.note},
                                      {"options_digest", r.options_digest},
                                      {"capture_digest", r.capture_digest}};
    }
    return WriteFileAtomically(state_path, state.dump(2) + "\n");
  };

  // The fits, `jobs` at a time.
  struct Running {
    size_t row;
    std::string log_path;
    std::chrono::steady_clock::time_point start;
  };
  std::map<pid_t, Running> running;
  size_t next = 0;
  while (next < queue.size() || !running.empty()) {
    while (next < queue.size() && static_cast<int>(running.size()) < run.jobs) {
      Row& row = rows[queue[next++]];
      const std::string dir = JoinPath(run.root, row.capture);
      std::vector<std::string> argv = {run.executable, "fit", row.fit, dir};
      for (const std::string& w : SplitWords(row.args)) argv.push_back(w);
      const std::string log_path = JoinPath(logs_dir, row.capture + "_" + row.fit + ".log");
      std::string command_line;
      for (const std::string& a : argv) command_line += (command_line.empty() ? "" : " ") + a;
      THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(log_path, "# thinslab batch: " + command_line + "\n"));
      log << "  fitting " << row.capture << " (fit " << row.fit << (row.args.empty() ? "" : " " + row.args) << ")\n";
      pid_t pid = 0;
      const Status started = StartProgram(argv, log_path, &pid);
      if (!started.ok()) {
        row.status = "failed";
        row.note = started.message();
        ++*failures;
        THINSLAB_RETURN_IF_ERROR(save_state());
        continue;
      }
      running[pid] = {queue[next - 1], log_path, std::chrono::steady_clock::now()};
    }
    if (running.empty()) continue;
    pid_t ended = 0;
    int exit_code = 0;
    THINSLAB_RETURN_IF_ERROR(WaitProgram(-1, &ended, &exit_code));
    const auto it = running.find(ended);
    if (it == running.end()) continue;
    Row& row = rows[it->second.row];
    row.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - it->second.start).count();
    std::string output;
    if (!ReadFileToString(it->second.log_path, &output).ok()) output.clear();
    const std::string fit_dir = JoinPath(JoinPath(JoinPath(run.root, row.capture), "fit"), row.fit);
    if (exit_code == 0) {
      row.status = "fitted";
      row.options_digest = OptionsDigest(fit_dir);
      if (!row.note.empty()) row.note = "refitted: " + row.note;
    } else {
      row.status = "failed";
      row.note = "exit " + std::to_string(exit_code) + ": " + ErrorLine(output) + " (log " + it->second.log_path + ")";
      ++*failures;
    }
    log << "  " << row.status << " " << row.capture << " in " << static_cast<int>(row.seconds + 0.5) << " s\n";
    running.erase(it);
    THINSLAB_RETURN_IF_ERROR(save_state());
  }
  THINSLAB_RETURN_IF_ERROR(save_state());
  THINSLAB_RETURN_IF_ERROR(WriteFileAtomically(table_path, Table(rows, true)));
  log << "\n" << Table(rows, false) << "\nwrote " << table_path << " and " << state_path << "\n";
  return Status::Ok();
}

}  // namespace thinslab
