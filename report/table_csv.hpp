#pragma once
// CSV tables whose cells may be text or empty (validation.csv's quantity names, validation_frames.csv's
// "nan"): read as text, numbers on request.
#include <string>
#include <vector>

namespace tirstrain::report {

struct TextTable {
  std::string path;
  std::vector<std::string> names;              // header
  std::vector<std::vector<std::string>> rows;  // rows[i][j]: cell j of data row i ("" where the row is short)
  bool has(const std::string& name) const;
  // Column `name` as numbers: NaN where a cell is empty or not a number. Throws Error naming the file and
  // the column when there is no such column.
  std::vector<double> numbers(const std::string& name) const;
  std::string cell(std::size_t row, const std::string& name) const;
};

// Throws Error naming the file when it cannot be read or has no header.
TextTable read_text_csv(const std::string& path);

}  // namespace tirstrain::report
