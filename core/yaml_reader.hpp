#pragma once
// Strict reading of YAML configuration (scene files): every key is typed and range-checked, and keys that
// nobody read are reported, so a typo never silently falls back to a default. Errors name the file and the
// full key path (e.g. "tissue.E_Pa").
#include <yaml-cpp/yaml.h>

#include <limits>
#include <optional>
#include <set>
#include <string>
#include <vector>

namespace tirstrain {

class YamlSection {
 public:
  // `node` must be a map (or null, treated as empty). `prefix` is the key path of this section ("" at top).
  YamlSection(YAML::Node node, std::string file, std::string prefix = "");

  bool has(const std::string& key) const;

  double number(const std::string& key, double fallback,
                double min = -std::numeric_limits<double>::infinity(),
                double max = std::numeric_limits<double>::infinity());
  double required_number(const std::string& key, double min = -std::numeric_limits<double>::infinity(),
                         double max = std::numeric_limits<double>::infinity());
  long integer(const std::string& key, long fallback, long min = std::numeric_limits<long>::min(),
               long max = std::numeric_limits<long>::max());
  bool boolean(const std::string& key, bool fallback);
  std::string text(const std::string& key, const std::string& fallback);
  std::string required_text(const std::string& key);
  // A text value restricted to a set of choices.
  std::string choice(const std::string& key, const std::string& fallback,
                     const std::vector<std::string>& choices);
  std::vector<double> numbers(const std::string& key, const std::vector<double>& fallback);
  // A nested map; absent gives an empty section.
  YamlSection section(const std::string& key);
  // The raw node, marked as read (for sections another module parses).
  YAML::Node raw(const std::string& key);

  // Throws Error naming the first key present in the file but never read.
  void finish() const;

  std::string path_of(const std::string& key) const { return prefix_.empty() ? key : prefix_ + "." + key; }
  const std::string& file() const { return file_; }

 private:
  [[noreturn]] void fail(const std::string& key, const std::string& message) const;
  std::optional<YAML::Node> get(const std::string& key);

  YAML::Node node_;
  std::string file_;
  std::string prefix_;
  std::set<std::string> read_;
};

// Loads a YAML file, turning parser errors into Error with the file and line.
YAML::Node load_yaml_file(const std::string& path);

}  // namespace tirstrain
