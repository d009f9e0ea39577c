#pragma once
// Numeric CSV tables with a header row of names (units in the name, e.g. "tangential_N").
// Reading reports the exact file, row and column of anything wrong; writing goes to a temporary name and is
// renamed on commit().
#include <cstddef>
#include <string>
#include <vector>

#include "core/atomic_output.hpp"

namespace tirstrain {

struct CsvTable {
  std::string path;
  std::vector<std::string> names;            // header, in file order
  std::vector<std::vector<double>> columns;  // columns[j][i] = value of column j in data row i

  std::size_t rows() const { return columns.empty() ? 0 : columns.front().size(); }
  bool has(const std::string& name) const;
  // Throws Error naming the file and the missing column (and listing the ones present).
  std::size_t index_of(const std::string& name) const;
  const std::vector<double>& column(const std::string& name) const { return columns[index_of(name)]; }
};

// What a "nan" cell is: an error (an input's cells must all be numbers), or a value its writer did not have
// (the per-frame tables `process` writes mark so a value not measured in that frame).
enum class NaNCells { kError, kNotMeasured };

// Reads a CSV whose first row is a header and whose cells are all numbers. Empty cells, "nan" (unless
// `nan_cells` allows it), infinities, text and ragged rows are errors naming file, row (1-based, header =
// row 1) and column.
CsvTable read_numeric_csv(const std::string& path, NaNCells nan_cells = NaNCells::kError);

// Writes a CSV with full double precision (round-trips exactly) to "<path>.partial" and renames it to
// <path> on commit(); destroyed uncommitted, it removes the partial file.
class CsvWriter {
 public:
  CsvWriter(const std::string& path, const std::vector<std::string>& names);
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;

  void row(const std::vector<double>& values);
  // For mixed rows (e.g. integer ids next to doubles) the caller formats the cells.
  void row_text(const std::vector<std::string>& cells);
  void commit();

 private:
  std::string path_;
  std::size_t width_;
  AtomicFile out_;
  std::string line_;  // the row being formatted
};

// Shortest text that reads back to the same double ("%.17g" trimmed).
std::string format_double(double value);

// One CSV line's cells: split at commas outside double quotes ("a,b" is one cell, "" inside quotes is a
// quote), each cell trimmed of surrounding blanks and quotes, a trailing CR dropped.
std::vector<std::string> split_csv_line(const std::string& line);
// `text` as a CSV cell: quoted (inner quotes doubled) when it holds a comma, a quote or a line break.
std::string csv_cell(const std::string& text);

}  // namespace tirstrain
