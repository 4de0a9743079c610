// SPDX-License-Identifier: Apache-2.0
#include "thinslab/drivers/display_gamma.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <sstream>

#include "thinslab/core/file.h"
#include "thinslab/drivers/pattern_id.h"

namespace thinslab {
namespace {

// Piecewise-linear interpolation through (xs, ys), xs strictly increasing.
double Interpolate(const std::vector<double>& xs, const std::vector<double>& ys, double x) {
  if (x <= xs.front()) return ys.front();
  if (x >= xs.back()) return ys.back();
  const size_t i = std::upper_bound(xs.begin(), xs.end(), x) - xs.begin();
  const double t = (x - xs[i - 1]) / (xs[i] - xs[i - 1]);
  return ys[i - 1] + t * (ys[i] - ys[i - 1]);
}

// `where` names the table (a file path); `lines`, when given, the file line of each entry, so a
// bad entry is reported as "<path>:<line>: entry <n>".
Status ValidateGammaTable(const GammaTable& table, const std::string& where, const std::vector<int>* lines = nullptr) {
  auto at = [&](size_t i) {
    return lines != nullptr && i < lines->size() ? where + ":" + std::to_string((*lines)[i]) : where;
  };
  const auto& p = table.drive_to_light;
  if (p.size() < 2) {
    return Status::Error(where + ": gamma table needs at least 2 entries, got " + std::to_string(p.size()));
  }
  for (size_t i = 0; i < p.size(); ++i) {
    const auto [d, l] = p[i];
    if (!std::isfinite(d) || !std::isfinite(l) || d < 0 || d > 1 || l < 0 || l > 1) {
      return Status::Error(at(i) + ": entry " + std::to_string(i + 1) + " is outside [0, 1] or not finite");
    }
    if (i > 0 && (d <= p[i - 1].first || l < p[i - 1].second)) {
      return Status::Error(at(i) + ": entry " + std::to_string(i + 1) +
                           ": drive levels must increase strictly and light must not decrease");
    }
  }
  if (p.front().first != 0 || p.front().second != 0 || p.back().first != 1 ||
      p.back().second != 1) {
    const size_t bad = p.front().first != 0 || p.front().second != 0 ? 0 : p.size() - 1;
    return Status::Error(at(bad) + ": gamma table must start at \"0 0\" and end at \"1 1\"");
  }
  return Status::Ok();
}

}  // namespace

double GammaTable::LightForDrive(double drive) const {
  std::vector<double> xs, ys;
  for (const auto& [d, l] : drive_to_light) {
    xs.push_back(d);
    ys.push_back(l);
  }
  return Interpolate(xs, ys, drive);
}

double GammaTable::DriveForLight(double light) const {
  // Light is non-decreasing in drive; a flat run (a display that does not respond between two
  // levels) maps to its lowest drive level, so the inverse is well defined.
  const auto& p = drive_to_light;
  if (light <= p.front().second) return p.front().first;
  for (size_t i = 1; i < p.size(); ++i) {
    if (light <= p[i].second && p[i].second > p[i - 1].second) {
      const double t = (light - p[i - 1].second) / (p[i].second - p[i - 1].second);
      return p[i - 1].first + std::clamp(t, 0.0, 1.0) * (p[i].first - p[i - 1].first);
    }
  }
  return p.back().first;
}

GammaTable IdentityGammaTable() { return GammaTable{{{0.0, 0.0}, {1.0, 1.0}}}; }

Status ReadGammaTable(const std::string& path, GammaTable* table) {
  std::string bytes;
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(path, &bytes).WithContext("gamma table"));
  GammaTable out;
  std::istringstream in(bytes);
  std::string line;
  int line_number = 0;
  std::vector<int> lines;  // File line of each entry, for messages.
  while (std::getline(in, line)) {
    ++line_number;
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    std::istringstream fields(line);
    std::string a, b, extra;
    if (!(fields >> a)) continue;  // Blank or comment line.
    const std::string where = path + ":" + std::to_string(line_number);
    if (!(fields >> b) || (fields >> extra)) {
      return Status::Error(where + ": expected two numbers \"drive light\"");
    }
    char* end_a = nullptr;
    char* end_b = nullptr;
    const double d = std::strtod(a.c_str(), &end_a);
    const double l = std::strtod(b.c_str(), &end_b);
    if (*end_a != '\0' || *end_b != '\0') {
      return Status::Error(where + ": \"" + a + " " + b + "\" is not two numbers");
    }
    out.drive_to_light.push_back({d, l});
    lines.push_back(line_number);
  }
  THINSLAB_RETURN_IF_ERROR(ValidateGammaTable(out, path, &lines));
  *table = out;
  return Status::Ok();
}

