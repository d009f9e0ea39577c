#include "core/yaml_reader.hpp"

#include <cmath>
#include <filesystem>
#include <map>

#include "core/csv.hpp"
#include "core/detail/yaml_tree.hpp"
#include "core/error.hpp"

namespace tirstrain {

namespace {

const SceneSection kAbsent;

}  // namespace

YamlSection::YamlSection(SceneSection section, std::string file, std::string prefix)
    : node_(std::move(section)), file_(std::move(file)), prefix_(std::move(prefix)) {
  if (!node_.empty() && !node_.is_map())
    throw Error("expected a mapping of keys to values",
                {.file = file_, .key = prefix_.empty() ? "(top)" : prefix_});
}

void YamlSection::fail(const std::string& key, const std::string& message) const {
  throw Error(message, {.file = file_, .key = path_of(key)});
}

bool YamlSection::has(const std::string& key) const {
  const YAML::Node& map = yaml_node(node_);  // const access: operator[] on a non-const node inserts the key
  if (!map.IsDefined() || !map.IsMap()) return false;
  return map[key].IsDefined();
}

std::optional<SceneSection> YamlSection::get(const std::string& key) {
  read_.insert(key);
  if (!has(key)) return std::nullopt;
  const YAML::Node& map = yaml_node(node_);
  return section_of(map[key]);
}

double YamlSection::number(const std::string& key, double fallback, double min, double max) {
  const auto found = get(key);
  if (!found) return fallback;
  const YAML::Node& value = yaml_node(*found);
  double result = 0.0;
  if (!value.IsScalar() || !YAML::convert<double>::decode(value, result)) fail(key, "expected a number");
  if (!std::isfinite(result)) fail(key, "expected a finite number");
  if (result < min || result > max)
    fail(key, "value " + format_double(result) + " is outside the allowed range [" + format_double(min) +
                  ", " + format_double(max) + "]");
  return result;
}

double YamlSection::required_number(const std::string& key, double min, double max) {
  if (!has(key)) fail(key, "required key is missing");
  return number(key, 0.0, min, max);
}

long YamlSection::integer(const std::string& key, long fallback, long min, long max) {
  const auto found = get(key);
  if (!found) return fallback;
  const YAML::Node& value = yaml_node(*found);
  long result = 0;
  if (!value.IsScalar() || !YAML::convert<long>::decode(value, result)) fail(key, "expected a whole number");
  if (result < min || result > max)
    fail(key, "value " + std::to_string(result) + " is outside the allowed range [" + std::to_string(min) +
                  ", " + std::to_string(max) + "]");
  return result;
}

bool YamlSection::boolean(const std::string& key, bool fallback) {
  const auto found = get(key);
  if (!found) return fallback;
  const YAML::Node& value = yaml_node(*found);
  bool result = false;
  if (!value.IsScalar() || !YAML::convert<bool>::decode(value, result)) fail(key, "expected true or false");
  return result;
}

std::string YamlSection::text(const std::string& key, const std::string& fallback) {
  const auto found = get(key);
  if (!found) return fallback;
  const YAML::Node& value = yaml_node(*found);
  if (!value.IsScalar()) fail(key, "expected a text value");
  return value.as<std::string>();
}

std::string YamlSection::required_text(const std::string& key) {
  if (!has(key)) fail(key, "required key is missing");
  return text(key, "");
}

std::string YamlSection::choice(const std::string& key, const std::string& fallback,
                                const std::vector<std::string>& choices) {
  const std::string value = text(key, fallback);
  std::string listed;
  for (const auto& c : choices) {
    if (c == value) return value;
    listed += (listed.empty() ? "" : ", ") + c;
  }
  fail(key, "'" + value + "' is not one of: " + listed);
}

std::vector<double> YamlSection::numbers(const std::string& key, const std::vector<double>& fallback) {
  const auto found = get(key);
  if (!found) return fallback;
  const YAML::Node& value = yaml_node(*found);
  if (!value.IsSequence()) fail(key, "expected a list of numbers");
  std::vector<double> out;
  for (const auto& item : value) {
    double x = 0.0;
    if (!item.IsScalar() || !YAML::convert<double>::decode(item, x) || !std::isfinite(x))
      fail(key, "expected a list of finite numbers");
    out.push_back(x);
  }
  return out;
}

YamlSection YamlSection::section(const std::string& key) {
  const auto found = get(key);
  if (found && !found->empty() && !found->is_map()) fail(key, "expected a mapping of keys to values");
  return YamlSection(found ? *found : kAbsent, file_, path_of(key));
}

std::vector<YamlSection> YamlSection::sections(const std::string& key) {
  const auto found = get(key);
  std::vector<YamlSection> out;
  if (!found || found->empty()) return out;
  const YAML::Node& list = yaml_node(*found);
  if (!list.IsSequence()) fail(key, "expected a list of mappings");
  for (const YAML::Node& item : list) {
    const std::string name = path_of(key) + "[" + std::to_string(out.size()) + "]";
    if (!item.IsNull() && !item.IsMap())
      throw Error("expected a mapping of keys to values",
                  {.file = file_, .row = item.Mark().line + 1, .key = name});
    out.emplace_back(section_of(item), file_, name);
  }
  return out;
}

std::vector<std::string> YamlSection::texts(const std::string& key, const std::vector<std::string>& fallback,
                                            const std::string& what) {
  const auto found = get(key);
  if (!found) return fallback;
  std::vector<std::string> out;
  if (found->empty()) return out;
  const YAML::Node& list = yaml_node(*found);
  if (!list.IsSequence()) fail(key, "expected a list of " + what);
  for (const YAML::Node& item : list) {
    if (!item.IsScalar())
      throw Error("expected a list of " + what + ", not a list or mapping inside it",
                  {.file = file_, .row = item.Mark().line + 1, .key = path_of(key)});
    out.push_back(item.Scalar());
  }
  return out;
}

std::vector<std::pair<std::string, std::string>> YamlSection::text_map(const std::string& key) {
  const auto found = get(key);
  std::vector<std::pair<std::string, std::string>> out;
  if (!found || found->empty()) return out;
  const YAML::Node& map = yaml_node(*found);
  if (!map.IsMap()) fail(key, "expected a mapping of names to values");
  for (const auto& item : map) {
    const std::string name = item.first.Scalar();
    if (!item.second.IsScalar()) fail(key + "." + name, "expected one number or word");
    out.emplace_back(name, item.second.Scalar());
  }
  return out;
}

std::vector<std::string> YamlSection::keys() const {
  std::vector<std::string> out;
  const YAML::Node& map = yaml_node(node_);
  if (!map.IsDefined() || !map.IsMap()) return out;
  for (const auto& item : map) out.push_back(item.first.Scalar());
  return out;
}

SceneSection YamlSection::raw(const std::string& key) {
  const auto found = get(key);
  return found ? *found : kAbsent;
}

int YamlSection::line() const {
  const YAML::Node& node = yaml_node(node_);
  return node.IsDefined() && node.Mark().line >= 0 ? node.Mark().line + 1 : 0;
}

void YamlSection::finish() const {
  const YAML::Node& map = yaml_node(node_);
  if (!map.IsDefined() || !map.IsMap()) return;
  for (const auto& item : map) {
    if (!item.first.IsScalar())
      throw Error(
          "a key must be plain text, not a list or mapping",
          {.file = file_, .row = item.first.Mark().line + 1, .key = prefix_.empty() ? "(top)" : prefix_});
    const std::string key = item.first.Scalar();
    if (!read_.count(key)) {
      std::string known;
      for (const auto& k : read_) known += (known.empty() ? "" : ", ") + k;
      fail(key, "unknown key (known keys here: " + known + ")");
    }
  }
}

}  // namespace tirstrain
