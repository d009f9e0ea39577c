#include "core/csv.hpp"

#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "core/error.hpp"

namespace tirstrain {

std::vector<std::string> split_csv_line(const std::string& line) {
  std::vector<std::string> cells;
  std::string cell;
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char ch = line[i];
    if (ch == '"') {
      if (quoted && i + 1 < line.size() && line[i + 1] == '"') {
        cell += '"';
        ++i;
      } else {
        quoted = !quoted;
      }
    } else if (ch == ',' && !quoted) {
      cells.push_back(cell);
      cell.clear();
    } else if (ch != '\r') {
      cell += ch;
    }
  }
  cells.push_back(cell);
  for (auto& c : cells) {
    const auto first = c.find_first_not_of(" \t");
    const auto last = c.find_last_not_of(" \t");
    c = first == std::string::npos ? std::string() : c.substr(first, last - first + 1);
  }
  return cells;
}

std::string csv_cell(const std::string& text) {
  if (text.find_first_of(",\"\n\r") == std::string::npos) return text;
  std::string out = "\"";
  for (const char ch : text) out += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return out + "\"";
}

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

namespace {

// A header the reader would misread, said as what it is: a byte-order mark (spreadsheets' "CSV UTF-8",
// invisible in the names) is dropped; other separators than commas, and lines ended by CR alone, are refused.
void check_header_line(std::string& line, const std::string& path, long row) {
  if (row == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);
  const auto cr = line.find('\r');
  if (cr != std::string::npos && line.find_first_not_of(" \t\r", cr) != std::string::npos)
    throw Error(
        "lines end with a carriage return alone (old Mac text): save the file with LF or CRLF line ends",
        {.file = path, .row = row});
  if (line.find(',') == std::string::npos)
    for (const char separator : {';', '\t'})
      if (line.find(separator) != std::string::npos)
        throw Error(std::string("the header is separated by ") + (separator == ';' ? "';'" : "tabs") +
                        ": columns are separated by commas (and the decimal mark is '.')",
                    {.file = path, .row = row});
}

// A number beyond a double's range: one too small to tell from 0 is 0 (as any reader rounds it); one too
// large is an error.
double out_of_range_value(const std::string& cell, const ErrorContext& where) {
  const double value = std::strtod(cell.c_str(), nullptr);
  if (!std::isfinite(value)) throw Error("'" + cell + "' is beyond the range of a double", where);
  return value;
}

}  // namespace

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
  check_header_line(line, path, row);
  table.names = split_csv_line(line);
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
    const auto cells = split_csv_line(line);
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
      if (result.ec == std::errc::result_out_of_range && result.ptr == end)
        value = out_of_range_value(cell, {.file = path, .row = row, .column = table.names[j]});
      else if (result.ec != std::errc() || result.ptr != end)
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
  for (std::size_t j = 0; j < names.size(); ++j) line_ += (j ? "," : "") + csv_cell(names[j]);
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
    line_ += csv_cell(cells[j]);
  }
  line_ += '\n';
  out_.append(line_);
}

void CsvWriter::commit() {
  out_.commit();
}

}  // namespace tirstrain
