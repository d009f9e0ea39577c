#include "tirstrain/signals_common.hpp"
#include "tirstrain/value_checks.hpp"

#include "core/atomic_output.hpp"

namespace tirstrain::cli {

const char* const kChannelInputHelp =
    "channel file: CSV with a header row (units in the names) and a time column, HDF5 with one numeric "
    "vector per channel, or MATLAB .mat of any version (v4, v5, v7, v7.3); a channel is a name, a matrix "
    "column NAME[:,k] (1-based) or a struct field a.b.c (docs/formats.md)";

void add_reading_options(CLI::App* sub, Common& c) {
  sub->add_option("--time-column", c.time_column, "name of the time column, seconds")->capture_default_str();
  sub->add_option("--rate-tolerance", c.rate_tolerance,
                  "largest allowed relative deviation of a sample interval from the median interval")
      ->capture_default_str();
  sub->add_option("--group", c.group, "HDF5 group holding the channel datasets")->capture_default_str();
  sub->add_option(
         "--rate-Hz", c.rate_Hz,
         "sample rate, Hz, of a file holding no time column (sample i at i / rate); an error when it has one")
      ->check(kPositive);
}

void add_common(CLI::App* sub, Common& c, const std::string& out_help) {
  sub->add_option("IN", c.input, kChannelInputHelp)->required();
  sub->add_option("--out", c.out, out_help)->required();
  add_reading_options(sub, c);
}

signals::ChannelTable load(const Common& c, const std::string& path, std::vector<std::string> required) {
  signals::ChannelReadOptions options;
  options.time_column = c.time_column;
  options.required = std::move(required);
  options.rate_tolerance = c.rate_tolerance;
  options.hdf5_group = c.group;
  options.rate_Hz = c.rate_Hz;
  return signals::read_channels(path, options);
}

std::optional<double> si_per_unit(const std::string& column, const std::string& given_unit,
                                  signals::Quantity quantity, const std::string& option) {
  if (!given_unit.empty()) {
    for (const signals::ColumnUnit& u : signals::column_units(quantity))
      if (given_unit == u.name) return u.to_si;
    throw Error("unknown unit '" + given_unit + "' (use one of " + signals::column_unit_list(quantity) + ")",
                {.key = option});
  }
  if (const auto unit = signals::unit_of_column_name(column, quantity)) return unit->to_si;
  return std::nullopt;
}

std::vector<double> scaled(std::vector<double> values, double scale) {
  if (scale != 1.0)
    for (double& v : values) v *= scale;
  return values;
}

std::vector<std::string> split_channel_names(const std::vector<std::string>& arguments) {
  std::vector<std::string> names;
  for (const std::string& argument : arguments) {
    int depth = 0;
    std::string name;
    for (const char c : argument) {
      if (c == '[' || c == '(') ++depth;
      if ((c == ']' || c == ')') && depth > 0) --depth;
      if (c == ',' && depth == 0) {
        if (!name.empty()) names.push_back(name);
        name.clear();
      } else {
        name += c;
      }
    }
    if (!name.empty()) names.push_back(name);
  }
  return names;
}

// A force column without a unit in its name is in N (as documented); one that names a unit not known here
// ("Fz [kN]") is refused rather than read as N.
std::vector<double> force_in_N(const signals::ChannelTable& table, const std::string& column) {
  const std::optional<double> N_per_unit = si_per_unit(column, "", signals::Quantity::kForce, "");
  if (!N_per_unit && signals::names_a_bracketed_unit(column))
    throw Error("cannot tell the unit of column '" + column + "' (forces are read in " +
                    signals::column_unit_list(signals::Quantity::kForce) + ")",
                {.file = table.path, .key = column});
  return scaled(table.column(column), N_per_unit.value_or(1.0));
}

CLI::App* add_verb(CLI::App& signals, const std::string& name, const std::string& summary,
                   const std::string& details) {
  CLI::App* sub = signals.add_subcommand(name, summary);
  sub->footer(details);
  return sub;
}

void add_example(CLI::App* sub, const std::string& command) {
  sub->footer(sub->get_footer() + "\nExample:\n  " + command);
}

void write_json(const std::string& path, const nlohmann::json& j) {
  write_text_file(path, j.dump(2) + "\n");
}

}  // namespace tirstrain::cli
