// Channels in MATLAB .mat files of every version (v4, v5, v7 compressed, v7.3) through libmatio. A v7.3
// file (HDF5 inside) that this matio cannot open is handed to the HDF5 reader.
#include <matio.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>

#include "core/csv.hpp"
#include "core/error.hpp"
#include "signals/channels.hpp"
#include "signals/hdf5_layout.hpp"
#include "signals/isolated_read.hpp"

namespace tirstrain::signals {
namespace {

struct MatCloser {
  void operator()(mat_t* mat) const { Mat_Close(mat); }
};
struct VarFreer {
  void operator()(matvar_t* var) const { Mat_VarFree(var); }
};
using MatHandle = std::unique_ptr<mat_t, MatCloser>;
using VarHandle = std::unique_ptr<matvar_t, VarFreer>;

// A channel's place in the file: `a.b.c` with an optional 1-based column `[:,k]` or row `[k,:]`.
struct Selector {
  std::string text;               // as the user wrote it, for messages
  std::vector<std::string> path;  // variable, then struct fields
  std::size_t column = 0;         // 1-based; 0 = none
  std::size_t row = 0;            // 1-based; 0 = none
};

Selector parse_selector(const std::string& text, const std::string& file) {
  Selector s;
  s.text = text;
  std::string names = text;
  const auto open = text.find_first_of("[(");
  if (open != std::string::npos) {
    names = text.substr(0, open);
    const char close = text[open] == '[' ? ']' : ')';
    const std::string inside = text.substr(open + 1, text.size() - open - 1);
    const auto comma = inside.find(',');
    const bool closed = !inside.empty() && inside.back() == close;
    std::string first = comma == std::string::npos ? "" : inside.substr(0, comma);
    std::string second =
        comma == std::string::npos || !closed ? "" : inside.substr(comma + 1, inside.size() - comma - 2);
    const auto strip = [](std::string& t) { t.erase(std::remove(t.begin(), t.end(), ' '), t.end()); };
    strip(first);
    strip(second);
    const auto index = [](const std::string& t) -> std::size_t {
      if (t.empty() || t.size() > 9 ||
          !std::all_of(t.begin(), t.end(), [](unsigned char c) { return std::isdigit(c); }))
        return 0;
      return std::stoul(t);
    };
    if (first == ":") s.column = index(second);
    if (second == ":") s.row = index(first);
    if (!closed || (s.column == 0 && s.row == 0))
      throw Error("cannot read '" + text + "' as NAME[:,k] (column k) or NAME[k,:] (row k), k from 1",
                  {.file = file, .column = text});
  }
  std::size_t start = 0;
  for (;;) {
    const auto dot = names.find('.', start);
    s.path.push_back(names.substr(start, dot - start));
    if (dot == std::string::npos) break;
    start = dot + 1;
  }
  for (const std::string& part : s.path)
    if (part.empty()) throw Error("has an empty name between dots", {.file = file, .column = text});
  return s;
}

std::string shape_of(const matvar_t* v) {
  std::string shape;
  for (int d = 0; d < v->rank; ++d) shape += (d ? "x" : "") + std::to_string(v->dims[d]);
  return shape;
}

std::string class_name(const matvar_t* v) {
  switch (v->class_type) {
    case MAT_C_CHAR:
      return "char array (text)";
    case MAT_C_CELL:
      return "cell array";
    case MAT_C_STRUCT:
      return "struct";
    case MAT_C_SPARSE:
      return "sparse matrix";
    case MAT_C_FUNCTION:
      return "function handle";
    case MAT_C_OBJECT:
    case MAT_C_OPAQUE:
      return "object";
    default:
      return "numeric array";
  }
}

bool is_numeric(const matvar_t* v) {
  switch (v->class_type) {
    case MAT_C_DOUBLE:
    case MAT_C_SINGLE:
    case MAT_C_INT8:
    case MAT_C_UINT8:
    case MAT_C_INT16:
    case MAT_C_UINT16:
    case MAT_C_INT32:
    case MAT_C_UINT32:
    case MAT_C_INT64:
    case MAT_C_UINT64:
      return true;
    default:
      return false;
  }
}

template <typename T>
double element(const void* data, std::size_t k) {
  T value;
  std::memcpy(&value, static_cast<const char*>(data) + k * sizeof(T), sizeof(T));
  return static_cast<double>(value);
}

// Element k (column-major) of a numeric variable, as double.
double value_at(const matvar_t* v, std::size_t k) {
  switch (v->class_type) {
    case MAT_C_DOUBLE:
      return element<double>(v->data, k);
    case MAT_C_SINGLE:
      return element<float>(v->data, k);
    case MAT_C_INT8:
      return element<std::int8_t>(v->data, k);
    case MAT_C_UINT8:
      return element<std::uint8_t>(v->data, k);
    case MAT_C_INT16:
      return element<std::int16_t>(v->data, k);
    case MAT_C_UINT16:
      return element<std::uint16_t>(v->data, k);
    case MAT_C_INT32:
      return element<std::int32_t>(v->data, k);
    case MAT_C_UINT32:
      return element<std::uint32_t>(v->data, k);
    case MAT_C_INT64:
      return element<std::int64_t>(v->data, k);
    case MAT_C_UINT64:
      return element<std::uint64_t>(v->data, k);
    default:
      return std::nan("");
  }
}

class MatFile {
 public:
  MatFile(std::string path, MatHandle mat) : path_(std::move(path)), mat_(std::move(mat)) {
    for (;;) {
      VarHandle info(Mat_VarReadNextInfo(mat_.get()));
      if (!info) break;
      if (info->name) variables_.emplace_back(info->name);
    }
  }

