#pragma once
// What a report shows of a `tirstrain validate` output folder: the summary rows of validation.csv and the
// per-frame errors of validation_frames.csv.
#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "report/table_csv.hpp"

namespace tirstrain::report {

struct ValidationData {
  std::string dir;
  TextTable summary;        // validation.csv: quantity, reference, mode, unit, rms, max_abs, mean, samples
  std::vector<double> t_s;  // validation_frames.csv's frames (empty without it)
  std::vector<double> displacement_rms_px;  // per frame, NaN where not measured
  std::vector<double> E_xx_rms;
  std::vector<double> U_J, U_truth_J;  // strain energy measured and true on the same triangles
  // validation.json's record of the result run it describes (summary.json's input and wall_time_s);
  // null for a validation written before it was kept.
  nlohmann::json result_run;
};

// Throws Error naming both folders when `validation` records a result run other than `result_summary`'s
// (a validation given beside another result).
void check_validation_of(const ValidationData& validation, const nlohmann::json& result_summary,
                         const std::string& result_dir);

// Throws Error naming the folder when it holds no validation.csv.
ValidationData read_validation(const std::string& dir);

}  // namespace tirstrain::report
