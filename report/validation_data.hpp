#pragma once
// What a report shows of a `tirstrain validate` output folder: the summary rows of validation.csv and the
// per-frame errors of validation_frames.csv.
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
};

// Throws Error naming the folder when it holds no validation.csv.
ValidationData read_validation(const std::string& dir);

}  // namespace tirstrain::report
