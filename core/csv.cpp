#include "core/csv.hpp"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>

#include "core/error.hpp"

namespace tirstrain {
namespace {

std::vector<std::string> split_line(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  for (char ch : line) {
    if (ch == ',') {
      cells.push_back(cell);
      cell.clear();
    } else if (ch != '\r') {
      cell += ch;
    }
  }
  cells.push_back(cell);
  for (auto& c : cells) {
    const auto first = c.find_first_not_of(" \t\"");
    const auto last = c.find_last_not_of(" \t\"");
    c = first == std::string::npos ? std::string() : c.substr(first, last - first + 1);
  }
  return cells;
}

}  // namespace

bool CsvTable::has(const std::string& name) const {
  for (const auto& n : names)
    if (n == name) return true;
  return false;
}

std::size_t CsvTable::index_of(const std::string& name) const {
  for (std::size_t j = 0; j < names.size(); ++j)
    if (names[j] == name) return j;
  std::string present;
  for (const auto& n : names) present += (present.empty() ? "" : ", ") + n;
  throw Error("no such column (columns present: " + present + ")", {.file = path, .column = name});
}

CsvTable read_numeric_csv(const std::string& path, NaNCells nan_cells) {
  std::ifstream in(path);
  if (!in) throw Error("cannot open file for reading", {.file = path});
  CsvTable table;
  table.path = path;
  std::string line;
  long row = 0;
  while (std::getline(in, line)) {
    ++row;
    if (!line.empty() && line.find_first_not_of(" \t\r") != std::string::npos) break;
  }
  if (row == 0 || line.find_first_not_of(" \t\r") == std::string::npos)
    throw Error("file is empty: expected a header row of column names", {.file = path});
  table.names = split_line(line);
  for (std::size_t j = 0; j < table.names.size(); ++j) {
    if (table.names[j].empty())
      throw Error("empty column name in header (column " + std::to_string(j + 1) + ")",
                  {.file = path, .row = row});
    for (std::size_t k = 0; k < j; ++k)
      if (table.names[k] == table.names[j])
        throw Error("duplicate column name in header", {.file = path, .row = row, .column = table.names[j]});
  }
  table.columns.assign(table.names.size(), {});
  while (std::getline(in, line)) {
    ++row;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    const auto cells = split_line(line);
    if (cells.size() != table.names.size())
      throw Error(
          "expected " + std::to_string(table.names.size()) + " cells, found " + std::to_string(cells.size()),
          {.file = path, .row = row});
    for (std::size_t j = 0; j < cells.size(); ++j) {
      const std::string& cell = cells[j];
      if (cell.empty()) throw Error("empty cell", {.file = path, .row = row, .column = table.names[j]});
      double value = 0.0;
      const char* begin = cell.data();
      const char* end = cell.data() + cell.size();
      if (*begin == '+') ++begin;
      const auto result = std::from_chars(begin, end, value);
      if (result.ec != std::errc() || result.ptr != end)
        throw Error("not a number: '" + cell + "'", {.file = path, .row = row, .column = table.names[j]});
      const bool not_measured = std::isnan(value) && nan_cells == NaNCells::kNotMeasured;
      if (!std::isfinite(value) && !not_measured)
        throw Error("non-finite value '" + cell + "'", {.file = path, .row = row, .column = table.names[j]});
      table.columns[j].push_back(value);
    }
  }
  return table;
}

std::string format_double(double value) {
  char buffer[32];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

CsvWriter::CsvWriter(const std::string& path, const std::vector<std::string>& names)
    : path_(path), width_(names.size()), out_(path) {
  for (std::size_t j = 0; j < names.size(); ++j) line_ += (j ? "," : "") + names[j];
  line_ += '\n';
  out_.append(line_);
}

void CsvWriter::row(const std::vector<double>& values) {
  if (values.size() != width_) throw Error("internal: CSV row width mismatch", {.file = path_});
  line_.clear();
  for (std::size_t j = 0; j < values.size(); ++j) {
    if (j) line_ += ',';
    line_ += format_double(values[j]);
  }
  line_ += '\n';
  out_.append(line_);
}

void CsvWriter::row_text(const std::vector<std::string>& cells) {
  if (cells.size() != width_) throw Error("internal: CSV row width mismatch", {.file = path_});
  line_.clear();
  for (std::size_t j = 0; j < cells.size(); ++j) {
    if (j) line_ += ',';
    line_ += cells[j];
  }
  line_ += '\n';
  out_.append(line_);
}

void CsvWriter::commit() {
  out_.commit();
}

}  // namespace tirstrain
