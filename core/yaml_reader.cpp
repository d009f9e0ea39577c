#include "core/yaml_reader.hpp"

#include <cmath>
#include <filesystem>
#include <map>

#include "core/csv.hpp"
#include "core/error.hpp"

namespace tirstrain {

YamlSection::YamlSection(YAML::Node node, std::string file, std::string prefix)
    : node_(std::move(node)), file_(std::move(file)), prefix_(std::move(prefix)) {
  if (node_.IsDefined() && !node_.IsNull() && !node_.IsMap())
    throw Error("expected a mapping of keys to values",
                {.file = file_, .key = prefix_.empty() ? "(top)" : prefix_});
}

void YamlSection::fail(const std::string& key, const std::string& message) const {
  throw Error(message, {.file = file_, .key = path_of(key)});
}

bool YamlSection::has(const std::string& key) const {
  if (!node_.IsDefined() || !node_.IsMap()) return false;
  const YAML::Node& map = node_;
  return map[key].IsDefined();
}

std::optional<YAML::Node> YamlSection::get(const std::string& key) {
  read_.insert(key);
  if (!has(key)) return std::nullopt;
  const YAML::Node& map = node_;  // const access: operator[] on a non-const node would insert the key
  return map[key];
}

double YamlSection::number(const std::string& key, double fallback, double min, double max) {
  const auto found = get(key);
  if (!found) return fallback;
  const YAML::Node& value = *found;
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
  const YAML::Node& value = *found;
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
  const YAML::Node& value = *found;
  bool result = false;
  if (!value.IsScalar() || !YAML::convert<bool>::decode(value, result)) fail(key, "expected true or false");
  return result;
}

std::string YamlSection::text(const std::string& key, const std::string& fallback) {
  const auto found = get(key);
  if (!found) return fallback;
  const YAML::Node& value = *found;
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
  const YAML::Node& value = *found;
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
  if (found && !found->IsNull() && !found->IsMap()) fail(key, "expected a mapping of keys to values");
  return YamlSection(found ? *found : YAML::Node(YAML::NodeType::Undefined), file_, path_of(key));
}

YAML::Node YamlSection::raw(const std::string& key) {
  const auto found = get(key);
  return found ? *found : YAML::Node(YAML::NodeType::Undefined);
}

void YamlSection::finish() const {
  if (!node_.IsDefined() || !node_.IsMap()) return;
  for (const auto& item : node_) {
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

namespace {

// yaml-cpp keeps both entries of a key written twice and lookups find the first, so a second block (say
// another `calibration:`) would be silently ignored: refused here, with both lines.
void check_unique_keys(const YAML::Node& node, const std::string& path, const std::string& prefix) {
  if (node.IsSequence()) {
    for (const auto& item : node) check_unique_keys(item, path, prefix);
    return;
  }
  if (!node.IsMap()) return;
  std::map<std::string, int> first_line;
  for (const auto& item : node) {
    const int line = item.first.Mark().line + 1;
    if (!item.first.IsScalar())
      throw Error("a key must be plain text, not a list or mapping",
                  {.file = path, .row = line, .key = prefix.empty() ? "(top)" : prefix});
    const std::string key = item.first.Scalar();
    const std::string full = prefix.empty() ? key : prefix + "." + key;
    if (const auto found = first_line.find(key); found != first_line.end())
      throw Error("key given twice (first at line " + std::to_string(found->second) + ")",
                  {.file = path, .row = line, .key = full});
    first_line.emplace(key, line);
    check_unique_keys(item.second, path, full);
  }
}

}  // namespace

YAML::Node load_yaml_file(const std::string& path) {
  if (!std::filesystem::is_regular_file(path))
    throw Error("file not found or not a regular file", {.file = path});
  try {
    YAML::Node root = YAML::LoadFile(path);
    check_unique_keys(root, path, "");
    return root;
  } catch (const YAML::Exception& e) {
    ErrorContext context{.file = path};
    if (e.mark.line >= 0) context.row = e.mark.line + 1;
    throw Error("not valid YAML: " + e.msg, context);
  }
}

}  // namespace tirstrain
