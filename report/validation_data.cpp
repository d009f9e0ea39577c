#include "report/validation_data.hpp"

#include <filesystem>

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

}  // namespace tirstrain::report
