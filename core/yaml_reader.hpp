#pragma once
// Strict reading of YAML configuration (scene files): every key is typed and range-checked, and keys that
// nobody read are reported, so a typo never silently falls back to a default. Errors name the file and the
// full key path (e.g. "tissue.E_Pa").
#include <limits>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "core/scene_section.hpp"

namespace tirstrain {

class YamlSection {
 public:
  // `section` must be a map (or absent, treated as empty). `prefix` is the key path of this section ("" at
  // the top).
  YamlSection(SceneSection section, std::string file, std::string prefix = "");

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
  // A list of maps (e.g. a study's trials), each a section named key[i]; absent gives none.
  std::vector<YamlSection> sections(const std::string& key);
  // A list of text values; absent gives the fallback. `what` names the items in the error ("names").
  std::vector<std::string> texts(const std::string& key, const std::vector<std::string>& fallback = {},
                                 const std::string& what = "text values");
  // A map of text values, in the file's order; absent gives none.
  std::vector<std::pair<std::string, std::string>> text_map(const std::string& key);
  // This section's keys, in the file's order (for maps whose keys are data, e.g. column names).
  std::vector<std::string> keys() const;
  // The sub-tree as it is, marked as read (for sections another module parses).
  SceneSection raw(const std::string& key);
  // The 1-based line of this section in its file (0 when unknown).
  int line() const;

  // Throws Error naming the first key present in the file but never read.
  void finish() const;

  std::string path_of(const std::string& key) const { return prefix_.empty() ? key : prefix_ + "." + key; }
  const std::string& file() const { return file_; }

 private:
  [[noreturn]] void fail(const std::string& key, const std::string& message) const;
  // The value under `key` (marked as read), absent if the key is not there.
  std::optional<SceneSection> get(const std::string& key);

  SceneSection node_;
  std::string file_;
  std::string prefix_;
  std::set<std::string> read_;
};

}  // namespace tirstrain