  const std::vector<std::string>& variables() const { return variables_; }
  bool has(const std::string& name) const {
    return std::find(variables_.begin(), variables_.end(), name) != variables_.end();
  }

  // The values a selector names, checked to be one finite numeric vector.
  std::vector<double> read(const Selector& s) {
    const matvar_t* v = resolve(s);
    if (!is_numeric(v) || v->isComplex)
      throw Error("is a " + std::string(v->isComplex ? "complex array" : class_name(v)) +
                      "; a channel must be a real numeric vector or a matrix column",
                  {.file = path_, .column = s.text});
    if (v->rank != 2 && (s.column || s.row))
      throw Error("has shape " + shape_of(v) + "; a column or row is taken from a 2-D matrix",
                  {.file = path_, .column = s.text});
    if (v->data == nullptr) throw Error("holds no data (an empty array)", {.file = path_, .column = s.text});
    return s.column || s.row ? slice(v, s) : whole_vector(v, s);
  }

  // Whether a top-level variable is one real numeric vector with data (what a file's channels are when none
  // are named); its values are not looked at.
  bool holds_numeric_vector(const Selector& s) {
    const matvar_t* v = resolve(s);
    if (!is_numeric(v) || v->isComplex || v->data == nullptr) return false;
    int non_singleton = 0;
    for (int d = 0; d < v->rank; ++d) non_singleton += v->dims[d] != 1;
    return non_singleton <= 1;
  }

  // Columns of a matrix variable (for mat_column_names): its column count.
  std::size_t columns_of(const Selector& s) {
    const matvar_t* v = resolve(s);
    if (!is_numeric(v) || v->rank != 2)
      throw Error("is a " + class_name(v) + " of shape " + shape_of(v) + "; column names need a 2-D matrix",
                  {.file = path_, .column = s.text});
    return v->dims[1];
  }

