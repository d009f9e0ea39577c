#include "signals/channels.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>

#include <H5Cpp.h>

#include "core/csv.hpp"
#include "core/error.hpp"
#include "core/median.hpp"
#include "signals/hdf5_layout.hpp"
#include "signals/isolated_read.hpp"
#include "signals/spectral.hpp"

namespace tirstrain::signals {

namespace {

// The unit a name ends with in brackets, as spreadsheets and DAQ software write it ("Fz [mN]", "t (ms)"),
// with the spelling variants mapped to the suffix names ("µm" -> "um", "m/s^2" -> "m_s2"); nullopt with none.
struct BracketedName {
  std::string stem, unit;
  char open = '[', close = ']';
};
std::optional<BracketedName> bracketed_unit(const std::string& name) {
  const auto last = name.find_last_not_of(' ');
  if (last == std::string::npos || (name[last] != ']' && name[last] != ')')) return std::nullopt;
  BracketedName b;
  b.close = name[last];
  b.open = b.close == ']' ? '[' : '(';
  const auto open = name.rfind(b.open, last);
  if (open == std::string::npos) return std::nullopt;
  b.stem = name.substr(0, open);
  std::string unit = name.substr(open + 1, last - open - 1);
  unit.erase(0, unit.find_first_not_of(' '));
  unit.erase(unit.find_last_not_of(' ') + 1);
  static const std::vector<std::pair<std::string, std::string>> spellings = {
      {"\xC2\xB5m", "um"}, {"\xCE\xBCm", "um"}, {"\xC2\xB5s", "us"},     {"\xCE\xBCs", "us"},
      {"m/s2", "m_s2"},    {"m/s^2", "m_s2"},   {"m/s\xC2\xB2", "m_s2"}, {"m s-2", "m_s2"}};
  for (const auto& [spelled, suffix] : spellings)
    if (unit == spelled) unit = suffix;
  b.unit = unit;
  return b;
}

}  // namespace

double time_column_seconds_per_unit(const std::string& name) {
  if (const auto b = bracketed_unit(name)) {
    if (b->unit == "ms") return 1e-3;
    if (b->unit == "us") return 1e-6;
    if (b->unit == "ns") return 1e-9;
    if (b->unit == "min") return 60.0;
    return 1.0;
  }
  const auto ends_with = [&](const char* tail) {
    const std::string t(tail);
    return name.size() > t.size() && name.compare(name.size() - t.size(), t.size(), t) == 0;
  };
  if (ends_with("_ms")) return 1e-3;
  if (ends_with("_us")) return 1e-6;
  if (ends_with("_ns")) return 1e-9;
  if (ends_with("_min")) return 60.0;
  return 1.0;
}

std::string seconds_column_name(const std::string& name) {
  if (time_column_seconds_per_unit(name) == 1.0) return name;
  if (const auto b = bracketed_unit(name)) return b->stem + b->open + "s" + b->close;
  return name.substr(0, name.rfind('_')) + "_s";
}

std::vector<ColumnUnit> column_units(Quantity quantity) {
  switch (quantity) {
    case Quantity::kForce:
      return {{"N", 1.0}, {"mN", 1e-3}};
    case Quantity::kPosition:
      return {{"m", 1.0}, {"mm", 1e-3}, {"um", 1e-6}};
    case Quantity::kAcceleration:
      return {{"m_s2", 1.0}, {"g", 9.80665}};
  }
  return {};
}

std::string column_unit_list(Quantity quantity) {
  std::string out;
  for (const ColumnUnit& u : column_units(quantity)) out += (out.empty() ? "" : ", ") + std::string(u.name);
  return out;
}

bool names_a_bracketed_unit(const std::string& column) {
  return bracketed_unit(column).has_value();
}

std::optional<ColumnUnit> unit_of_column_name(const std::string& column, Quantity quantity) {
  if (const auto b = bracketed_unit(column)) {
    for (const ColumnUnit& u : column_units(quantity))
      if (b->unit == u.name) return u;
    return std::nullopt;
  }
  std::optional<ColumnUnit> unit;
  for (const ColumnUnit& u : column_units(quantity)) {
    const std::string tail = std::string("_") + u.name;
    const bool ends =
        column.size() > tail.size() && column.compare(column.size() - tail.size(), tail.size(), tail) == 0;
    if (ends && (!unit || std::string(u.name).size() > std::string(unit->name).size())) unit = u;
  }
  return unit;
}

namespace {

// The time column in seconds, whatever unit its name carries.
void time_to_seconds(const std::string& time_column, std::vector<double>& time_s) {
  const double scale = time_column_seconds_per_unit(time_column);
  if (scale != 1.0)
    for (double& t : time_s) t *= scale;
}

std::string lower_extension(const std::string& path) {
  const auto dot = path.find_last_of('.');
  if (dot == std::string::npos) return {};
  std::string ext = path.substr(dot + 1);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

std::string fmt(double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

// The core CSV reader skips blank lines, so the user-visible line of data row i is recovered by
// re-scanning the file; only done when an error is about to be reported.
long csv_line_of_data_row(const std::string& path, std::size_t data_index) {
  std::ifstream in(path);
  std::string line;
  long line_no = 0;
  bool header_seen = false;
  std::size_t data_seen = 0;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    if (!header_seen) {
      header_seen = true;
      continue;
    }
    if (data_seen == data_index) return line_no;
    ++data_seen;
  }
  return static_cast<long>(data_index) + 2;
}

std::string rate_conflict() {
  return "the file has this time column and --rate-Hz (rate_hz) was given too; a recording has one clock: "
         "drop the rate, or name another time column";
}

std::string time_source_of(const ChannelReadOptions& options) {
  if (!options.rate_Hz) return options.time_column + " column";
  return "sample index / " + fmt(*options.rate_Hz) + " Hz (--rate-Hz; the file holds no time column)";
}

void check_unknown_and_required(const ChannelTable& table, const ChannelReadOptions& options) {
  if (!options.expected.empty()) {
    for (const std::string& name : table.names) {
      if (std::find(options.expected.begin(), options.expected.end(), name) == options.expected.end()) {
        std::string list;
        for (const auto& e : options.expected) list += (list.empty() ? "" : ", ") + e;
        throw Error("unknown column (expected only: " + list + ")", {.file = table.path, .column = name});
      }
    }
  }
  for (const std::string& name : options.required) (void)table.column(name);
}

struct ValidationFailure {
  std::size_t index;
  std::string message;
};

std::optional<ValidationFailure> find_time_problem(const std::vector<double>& t, double tolerance,
                                                   double& rate_Hz) {
  const std::size_t n = t.size();
  if (n < 2)
    return ValidationFailure{0,
                             "need at least 2 samples to know the sample rate, found " + std::to_string(n)};
  for (std::size_t i = 0; i < n; ++i) {
    if (!std::isfinite(t[i])) return ValidationFailure{i, "timestamp is not a finite number"};
    if (i == 0) continue;
    if (t[i] == t[i - 1])
      return ValidationFailure{i, "duplicate timestamp " + fmt(t[i]) + " s (same as the previous sample)"};
    if (t[i] < t[i - 1])
      return ValidationFailure{
          i, "timestamps not increasing: " + fmt(t[i]) + " s follows " + fmt(t[i - 1]) + " s"};
  }
  std::vector<double> dt(n - 1);
  for (std::size_t i = 1; i < n; ++i) dt[i - 1] = t[i] - t[i - 1];
  std::vector<double> sorted = dt;
  const double median_dt = upper_median_in_place(sorted);
  for (std::size_t i = 0; i < dt.size(); ++i) {
    if (std::abs(dt[i] - median_dt) > tolerance * median_dt)
      return ValidationFailure{i + 1, "sample rate varies: interval " + fmt(dt[i]) +
                                          " s before this sample differs from the median interval " +
                                          fmt(median_dt) + " s by more than the tolerance of " +
                                          fmt(100.0 * tolerance) + " % (a dropped or repeated sample?)"};
  }
  rate_Hz = 1.0 / median_dt;
  return std::nullopt;
}

}  // namespace

bool ChannelTable::has(const std::string& name) const {
  return std::find(names.begin(), names.end(), name) != names.end();
}

const std::vector<double>& ChannelTable::column(const std::string& name) const {
  for (std::size_t j = 0; j < names.size(); ++j)
    if (names[j] == name) return columns[j];
  std::string present = time_column;
  for (const auto& n : names) present += ", " + n;
  throw Error("no such column (columns present: " + present + ")", {.file = path, .column = name});
}

double validate_time_axis(const std::vector<double>& time_s, double rate_tolerance, const std::string& where,
                          const std::string& column, long first_row) {
  double rate_Hz = 0.0;
  if (auto problem = find_time_problem(time_s, rate_tolerance, rate_Hz)) {
    if (first_row >= 0)
      throw Error(problem->message,
                  {.file = where, .row = first_row + static_cast<long>(problem->index), .column = column});
    throw Error("sample " + std::to_string(problem->index) + " (0-based): " + problem->message,
                {.file = where, .column = column});
  }
  return rate_Hz;
}

ChannelTable read_channels_csv(const std::string& path, const ChannelReadOptions& options) {
  const CsvTable csv = read_numeric_csv(path);
  ChannelTable table;
  table.path = path;
  table.time_column = options.time_column;
  if (!csv.has(options.time_column) && !options.rate_Hz) {
    std::string present;
    for (const auto& n : csv.names) present += (present.empty() ? "" : ", ") + n;
    throw Error("no time column (columns present: " + present +
                    "); name it with --time-column, or give the sample rate with --rate-Hz",
                {.file = path, .column = options.time_column});
  }
  if (csv.has(options.time_column) && options.rate_Hz)
    throw Error(rate_conflict(), {.file = path, .column = options.time_column, .key = "--rate-Hz"});
  for (std::size_t j = 0; j < csv.names.size(); ++j) {
    if (csv.names[j] == options.time_column) {
      table.time_s = csv.columns[j];
      time_to_seconds(options.time_column, table.time_s);
    } else {
      table.names.push_back(csv.names[j]);
      table.columns.push_back(csv.columns[j]);
    }
  }
  if (options.rate_Hz && !table.columns.empty())
    table.time_s = times_from_rate(table.columns.front().size(), *options.rate_Hz, path);
  table.time_source = time_source_of(options);
  check_unknown_and_required(table, options);
  apply_calibration(table, options.calibration);
  double rate_Hz = 0.0;
  if (auto problem = find_time_problem(table.time_s, options.rate_tolerance, rate_Hz)) {
    const long row = table.time_s.size() < 2 ? 1 : csv_line_of_data_row(path, problem->index);
    throw Error(problem->message, {.file = path, .row = row, .column = options.time_column});
  }
  table.sample_rate_Hz = rate_Hz;
  return table;
}

namespace {

// Deflate shrinks data at most about 1032:1, so a dataset claiming more samples than its stored bytes (no
// more than the file's own size) could hold, even compressed, has a damaged header; reading it would
// allocate what the header claims.
std::string implausible_length(const H5::DataSet& ds, std::size_t length, std::size_t element_bytes,
                               std::uintmax_t file_bytes) {
  constexpr double kMaxCompression = 1100.0;
  constexpr double kSlackBytes = 1 << 20;
  const double stored_bytes =
      std::min(static_cast<double>(ds.getStorageSize()), static_cast<double>(file_bytes));
  if (static_cast<double>(length) * static_cast<double>(element_bytes) <=
      kMaxCompression * stored_bytes + kSlackBytes)
    return "";
  return "claims " + std::to_string(length) + " samples but the file holds " +
         std::to_string(static_cast<long long>(stored_bytes)) + " bytes of them (a damaged file?)";
}

// HDF5 1.10 copies a compact dataset's samples out of its header without checking that the header holds as
// many bytes as the shape and type need (in a damaged file it reads through a null pointer), and reads a
// contiguous one from wherever its address points; such a dataset is damaged, not read.
std::string damaged_storage(const H5::DataSet& ds, std::size_t length, std::size_t element_bytes,
                            std::uintmax_t file_bytes) {
  const double needed_bytes = static_cast<double>(length) * static_cast<double>(element_bytes);
  const H5D_layout_t layout = ds.getCreatePlist().getLayout();
  if (layout == H5D_COMPACT && static_cast<double>(ds.getStorageSize()) != needed_bytes)
    return "is damaged: its compact storage holds " + std::to_string(ds.getStorageSize()) +
           " bytes where its shape and type need " + std::to_string(static_cast<long long>(needed_bytes));
  if (layout == H5D_CONTIGUOUS) {
    const haddr_t offset = ds.getOffset();  // undefined when nothing was written: HDF5 reads fill values
    if (offset != HADDR_UNDEF && static_cast<double>(offset) + needed_bytes > static_cast<double>(file_bytes))
      return "is damaged: its samples would lie beyond the end of the file (byte " + std::to_string(offset) +
             " + " + std::to_string(static_cast<long long>(needed_bytes)) + ")";
  }
  return "";
}

// The MATLAB class a v7.3 file gives a dataset ("" for other HDF5 writers).
std::string matlab_class_of(const H5::DataSet& ds) {
  std::string matlab_class;
  if (!ds.attrExists("MATLAB_class")) return matlab_class;
  H5::Attribute attr = ds.openAttribute("MATLAB_class");
  attr.read(attr.getStrType(), matlab_class);
  // Fixed-length HDF5 strings may carry trailing NULs.
  if (const auto nul = matlab_class.find('\0'); nul != std::string::npos) matlab_class.resize(nul);
  return matlab_class;
}

// Why a dataset is not a channel ("" when it is one: numeric, a vector, not empty, plausibly sized);
// `length` receives its number of samples.
std::string why_not_a_channel(const H5::DataSet& ds, std::uintmax_t file_bytes, std::size_t& length) {
  const std::string matlab_class = matlab_class_of(ds);
  const H5T_class_t type_class = ds.getTypeClass();
  // A damaged header can claim elements gigabytes wide, which HDF5 would allocate for the conversion.
  const std::size_t element_bytes = ds.getDataType().getSize();
  const bool numeric =
      (type_class == H5T_INTEGER || type_class == H5T_FLOAT) && element_bytes >= 1 && element_bytes <= 16;
  if (matlab_class == "char") return "is a MATLAB char array (text stored as uint16), not a numeric channel";
  if (matlab_class == "cell" || matlab_class == "struct")
    return "is a MATLAB " + matlab_class + ", not a numeric channel";
  if (ds.attrExists("MATLAB_empty")) return "is an empty MATLAB array";
  if (!numeric) return "is not a numeric dataset";
  H5::DataSpace space = ds.getSpace();
  const int rank = space.getSimpleExtentNdims();
  std::vector<hsize_t> dims(static_cast<std::size_t>(std::max(rank, 0)));
  if (rank > 0) space.getSimpleExtentDims(dims.data());
  length = 1;
  int non_singleton = 0;
  for (hsize_t d : dims) {
    length *= static_cast<std::size_t>(d);
    non_singleton += d != 1;
  }
  if (non_singleton > 1) {
    std::string shape;
    for (hsize_t d : dims) shape += (shape.empty() ? "" : "x") + std::to_string(d);
    return "has shape " + shape + "; a channel must be a vector (one non-singleton dimension)";
  }
  if (length == 0) return "is empty";
  if (const std::string implausible = implausible_length(ds, length, element_bytes, file_bytes);
      !implausible.empty())
    return implausible;
  return damaged_storage(ds, length, element_bytes, file_bytes);
}

// The compression filters a dataset needs that this HDF5 lacks ("needs filter 32000 (LZF), not in this
// HDF5; "), or "".
std::string unavailable_filters(const H5::DataSet& ds) {
  std::string out;
  const H5::DSetCreatPropList plist = ds.getCreatePlist();
  for (int k = 0; k < plist.getNfilters(); ++k) {
    unsigned flags = 0;
    size_t values = 0;
    unsigned config = 0;
    char filter_name[64] = {};
    const H5Z_filter_t id =
        plist.getFilter(k, flags, values, nullptr, sizeof filter_name, filter_name, config);
    if (H5Zfilter_avail(id) <= 0)
      out += "needs filter " + std::to_string(id) +
             (filter_name[0] ? " (" + std::string(filter_name) + ")" : "") + ", not in this HDF5; ";
  }
  return out;
}

std::vector<double> read_finite_samples(const H5::DataSet& ds, std::size_t length, const std::string& path,
                                        const std::string& name) {
  std::vector<double> values(length);
  try {
    ds.read(values.data(), H5::PredType::NATIVE_DOUBLE);
  } catch (const H5::Exception& e) {
    throw Error("cannot be read (" + unavailable_filters(ds) + "HDF5: " + e.getDetailMsg() + ")",
                {.file = path, .column = name});
  }
  for (std::size_t k = 0; k < values.size(); ++k)
    if (!std::isfinite(values[k]))
      throw Error("sample " + std::to_string(k) + " (0-based) is not a finite number",
                  {.file = path, .column = name});
  return values;
}

// Every numeric vector dataset of the group into `table` (the time dataset as its time axis); returns
// whether the time dataset was there. A requested dataset (or any, when the columns are expected ones) that
// is not a channel is an error naming it; others are skipped.
bool read_group_channels(const H5::Group& group, const std::string& path, std::uintmax_t file_bytes,
                         const ChannelReadOptions& options, ChannelTable& table) {
  std::vector<std::string> wanted = options.required;
  wanted.push_back(options.time_column);
  bool have_time = false;
  for (hsize_t i = 0; i < group.getNumObjs(); ++i) {
    const std::string name = group.getObjnameByIdx(i);
    const bool requested = std::find(wanted.begin(), wanted.end(), name) != wanted.end();
    // MATLAB keeps cell/struct payloads in "#refs#" and "#subsystem#"; they are not channels.
    if (!name.empty() && name[0] == '#') continue;
    // Columns asked for by name: the others are not read (one this HDF5 cannot decode stays harmless).
    if (!requested && !options.required.empty() && options.expected.empty()) continue;
    if (group.childObjType(name) != H5O_TYPE_DATASET) {
      if (requested)
        throw Error("is a group, not a numeric dataset (a MATLAB struct?)", {.file = path, .column = name});
      continue;
    }
    const H5::DataSet ds = group.openDataSet(name);
    std::size_t length = 0;
    if (const std::string why_not = why_not_a_channel(ds, file_bytes, length); !why_not.empty()) {
      if (requested || !options.expected.empty()) throw Error(why_not, {.file = path, .column = name});
      continue;
    }
    std::vector<double> values = read_finite_samples(ds, length, path, name);
    if (name == options.time_column) {
      table.time_s = std::move(values);
      time_to_seconds(options.time_column, table.time_s);
      have_time = true;
    } else {
      table.names.push_back(name);
      table.columns.push_back(std::move(values));
    }
  }
  return have_time;
}

// The time axis from --rate-Hz when the file has no time dataset; an error when it has neither or both.
void settle_time_axis(bool have_time, const std::string& path, const ChannelReadOptions& options,
                      ChannelTable& table) {
  if (have_time && options.rate_Hz)
    throw Error(rate_conflict(), {.file = path, .column = options.time_column, .key = "--rate-Hz"});
  if (have_time) return;
  if (options.rate_Hz && !table.columns.empty()) {
    table.time_s = times_from_rate(table.columns.front().size(), *options.rate_Hz, path);
    return;
  }
  std::string present;
  for (const auto& n : table.names) present += (present.empty() ? "" : ", ") + n;
  throw Error("no time dataset in group '" + options.hdf5_group + "' (numeric datasets present: " + present +
                  "); name it with --time-column, or give the sample rate with --rate-Hz",
              {.file = path, .column = options.time_column});
}

// The read itself, once the layout is checked.
ChannelTable read_hdf5_table(const std::string& path, const ChannelReadOptions& options) {
  H5::Exception::dontPrint();
  ChannelTable table;
  table.path = path;
  table.time_column = options.time_column;
  table.first_data_row = -1;
  try {
    H5::H5File file(path, H5F_ACC_RDONLY);
    std::error_code size_error;
    const std::uintmax_t file_bytes = std::filesystem::file_size(path, size_error);
    const bool have_time =
        read_group_channels(file.openGroup(options.hdf5_group), path, file_bytes, options, table);
    settle_time_axis(have_time, path, options, table);
  } catch (const H5::Exception& e) {
    throw Error("cannot read HDF5 file: " + std::string(e.getCDetailMsg()), {.file = path});
  }
  for (std::size_t j = 0; j < table.names.size(); ++j)
    if (table.columns[j].size() != table.time_s.size())
      throw Error("has " + std::to_string(table.columns[j].size()) + " samples but the time dataset '" +
                      options.time_column + "' has " + std::to_string(table.time_s.size()),
                  {.file = path, .column = table.names[j]});
  check_unknown_and_required(table, options);
  table.time_source = time_source_of(options);
  table.sample_rate_Hz =
      validate_time_axis(table.time_s, options.rate_tolerance, path, options.time_column, -1);
  apply_calibration(table, options.calibration);
  return table;
}

}  // namespace

ChannelTable read_channels_hdf5(const std::string& path, const ChannelReadOptions& options) {
  check_hdf5_layout(path);
  if (options.read_in_child_first)
    survive_read_in_child(path, "HDF5", [&] { read_hdf5_table(path, options); });
  return read_hdf5_table(path, options);
}

ChannelTable read_channels(const std::string& path, const ChannelReadOptions& options) {
  const std::string ext = lower_extension(path);
  if (ext == "mat") return read_channels_mat(path, options);
  if (ext == "h5" || ext == "hdf5") return read_channels_hdf5(path, options);
  // Any other name: the first bytes say whether it is a MAT-file or HDF5 under another name, or binary
  // that the CSV reader would only report as a ragged row.
  std::ifstream in(path, std::ios::binary);
  std::string head(4096, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  if (head.rfind("MATLAB ", 0) == 0) return read_channels_mat(path, options);
  if (head.rfind("\x89HDF\r\n\x1a\n", 0) == 0) return read_channels_hdf5(path, options);
  if (head.find('\0') != std::string::npos) {
    std::string shown;
    for (std::size_t k = 0; k < std::min<std::size_t>(head.size(), 8); ++k)
      shown += std::isprint(static_cast<unsigned char>(head[k])) ? head[k] : '.';
    throw Error("is not a channel file read here (binary, starting with '" + shown +
                    "'); channel files are CSV (a header row and a time column), HDF5 (.h5, .hdf5) or MATLAB "
                    ".mat (v4, v5, v7, v7.3)",
                {.file = path});
  }
  return read_channels_csv(path, options);
}

std::vector<double> times_from_rate(std::size_t count, double rate_Hz, const std::string& where) {
  if (!(rate_Hz > 0.0) || !std::isfinite(rate_Hz))
    throw Error("the sample rate must be a positive number of Hz, not " + fmt(rate_Hz),
                {.file = where, .key = "--rate-Hz"});
  std::vector<double> t(count);
  for (std::size_t i = 0; i < count; ++i) t[i] = static_cast<double>(i) / rate_Hz;
  return t;
}

void apply_calibration(ChannelTable& table, const std::map<std::string, ChannelCalibration>& calibration) {
  for (const auto& [name, cal] : calibration) {
    if (!std::isfinite(cal.gain) || !std::isfinite(cal.offset) || cal.gain == 0.0)
      throw Error("calibration gain must be finite and non-zero and offset finite (gain " + fmt(cal.gain) +
                      ", offset " + fmt(cal.offset) + ")",
                  {.file = table.path, .column = name});
    if (!table.has(name)) {
      std::string present;
      for (const auto& n : table.names) present += (present.empty() ? "" : ", ") + n;
      throw Error("a calibration is given for this channel but the file has no such channel (channels: " +
                      present + ")",
                  {.file = table.path, .column = name});
    }
    for (std::size_t j = 0; j < table.names.size(); ++j)
      if (table.names[j] == name)
        for (double& v : table.columns[j]) v = cal.gain * v + cal.offset;
  }
}

std::vector<double> resample_linear(const std::vector<double>& time_s, const std::vector<double>& values,
                                    const std::vector<double>& query_s) {
  if (time_s.size() != values.size() || time_s.size() < 2)
    throw Error("internal: resample_linear needs matching time and value vectors of at least 2 samples");
  std::vector<double> out(query_s.size());
  std::size_t k = 0;
  for (std::size_t q = 0; q < query_s.size(); ++q) {
    const double t = query_s[q];
    if (!(t >= time_s.front() && t <= time_s.back()))
      throw Error("time " + fmt(t) + " s is outside the channel's span [" + fmt(time_s.front()) + ", " +
                      fmt(time_s.back()) + "] s; channels are not extrapolated",
                  {.frame = static_cast<long>(q)});
    // Queries are usually increasing (frame times), so the search restarts from the last bracket.
    if (k >= time_s.size() - 1 || time_s[k] > t) k = 0;
    if (time_s[k + 1] < t)
      k = static_cast<std::size_t>(
              std::upper_bound(time_s.begin() + static_cast<std::ptrdiff_t>(k), time_s.end(), t) -
              time_s.begin()) -
          1;
    if (k >= time_s.size() - 1) k = time_s.size() - 2;
    const double w = (t - time_s[k]) / (time_s[k + 1] - time_s[k]);
    out[q] = values[k] + w * (values[k + 1] - values[k]);
  }
  return out;
}

std::optional<double> first_crossing_s(const std::vector<double>& time_s, const std::vector<double>& values,
                                       double threshold, bool rising, std::size_t start_index) {
  for (std::size_t i = std::max<std::size_t>(start_index, 1); i < values.size(); ++i) {
    const double a = values[i - 1], b = values[i];
    const bool crossed = rising ? (a < threshold && b >= threshold) : (a > threshold && b <= threshold);
    if (crossed) {
      const double w = (threshold - a) / (b - a);
      return time_s[i - 1] + w * (time_s[i] - time_s[i - 1]);
    }
  }
  return std::nullopt;
}

ClockAlignment align_explicit(double offset_s) {
  if (!std::isfinite(offset_s))
    throw Error("clock offset must be a finite number of seconds", {.key = "offset_s"});
  ClockAlignment out;
  out.offset_s = offset_s;
  out.correlation = 1.0;
  out.method = "explicit";
  return out;
}

ClockAlignment align_by_trigger(double trigger_channel_s, double trigger_camera_s) {
  ClockAlignment out;
  out.offset_s = trigger_camera_s - trigger_channel_s;
  out.correlation = 1.0;
  out.method = "trigger";
  out.channel_edge_s = trigger_channel_s;
  out.camera_edge_s = trigger_camera_s;
  return out;
}

ClockAlignment align_by_trigger_channel(const std::vector<double>& time_s, const std::vector<double>& trigger,
                                        double trigger_camera_s, std::optional<double> threshold,
                                        bool rising) {
  if (time_s.size() != trigger.size() || time_s.size() < 2)
    throw Error("internal: trigger time and value vectors differ in length or have fewer than 2 samples");
  const auto [lo, hi] = std::minmax_element(trigger.begin(), trigger.end());
  if (!(*hi > *lo)) throw Error("the trigger channel is constant (" + fmt(*lo) + "): no edge to align on");
  const double level = threshold.value_or(0.5 * (*lo + *hi));
  const auto edge = first_crossing_s(time_s, trigger, level, rising);
  if (!edge)
    throw Error(std::string("the trigger channel never crosses ") + fmt(level) +
                    (rising ? " rising" : " falling") + " (range " + fmt(*lo) + " to " + fmt(*hi) + ")",
                {.key = "threshold"});
  return align_by_trigger(*edge, trigger_camera_s);
}

namespace {

// Pearson correlation of p(t_camera - shift) (channel interpolated) with the camera series; -2 when fewer
// than 4 camera samples overlap the channel or a series is constant there.
double correlation_at(const std::vector<double>& tc, const std::vector<double>& pc,
                      const std::vector<double>& tv, const std::vector<double>& pv, double shift_s,
                      std::size_t* pairs) {
  std::size_t count = 0, k = 0;
  double sp = 0.0, sv = 0.0, spp = 0.0, svv = 0.0, spv = 0.0;
  for (std::size_t q = 0; q < tv.size(); ++q) {
    const double t = tv[q] - shift_s;
    if (t < tc.front() || t > tc.back()) continue;
    while (k + 2 < tc.size() && tc[k + 1] < t) ++k;
    const double w = (t - tc[k]) / (tc[k + 1] - tc[k]);
    const double p = pc[k] + w * (pc[k + 1] - pc[k]);
    sp += p;
    sv += pv[q];
    spp += p * p;
    svv += pv[q] * pv[q];
    spv += p * pv[q];
    ++count;
  }
  if (pairs) *pairs = count;
  if (count < 4) return -2.0;
  const double n = static_cast<double>(count);
  const double cpp = spp - sp * sp / n, cvv = svv - sv * sv / n, cpv = spv - sp * sv / n;
  // Relative guard: sums of squares of a constant series cancel to rounding noise, not exactly 0.
  if (!(cpp > 1e-12 * spp) || !(cvv > 1e-12 * svv)) return -2.0;
  return cpv / std::sqrt(cpp * cvv);
}

}  // namespace

ClockAlignment align_by_cross_correlation(const std::vector<double>& channel_time_s,
                                          const std::vector<double>& channel_position,
                                          const std::vector<double>& camera_time_s,
                                          const std::vector<double>& camera_displacement, double max_lag_s) {
  if (channel_time_s.size() != channel_position.size() || camera_time_s.size() != camera_displacement.size())
    throw Error("internal: time and value vectors differ in length");
  if (channel_time_s.size() < 4 || camera_time_s.size() < 4)
    throw Error("cross-correlation alignment needs at least 4 samples in each series");
  if (!(max_lag_s >= 0.0)) throw Error("maximum lag must be non-negative", {.key = "max_lag_s"});
  // The camera series is walked in order: it must increase (frame times after skipped frames do).
  for (std::size_t q = 1; q < camera_time_s.size(); ++q)
    if (!(camera_time_s[q] > camera_time_s[q - 1]))
      throw Error("camera times must increase (sample " + std::to_string(q) + ")");
  const double dt =
      (channel_time_s.back() - channel_time_s.front()) / static_cast<double>(channel_time_s.size() - 1);
  const long max_lag = static_cast<long>(std::ceil(max_lag_s / dt - 1e-9));
  std::vector<double> corr(static_cast<std::size_t>(2 * max_lag + 1), -2.0);
  const auto shift_of = [&](double index) { return (index - static_cast<double>(max_lag)) * dt; };
  const auto eval = [&](double index) {
    return correlation_at(channel_time_s, channel_position, camera_time_s, camera_displacement,
                          shift_of(index), nullptr);
  };
  for (std::size_t j = 0; j < corr.size(); ++j) corr[j] = eval(static_cast<double>(j));
  const auto best = std::max_element(corr.begin(), corr.end());
  if (*best < -1.5)
    throw Error(
        "cross-correlation alignment failed: fewer than 4 camera samples overlap the channel within the lag "
        "range, or one of the series is constant",
        {.key = "max_lag_s"});
  const std::size_t b = static_cast<std::size_t>(best - corr.begin());
  double index = static_cast<double>(b);
  double value = *best;
  if (b > 0 && b + 1 < corr.size() && corr[b - 1] > -1.5 && corr[b + 1] > -1.5) {
    // Parabola first (exact for a quadratic peak), then golden-section on the continuous correlation.
    const double parabola = std::clamp(parabolic_peak_index(corr, b), index - 1.0, index + 1.0);
    if (const double c = eval(parabola); c > value) {
      value = c;
      index = parabola;
    }
    constexpr double kGolden = 0.6180339887498949;
    double lo = static_cast<double>(b) - 1.0, hi = static_cast<double>(b) + 1.0;
    double x1 = hi - kGolden * (hi - lo), x2 = lo + kGolden * (hi - lo);
    double f1 = eval(x1), f2 = eval(x2);
    for (int it = 0; it < 60 && hi - lo > 1e-7; ++it) {
      if (f1 >= f2) {
        hi = x2;
        x2 = x1;
        f2 = f1;
        x1 = hi - kGolden * (hi - lo);
        f1 = eval(x1);
      } else {
        lo = x1;
        x1 = x2;
        f1 = f2;
        x2 = lo + kGolden * (hi - lo);
        f2 = eval(x2);
      }
    }
    const double golden = 0.5 * (lo + hi);
    if (const double c = eval(golden); c >= value) {
      value = c;
      index = golden;
    }
  }
  ClockAlignment out;
  out.offset_s = shift_of(index);
  correlation_at(channel_time_s, channel_position, camera_time_s, camera_displacement, out.offset_s,
                 &out.samples_compared);
  out.correlation = value;
  out.method = "cross-correlation";
  out.max_lag_s = max_lag_s;
  return out;
}

std::vector<double> oriented_along_motion(std::vector<double> series) {
  double largest = 0.0;
  for (double x : series)
    if (std::abs(x - series.front()) > std::abs(largest)) largest = x - series.front();
  if (largest < 0.0)
    for (double& x : series) x = -x;
  return series;
}

}  // namespace tirstrain::signals
