#include "report/validation_data.hpp"

#include <filesystem>
#include <fstream>

#include "core/error.hpp"

namespace tirstrain::report {

ValidationData read_validation(const std::string& dir) {
  namespace fs = std::filesystem;
  const fs::path summary = fs::path(dir) / "validation.csv";
  if (!fs::exists(summary))
    throw Error("no validation.csv here: give a folder written by `tirstrain validate`",
                {.file = dir, .key = "--validation"});
  ValidationData v;
  v.dir = dir;
  v.summary = read_text_csv(summary.string());
  for (const char* column : {"quantity", "reference", "mode", "rms"})
    if (!v.summary.has(column))
      throw Error(std::string("not a validation table of `tirstrain validate`: no column '") + column + "'",
                  {.file = summary.string(), .key = "--validation"});
  if (std::ifstream provenance(fs::path(dir) / "validation.json"); provenance) {
    const nlohmann::json j = nlohmann::json::parse(provenance, nullptr, false);
    if (j.is_object() && j.contains("result_run")) v.result_run = j["result_run"];
  }
  const fs::path frames = fs::path(dir) / "validation_frames.csv";
  if (!fs::exists(frames)) return v;
  const TextTable t = read_text_csv(frames.string());
  v.t_s = t.numbers("t_s");
  v.displacement_rms_px = t.numbers("displacement_rms_px");
  v.E_xx_rms = t.numbers("E_xx_rms");
  v.U_J = t.numbers("U_J");
  v.U_truth_J = t.numbers("U_truth_J");
  return v;
}

void check_validation_of(const ValidationData& validation, const nlohmann::json& result_summary,
                         const std::string& result_dir) {
  if (!validation.result_run.is_object() || !validation.result_run.contains("input")) return;
  const std::string input = result_summary.value("input", "");
  const double wall_time_s = result_summary.value("wall_time_s", -1.0);
  if (input == validation.result_run.value("input", "") &&
      wall_time_s == validation.result_run.value("wall_time_s", -2.0))
    return;
  throw Error("describes another result run (of " + validation.result_run.value("input", std::string("?")) +
                  ") than " + result_dir + " (of " + input +
                  "): give each result its own validation, in the results' order",
              {.file = validation.dir, .key = "--validation"});
}

}  // namespace tirstrain::report