 private:
  const matvar_t* resolve(const Selector& s) {
    const std::string& top = s.path.front();
    if (!has(top)) {
      std::string list;
      for (const auto& n : variables_) list += (list.empty() ? "" : ", ") + n;
      throw Error("no variable '" + top + "' in the file (variables: " + (list.empty() ? "none" : list) + ")",
                  {.file = path_, .column = s.text});
    }
    auto it = loaded_.find(top);
    if (it == loaded_.end()) {
      VarHandle var(Mat_VarRead(mat_.get(), top.c_str()));
      if (!var)
        throw Error("cannot read variable '" + top + "' (damaged file?)", {.file = path_, .column = s.text});
      it = loaded_.emplace(top, std::move(var)).first;
    }
    const matvar_t* v = it->second.get();
    std::string walked = top;
    for (std::size_t k = 1; k < s.path.size(); ++k) {
      if (v->class_type != MAT_C_STRUCT)
        throw Error(
            "'" + walked + "' is a " + class_name(v) + ", not a struct with a field '" + s.path[k] + "'",
            {.file = path_, .column = s.text});
      std::size_t elements = 1;
      for (int d = 0; d < v->rank; ++d) elements *= v->dims[d];
      if (elements != 1)
        throw Error(
            "'" + walked + "' is a " + shape_of(v) + " struct array; fields are read from a 1x1 struct",
            {.file = path_, .column = s.text});
      const matvar_t* field = Mat_VarGetStructFieldByName(const_cast<matvar_t*>(v), s.path[k].c_str(), 0);
      if (!field) {
        std::string fields;
        const unsigned n = Mat_VarGetNumberOfFields(const_cast<matvar_t*>(v));
        char* const* names = Mat_VarGetStructFieldnames(v);
        for (unsigned f = 0; f < n && names; ++f)
          fields += (fields.empty() ? "" : ", ") + std::string(names[f]);
        throw Error("struct '" + walked + "' has no field '" + s.path[k] + "' (fields: " + fields + ")",
                    {.file = path_, .column = s.text});
      }
      v = field;
      walked += "." + s.path[k];
    }
    return v;
  }

  std::vector<double> whole_vector(const matvar_t* v, const Selector& s) const {
    std::size_t length = 1;
    int non_singleton = 0;
    for (int d = 0; d < v->rank; ++d) {
      length *= v->dims[d];
      non_singleton += v->dims[d] != 1;
    }
    if (non_singleton > 1) {
      const std::string hint = v->rank == 2 ? " (k = 1.." + std::to_string(v->dims[1]) + ")" : "";
      throw Error("is a " + shape_of(v) + " matrix; name one column as " + s.text + "[:,k]" + hint +
                      ", or give the matrix's column names in the channel config",
                  {.file = path_, .column = s.text});
    }
    std::vector<double> out(length);
    for (std::size_t k = 0; k < length; ++k) out[k] = checked(v, k, k, s);
    return out;
  }

  std::vector<double> slice(const matvar_t* v, const Selector& s) const {
    const std::size_t rows = v->dims[0], cols = v->dims[1];
    if (s.column > cols || s.row > rows)
      throw Error(
          "asks for " +
              std::string(s.column ? "column " + std::to_string(s.column) : "row " + std::to_string(s.row)) +
              " but the matrix is " + shape_of(v) + " (indices start at 1)",
          {.file = path_, .column = s.text});
    std::vector<double> out(s.column ? rows : cols);
    for (std::size_t i = 0; i < out.size(); ++i) {
      const std::size_t k = s.column ? (s.column - 1) * rows + i : i * rows + (s.row - 1);
      out[i] = checked(v, k, i, s);
    }
    return out;
  }

  double checked(const matvar_t* v, std::size_t k, std::size_t sample, const Selector& s) const {
    const double value = value_at(v, k);
    if (!std::isfinite(value))
      throw Error("sample " + std::to_string(sample) + " (0-based) is not a finite number",
                  {.file = path_, .column = s.text});
    return value;
  }

