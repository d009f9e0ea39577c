#pragma once
// What every `tirstrain signals` verb shares: the input options, reading a channel file, errors named with
// the file and the option the user typed, and writing JSON through a temporary name.
#include <CLI/CLI.hpp>

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "core/error.hpp"
#include "signals/channels.hpp"

namespace tirstrain::cli {

extern const char* const kChannelInputHelp;

// Options of one channel-file input and one output.
struct Common {
  std::string input;                // channel file
  std::string out;                  // output file
  std::string time_column = "t_s";  // index column: time in s (or a distance for spatial series)
  double rate_tolerance = 0.01;     // largest relative deviation of a sample interval from the median
  std::string group = "/";          // HDF5 group holding the channel datasets
  std::optional<double> rate_Hz;    // of a file without a time column, Hz; unset: the time column is read
};

// IN, --out and the reading options.
void add_common(CLI::App* sub, Common& c, const std::string& out_help);
// The reading options without IN and --out (verbs taking several inputs).
void add_reading_options(CLI::App* sub, Common& c);

signals::ChannelTable load(const Common& c, const std::string& path, std::vector<std::string> required);

// Library errors know the parameter but not the file or option the user typed; add them.
template <typename Fn>
auto in_context(const std::string& file, const std::string& column, Fn fn) -> decltype(fn()) {
  return with_error_context(fn, [&](ErrorContext& ctx) {
    ctx.file = file;
    if (ctx.column.empty()) ctx.column = column;
    if (!ctx.key.empty() && ctx.key.rfind("--", 0) != 0) {
      std::string key = ctx.key;
      for (char& ch : key)
        if (ch == '_') ch = '-';
      ctx.key = "--" + key;
    }
  });
}

// SI units per unit of a channel: the unit given by an option (`given_unit`, named `option` in errors),
// else the one the column's name ends with ("_mm"); nullopt when neither says.
std::optional<double> si_per_unit(const std::string& column, const std::string& given_unit,
                                  signals::Quantity quantity, const std::string& option);
// `values` times `scale`.
std::vector<double> scaled(std::vector<double> values, double scale);
// A force column in N: mN when its name says so (a name without a unit is read as N; one naming another
// unit is an error).
std::vector<double> force_in_N(const signals::ChannelTable& table, const std::string& column);
// Channel names given as NAME,NAME,... (or as several arguments), split at the commas that are not inside
// a selector's brackets or a unit's: "dataQ[:,2],Fz [mN]" is two names.
std::vector<std::string> split_channel_names(const std::vector<std::string>& arguments);

// One-line description for `tirstrain signals --help`; the full contract goes into the verb's own --help.
CLI::App* add_verb(CLI::App& signals, const std::string& name, const std::string& summary,
                   const std::string& details);

// Ends a verb's --help with a command a user can start from ("tirstrain signals VERB ..." in full).
void add_example(CLI::App* sub, const std::string& command);

void write_json(const std::string& path, const nlohmann::json& j);

}  // namespace tirstrain::cli