Status WriteGammaTable(const std::string& path, const GammaTable& table, const std::string& comment) {
  THINSLAB_RETURN_IF_ERROR(ValidateGammaTable(table, path));
  std::string text =
      "# thinslab display gamma table (docs/drivers.md): drive level, relative emitted light\n";
  if (!comment.empty()) {
    std::istringstream lines(comment);
    std::string line;
    while (std::getline(lines, line)) text += "# " + line + "\n";
  }
  char buf[80];
  for (const auto& [d, l] : table.drive_to_light) {
    std::snprintf(buf, sizeof(buf), "%.17g %.17g\n", d, l);
    text += buf;
  }
  return WriteFileAtomically(path, text);
}

Status FitGammaTable(const std::vector<std::pair<double, double>>& level_signal, GammaTable* table) {
  // Average repeated levels.
  std::map<double, std::pair<double, int>> by_level;
  for (size_t i = 0; i < level_signal.size(); ++i) {
    const auto [level, signal] = level_signal[i];
    if (!std::isfinite(level) || !std::isfinite(signal) || level < 0 || level > 1) {
      return Status::Error("FitGammaTable: measurement " + std::to_string(i + 1) +
                           " has a level outside [0, 1] or a non-finite value");
    }
    auto& [sum, count] = by_level[level];
    sum += signal;
    ++count;
  }
  if (by_level.size() < 3) {
    return Status::Error("FitGammaTable: need at least 3 distinct drive levels, got " +
                         std::to_string(by_level.size()));
  }
  if (by_level.begin()->first != 0 || by_level.rbegin()->first != 1) {
    return Status::Error("FitGammaTable: the measurement must include drive levels 0 and 1");
  }
  std::vector<double> levels, values, weights;
  for (const auto& [level, sum_count] : by_level) {
    levels.push_back(level);
    values.push_back(sum_count.first / sum_count.second);
    weights.push_back(sum_count.second);
  }
  // Pool adjacent violators: the weighted least-squares non-decreasing fit. Camera noise makes
  // neighbouring levels of a nearly flat (dark) region swap order; the display itself is
  // monotonic, and the inverse lookup needs monotonic data.
  struct Block {
    double value, weight;
    size_t count;
  };
  std::vector<Block> blocks;
  for (size_t i = 0; i < values.size(); ++i) {
    blocks.push_back({values[i], weights[i], 1});
    while (blocks.size() > 1 && blocks[blocks.size() - 2].value > blocks.back().value) {
      Block b = blocks.back();
      blocks.pop_back();
      Block& a = blocks.back();
      a.value = (a.value * a.weight + b.value * b.weight) / (a.weight + b.weight);
      a.weight += b.weight;
      a.count += b.count;
    }
  }
  std::vector<double> fitted;
  for (const Block& b : blocks) fitted.insert(fitted.end(), b.count, b.value);
  const double s0 = fitted.front(), s1 = fitted.back();
  if (!(s1 > s0)) {
    return Status::Error(
        "FitGammaTable: the signal at drive level 1 is not above the signal at level 0 (camera "
        "not seeing the display, or saturated at every level)");
  }
  GammaTable out;
  for (size_t i = 0; i < levels.size(); ++i) {
    out.drive_to_light.push_back({levels[i], std::clamp((fitted[i] - s0) / (s1 - s0), 0.0, 1.0)});
  }
  out.drive_to_light.front().second = 0;
  out.drive_to_light.back().second = 1;
  *table = out;
  return Status::Ok();
}

std::vector<std::string> GammaMeasurementPatterns(int steps) {
  std::vector<std::string> ids;
  steps = std::max(steps, 2);
  for (int i = 0; i <= steps; ++i) ids.push_back(FlatPatternId(static_cast<double>(i) / steps));
  return ids;
}

std::string GammaTableCompactText(const GammaTable& table) {
  std::string text;
  char buf[64];
  for (const auto& [d, l] : table.drive_to_light) {
    std::snprintf(buf, sizeof(buf), "%s%.6g:%.6g", text.empty() ? "" : ",", d, l);
    text += buf;
  }
  return text;
}

}  // namespace thinslab
