// SPDX-License-Identifier: Apache-2.0
#include "thinslab/pipeline/folder_report.h"

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <sstream>
#include <vector>

#include "thinslab/core/file.h"
#include "thinslab/core/plot.h"

namespace thinslab {
namespace {

std::string Escape(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string Base64(const std::string& bytes) {
  static const char* kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  for (size_t i = 0; i < bytes.size(); i += 3) {
    const uint32_t b0 = static_cast<uint8_t>(bytes[i]);
    const uint32_t b1 = i + 1 < bytes.size() ? static_cast<uint8_t>(bytes[i + 1]) : 0;
    const uint32_t b2 = i + 2 < bytes.size() ? static_cast<uint8_t>(bytes[i + 2]) : 0;
    const uint32_t triple = (b0 << 16) | (b1 << 8) | b2;
    out += kAlphabet[(triple >> 18) & 63];
    out += kAlphabet[(triple >> 12) & 63];
    out += i + 1 < bytes.size() ? kAlphabet[(triple >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? kAlphabet[triple & 63] : '=';
  }
  return out;
}

// Scalars of summary.json's top level and of its small objects, as "key: value" rows.
void FigureRows(const nlohmann::json& j, const std::string& prefix, int depth, std::ostringstream* rows) {
  for (const auto& [key, value] : j.items()) {
    if (key == "provenance" || key == "warnings" || key == "message") continue;
    const std::string name = prefix.empty() ? key : prefix + "." + key;
    if (value.is_object() && depth < 1) {
      FigureRows(value, name, depth + 1, rows);
    } else if (value.is_primitive() || (value.is_array() && value.size() <= 4 && !value.empty() && value[0].is_primitive())) {
      *rows << "<tr><td>" << Escape(name) << "</td><td>" << Escape(value.is_string() ? value.get<std::string>() : value.dump())
            << "</td></tr>\n";
    }
  }
}

}  // namespace

Status WriteFolderReport(const std::string& folder, const std::string& final_folder, const std::string& title) {
  nlohmann::json summary = nlohmann::json::object();
  std::string text;
  if (ReadFileToString(JoinPath(folder, "summary.json"), &text).ok()) {
    summary = nlohmann::json::parse(text, nullptr, false);
    if (summary.is_discarded() || !summary.is_object()) {
      return Status::Error(JoinPath(folder, "summary.json") + ": not a JSON object; cannot write report.html");
    }
  }
  std::string options_ini;
  const bool has_options = ReadFileToString(JoinPath(folder, "options.ini"), &options_ini).ok();
  std::vector<std::string> maps, charts, files;
  for (const auto& entry : std::filesystem::directory_iterator(folder)) {
    files.push_back(entry.path().filename().string());
  }
  for (const std::string& name : files) {
    if (name.size() < 4 || name.compare(name.size() - 4, 4, ".png") != 0) continue;
    // A chart has its data beside it (core/plot.h); other pictures are maps and previews.
    const bool chart = std::find(files.begin(), files.end(), PlotCsvPath(name)) != files.end();
    (chart ? charts : maps).push_back(name);
  }
  // The fitted maps first, then the status and the comparisons with a simulated capture's truth.
  auto secondary = [](const std::string& name) {
    return name.find("status") != std::string::npos || name.find("truth") != std::string::npos ||
           name.find("error") != std::string::npos;
  };
  std::sort(files.begin(), files.end());
  std::sort(maps.begin(), maps.end(), [&](const std::string& a, const std::string& b) {
    return std::make_pair(secondary(a), a) < std::make_pair(secondary(b), b);
  });
  std::sort(charts.begin(), charts.end());

  std::ostringstream html;
  html << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>" << Escape(title)
       << "</title>\n<style>\nbody{font-family:sans-serif;margin:2em;max-width:1400px}"
          "table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:2px 8px;text-align:left}"
          "figure{display:inline-block;margin:0 1em 1em 0;vertical-align:top}figcaption{font-size:90%}"
          "figure img{max-width:460px;height:auto}"
          ".warning{color:#a40}.failure{color:#c00}pre{background:#f4f4f4;padding:0.5em}\n</style>\n</head>\n<body>\n";
  html << "<h1>" << Escape(title) << "</h1>\n<p>Folder: <code>" << Escape(final_folder) << "</code></p>\n";
  const std::string result = summary.value("result", std::string());
  if (!result.empty()) {
    html << "<p class=\"" << (result == "success" ? "result" : "failure") << "\">Result: <b>" << Escape(result)
         << "</b>";
    if (summary.contains("message")) {
      const nlohmann::json& m = summary["message"];
      html << " &mdash; " << Escape(m.is_string() ? m.get<std::string>() : m.dump());
    }
    html << "</p>\n";
  }
  html << "<h2>Warnings</h2>\n";
  const nlohmann::json warnings = summary.value("warnings", nlohmann::json::array());
  if (warnings.empty()) html << "<p>None.</p>\n";
  for (const auto& w : warnings) html << "<p class=\"warning\">" << Escape(w.is_string() ? w.get<std::string>() : w.dump()) << "</p>\n";

  auto figures = [&](const std::vector<std::string>& names) -> Status {
    for (const std::string& name : names) {
      std::string bytes;
      THINSLAB_RETURN_IF_ERROR(ReadFileToString(JoinPath(folder, name), &bytes));
      const std::string csv = PlotCsvPath(name);
      html << "<figure><img src=\"data:image/png;base64," << Base64(bytes) << "\" alt=\"" << Escape(name)
           << "\"><figcaption>" << Escape(name)
           << (std::find(files.begin(), files.end(), csv) != files.end() ? " (data: " + Escape(csv) + ")" : "")
           << "</figcaption></figure>\n";
    }
    return Status::Ok();
  };
  html << "<h2>Maps and pictures</h2>\n";
  if (maps.empty()) html << "<p>None.</p>\n";
  THINSLAB_RETURN_IF_ERROR(figures(maps));
  html << "<h2>Charts</h2>\n";
  if (charts.empty()) html << "<p>None.</p>\n";
  THINSLAB_RETURN_IF_ERROR(figures(charts));

  std::ostringstream rows;
  FigureRows(summary, "", 0, &rows);
  html << "<h2>Summary</h2>\n<table>\n" << rows.str() << "</table>\n";

  html << "<h2>Provenance</h2>\n<table>\n";
  const nlohmann::json provenance = summary.value("provenance", nlohmann::json::object());
  for (const auto& [key, value] : provenance.items()) {
    html << "<tr><td>" << Escape(key) << "</td><td><code>" << Escape(value.is_string() ? value.get<std::string>() : value.dump())
         << "</code></td></tr>\n";
  }
  html << "</table>\n";
  if (provenance.contains("command") && has_options) {
    html << "<p>Repeat this run exactly: <code>thinslab " << Escape(provenance["command"].get<std::string>())
         << " --config " << Escape(JoinPath(final_folder, "options.ini")) << "</code></p>\n";
  }
  if (has_options) html << "<h2>options.ini</h2>\n<pre>" << Escape(options_ini) << "</pre>\n";
  html << "<h2>Files</h2>\n<ul>\n";
  for (const std::string& f : files) html << "<li>" << Escape(f) << "</li>\n";
  html << "<li>report.html</li>\n</ul>\n";
  // For readers that check the page (tests/cli_report_test.cc): how many images decoded.
  html << "<script>\nwindow.addEventListener('load', function () {\n"
          "  var images = Array.prototype.slice.call(document.images);\n"
          "  var shown = images.filter(function (i) { return i.complete && i.naturalWidth > 0; }).length;\n"
          "  document.body.setAttribute('data-images-shown', shown + '/' + images.length);\n"
          "});\n</script>\n</body>\n</html>\n";
  return WriteFileAtomically(JoinPath(folder, "report.html"), html.str());
}

}  // namespace thinslab
