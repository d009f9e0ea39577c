#include "report/table_csv.hpp"

#include <algorithm>
#include <charconv>
#include <fstream>
#include <limits>

#include "core/csv.hpp"
#include "core/error.hpp"

namespace tirstrain::report {
namespace {

std::size_t column_of(const TextTable& t, const std::string& name) {
  const auto it = std::find(t.names.begin(), t.names.end(), name);
  if (it == t.names.end()) throw Error("no column '" + name + "'", {.file = t.path});
  return static_cast<std::size_t>(it - t.names.begin());
}

double number_of(const std::string& cell) {
  double value = std::numeric_limits<double>::quiet_NaN();
  const char* end = cell.data() + cell.size();
  const auto [ptr, ec] = std::from_chars(cell.data(), end, value);
  return (ec == std::errc() && ptr == end) ? value : std::numeric_limits<double>::quiet_NaN();
}

}  // namespace

bool TextTable::has(const std::string& name) const {
  return std::find(names.begin(), names.end(), name) != names.end();
}

std::vector<double> TextTable::numbers(const std::string& name) const {
  const std::size_t j = column_of(*this, name);
  std::vector<double> out;
  out.reserve(rows.size());
  for (const auto& row : rows)
    out.push_back(j < row.size() ? number_of(row[j]) : std::numeric_limits<double>::quiet_NaN());
  return out;
}

std::string TextTable::cell(std::size_t row, const std::string& name) const {
  const std::size_t j = column_of(*this, name);
  return j < rows.at(row).size() ? rows[row][j] : "";
}

TextTable read_text_csv(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error("cannot open the table", {.file = path});
  TextTable t;
  t.path = path;
  std::string line;
  if (!std::getline(in, line)) throw Error("the table is empty: a header row is expected", {.file = path});
  t.names = split_csv_line(line);
  while (std::getline(in, line))
    if (!line.empty()) t.rows.push_back(split_csv_line(line));
  return t;
}

}  // namespace tirstrain::report