  std::string path_;
  MatHandle mat_;
  std::vector<std::string> variables_;
  std::map<std::string, VarHandle> loaded_;
};

// What the first bytes say, so that matio only ever sees what looks like a MAT-file (its version 4 reader
// would otherwise take arbitrary bytes for a matrix header).
enum class MatHeader { kText, kVersion4, kHdf5, kUnknown };

MatHeader sniff_mat_header(const std::string& path, std::string& first_bytes) {
  constexpr unsigned char kSignature[8] = {0x89, 'H', 'D', 'F', '\r', '\n', 0x1a, '\n'};
  std::ifstream in(path, std::ios::binary);
  unsigned char head[520] = {};
  in.read(reinterpret_cast<char*>(head), sizeof head);
  const auto n = static_cast<std::size_t>(in.gcount());
  for (std::size_t k = 0; k < std::min<std::size_t>(n, 12); ++k)
    first_bytes += std::isprint(head[k]) ? static_cast<char>(head[k]) : '.';
  const bool hdf5 = (n >= 8 && std::memcmp(head, kSignature, 8) == 0) ||
                    (n >= 520 && std::memcmp(head + 512, kSignature, 8) == 0);
  if (n >= 7 && std::memcmp(head, "MATLAB ", 7) == 0) return MatHeader::kText;
  if (hdf5) return MatHeader::kHdf5;
  // Version 4: int32 type MOPT (M 0 or 1 = byte order, O 0, P 0..5 precision, T 0..2), rows, columns,
  // imaginary flag 0/1, name length (with its NUL) 2..64; read in both byte orders.
  if (n < 22) return MatHeader::kUnknown;
  for (const bool little : {true, false}) {
    const auto word = [&](std::size_t k) {
      const unsigned char* b = head + 4 * k;
      return little ? static_cast<std::uint32_t>(b[0] | b[1] << 8 | b[2] << 16 |
                                                 static_cast<std::uint32_t>(b[3]) << 24)
                    : static_cast<std::uint32_t>(b[3] | b[2] << 8 | b[1] << 16 |
                                                 static_cast<std::uint32_t>(b[0]) << 24);
    };
    const std::uint32_t type = word(0), imag = word(3), name_bytes = word(4);
    const bool type_ok = type < 2000 && (type / 100) % 10 == 0 && (type / 10) % 10 <= 5 && type % 10 <= 2;
    if (type_ok && imag <= 1 && name_bytes >= 2 && name_bytes <= 64 && n >= 20 + name_bytes &&
        head[20 + name_bytes - 1] == '\0' && std::isalpha(head[20]))
      return MatHeader::kVersion4;
  }
  return MatHeader::kUnknown;
}

// Channel name -> selector: the required names (a name is its own selector), then every named matrix
// column; with neither, every top-level numeric vector.
std::vector<std::pair<std::string, Selector>> wanted_channels(MatFile& file, const std::string& path,
                                                              const ChannelReadOptions& options) {
  std::vector<std::pair<std::string, Selector>> wanted;
  for (const auto& [matrix, names] : options.mat_column_names) {
    Selector whole = parse_selector(matrix, path);
    const std::size_t columns = file.columns_of(whole);
    if (names.size() != columns)
      throw Error("has " + std::to_string(columns) + " columns but " + std::to_string(names.size()) +
                      " column names are given",
                  {.file = path, .column = matrix});
    for (std::size_t k = 0; k < names.size(); ++k) {
      Selector s = whole;
      s.column = k + 1;
      s.text = matrix + "[:," + std::to_string(k + 1) + "]";
      wanted.emplace_back(names[k], s);
    }
  }
  const auto listed = [&](const std::string& name) {
    return std::any_of(wanted.begin(), wanted.end(), [&](const auto& w) { return w.first == name; });
  };
  for (const std::string& name : options.required)
    if (!listed(name)) wanted.emplace_back(name, parse_selector(name, path));
  if (!wanted.empty()) return wanted;
  // Every numeric vector, as the HDF5 reader takes them; other variables (matrices, structs, text) are
  // skipped unless the channel config lists what the file must hold. A vector's samples must be finite.
  std::vector<std::string> skipped;
  for (const std::string& name : file.variables()) {
    if (name == options.time_column) continue;
    Selector s = parse_selector(name, path);
    if (file.holds_numeric_vector(s)) {
      file.read(s);
      wanted.emplace_back(name, s);
    } else if (!options.expected.empty()) {
      file.read(s);  // throws what the variable is instead
    } else {
      skipped.push_back(name);
    }
  }
  if (wanted.empty()) {
    std::string list;
    for (const auto& n : skipped) list += (list.empty() ? "" : ", ") + n;
    throw Error("holds no numeric vector besides the time axis (" +
                    (list.empty() ? "no other variable" : list) +
                    "): name a matrix column as NAME[:,k] or a struct field as NAME.FIELD",
                {.file = path});
  }
  return wanted;
}

// The file opened and read by libmatio, once a v7.3 file's HDF5 layout is checked.
ChannelTable read_mat_table(const std::string& path, const ChannelReadOptions& options, bool hdf5_inside) {
  MatHandle mat(Mat_Open(path.c_str(), MAT_ACC_RDONLY));
  if (!mat) {
    // A v7.3 file this matio cannot open (built without HDF5) is HDF5 inside.
    if (hdf5_inside) return read_channels_hdf5(path, options);
    throw Error("libmatio cannot open it as a MAT-file (damaged?); MATLAB v4, v5, v7 and v7.3 files are read",
                {.file = path});
  }
  MatFile file(path, std::move(mat));
  ChannelTable table;
  table.path = path;
  table.time_column = options.time_column;
  table.first_data_row = -1;
  for (auto& [name, selector] : wanted_channels(file, path, options)) {
    table.names.push_back(name);
    table.columns.push_back(file.read(selector));
  }
  const Selector time = parse_selector(options.time_column, path);
  const bool have_time = file.has(time.path.front());
  if (have_time && options.rate_Hz)
    throw Error(
        "the file has a time variable and --rate-Hz (rate_hz) was given too; a recording has one "
        "clock: drop the rate, or name another time variable",
        {.file = path, .column = options.time_column, .key = "--rate-Hz"});
  if (have_time) {
    table.time_s = file.read(time);
    for (double& t : table.time_s) t *= time_column_seconds_per_unit(options.time_column);
    table.time_source = options.time_column + " variable";
  } else if (options.rate_Hz) {
    table.time_s =
        times_from_rate(table.columns.empty() ? 0 : table.columns.front().size(), *options.rate_Hz, path);
    table.time_source =
        "sample index / " + format_double(*options.rate_Hz) + " Hz (--rate-Hz; no time variable)";
  } else {
    std::string list;
    for (const auto& n : file.variables()) list += (list.empty() ? "" : ", ") + n;
    throw Error(
        "no time variable '" + options.time_column + "' (variables: " + list +
            "); name it with --time-column, or give the sample rate with --rate-Hz (rate_hz in a channel "
            "config)",
        {.file = path, .column = options.time_column});
  }
  for (std::size_t j = 0; j < table.names.size(); ++j)
    if (table.columns[j].size() != table.time_s.size())
      throw Error("has " + std::to_string(table.columns[j].size()) + " samples but the time axis has " +
                      std::to_string(table.time_s.size()),
                  {.file = path, .column = table.names[j]});
  if (!options.expected.empty())
    for (const std::string& name : table.names)
      if (std::find(options.expected.begin(), options.expected.end(), name) == options.expected.end())
        throw Error("unknown channel (not in the expected list)", {.file = path, .column = name});
  table.sample_rate_Hz =
      validate_time_axis(table.time_s, options.rate_tolerance, path, options.time_column, -1);
  apply_calibration(table, options.calibration);
  return table;
}

}  // namespace

ChannelTable read_channels_mat(const std::string& path, const ChannelReadOptions& options) {
  if (!std::ifstream(path)) throw Error("cannot open the file", {.file = path});
  std::string first_bytes;
  const MatHeader header = sniff_mat_header(path, first_bytes);
  // HDF5 without MATLAB's text header (h5py, or a v7.3 layout written by other tools): the HDF5 reader.
  if (header == MatHeader::kHdf5) return read_channels_hdf5(path, options);
  if (header == MatHeader::kUnknown)
    throw Error("is not a MATLAB .mat file (it starts with '" + first_bytes +
                    "': neither MATLAB's text header nor a version 4 matrix header); MATLAB v4, v5, v7 and "
                    "v7.3 files are read",
                {.file = path});
  // libmatio reads a v7.3 file through HDF5, which crashes on some damaged ones.
  const bool hdf5_inside = first_bytes.rfind("MATLAB 7.3", 0) == 0;
  if (hdf5_inside) {
    check_hdf5_layout(path);
    if (options.read_in_child_first)
      survive_read_in_child(path, "libmatio (HDF5)", [&] { read_mat_table(path, options, hdf5_inside); });
  }
  return read_mat_table(path, options, hdf5_inside);
}

}  // namespace tirstrain::signals
