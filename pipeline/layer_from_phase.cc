// SPDX-License-Identifier: Apache-2.0
#include "thinslab/pipeline/layer_from_phase.h"

#include <nlohmann/json.hpp>

#include "thinslab/core/file.h"

namespace thinslab {

Status ReadJsonObjectFile(const std::string& path, const std::string& expected, nlohmann::json* j) {
  if (!FileExists(path)) return Status::Error(path + ": not found (expected " + expected + ")");
  std::string text;
  THINSLAB_RETURN_IF_ERROR(ReadFileToString(path, &text));
  *j = nlohmann::json::parse(text, nullptr, false);
  if (j->is_discarded() || !j->is_object()) return Status::Error(path + ": not a JSON object");
  return Status::Ok();
}

Status ReadPhaseLayerChoice(const std::string& phase_dir, PhaseLayerChoice* choice) {
  *choice = PhaseLayerChoice();
  choice->summary_path = JoinPath(phase_dir, "summary.json");
  nlohmann::json summary;
  THINSLAB_RETURN_IF_ERROR(ReadJsonObjectFile(choice->summary_path, "a `thinslab fit phase` output", &summary));
  const std::string& path = choice->summary_path;
  if (!summary.contains("model") || summary["model"] != "gu2007_eq8") {
    return Status::Error(path + ": model: expected \"gu2007_eq8\" (a `thinslab fit phase` summary)");
  }
  if (!summary.contains("result") || !summary["result"].is_string()) return Status::Error(path + ": result: missing");
  const std::string result = summary["result"].get<std::string>();
  if (result == "no_measurable_scattering") {
    choice->rung = 0;
  } else if (result == "success") {
    if (!summary.contains("g") || !summary["g"].is_number())
      return Status::Error(path + ": g: missing or not a number");
    choice->g = summary["g"].get<double>();
    if (!(choice->g > -1 && choice->g < 1))
      return Status::Error(path + ": g: " + summary["g"].dump() + " is not in (-1, 1)");
    if (summary.contains("sigma_g") && summary["sigma_g"].is_number())
      choice->sigma_g = summary["sigma_g"].get<double>();
  } else {
    return Status::Error(path + ": result is \"" + result + "\": the lobe fit gave no usable g (" +
                         (summary.contains("message") ? summary["message"].dump() : std::string("no message")) + ")");
  }
  const std::string ladder_path = JoinPath(phase_dir, "ladder.json");
  if (result == "success" && FileExists(ladder_path)) {
    nlohmann::json ladder;
    THINSLAB_RETURN_IF_ERROR(ReadJsonObjectFile(ladder_path, "a `thinslab fit phase` output", &ladder));
    if (!ladder.contains("chosen_rung") || !ladder["chosen_rung"].is_number_integer() ||
        ladder["chosen_rung"].get<int>() < 0 || ladder["chosen_rung"].get<int>() > 2) {
      return Status::Error(ladder_path + ": chosen_rung: expected 0, 1 or 2");
    }
    choice->ladder_path = ladder_path;
    choice->rung = ladder["chosen_rung"].get<int>();
  }
  return Status::Ok();
}

void ApplyPhaseLayerChoice(const PhaseLayerChoice& choice, TauFitOptions* options) {
  options->refine_scattering = choice.rung > 0;
  options->layer_g = choice.rung == 2 ? choice.g : 0.0;
}

}  // namespace thinslab
