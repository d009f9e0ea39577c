#include "core/scene_section.hpp"

#include <filesystem>
#include <map>

#include "core/detail/yaml_tree.hpp"
#include "core/error.hpp"

namespace tirstrain {
namespace {

// yaml-cpp keeps both entries of a key written twice and lookups find the first, so a second block (say
// another `calibration:`) would be silently ignored: refused here, with both lines.
void check_unique_keys(const YAML::Node& node, const std::string& origin, const std::string& prefix) {
  if (node.IsSequence()) {
    for (const auto& item : node) check_unique_keys(item, origin, prefix);
    return;
  }
  if (!node.IsMap()) return;
  std::map<std::string, int> first_line;
  for (const auto& item : node) {
    const int line = item.first.Mark().line + 1;
    if (!item.first.IsScalar())
      throw Error("a key must be plain text, not a list or mapping",
                  {.file = origin, .row = line, .key = prefix.empty() ? "(top)" : prefix});
    const std::string key = item.first.Scalar();
    const std::string full = prefix.empty() ? key : prefix + "." + key;
    if (const auto found = first_line.find(key); found != first_line.end())
      throw Error("key given twice (first at line " + std::to_string(found->second) + ")",
                  {.file = origin, .row = line, .key = full});
    first_line.emplace(key, line);
    check_unique_keys(item.second, origin, full);
  }
}

template <typename Load>
SceneSection checked(Load&& load, const std::string& origin) {
  try {
    YAML::Node root = load();
    check_unique_keys(root, origin, "");
    return section_of(std::move(root));
  } catch (const YAML::Exception& e) {
    ErrorContext context{.file = origin};
    if (e.mark.line >= 0) context.row = e.mark.line + 1;
    throw Error("not valid YAML: " + e.msg, context);
  }
}

YAML::Node map_copy(const YAML::Node& node) {
  return node.IsMap() ? YAML::Clone(node) : YAML::Node(YAML::NodeType::Map);
}

}  // namespace

SceneSection::SceneSection() : tree_(std::make_shared<const Tree>()) {}

SceneSection::SceneSection(std::shared_ptr<const Tree> tree) : tree_(std::move(tree)) {}

SceneSection SceneSection::parse(const std::string& yaml, const std::string& origin) {
  return checked([&] { return YAML::Load(yaml); }, origin);
}

SceneSection SceneSection::load(const std::string& path) {
  if (!std::filesystem::is_regular_file(path))
    throw Error("file not found or not a regular file", {.file = path});
  return checked([&] { return YAML::LoadFile(path); }, path);
}

bool SceneSection::empty() const {
  return !tree_->node.IsDefined() || tree_->node.IsNull();
}

bool SceneSection::is_map() const {
  return tree_->node.IsMap();
}

SceneSection SceneSection::at(const std::string& key) const {
  const YAML::Node& node = tree_->node;  // const: operator[] on a non-const node would insert the key
  if (!node.IsMap() || !node[key].IsDefined()) return {};
  return section_of(node[key]);
}

SceneSection SceneSection::with(const std::string& key, const std::string& text) const {
  YAML::Node copy = map_copy(tree_->node);
  copy[key] = text;
  return section_of(std::move(copy));
}

SceneSection SceneSection::with(const std::string& key, const SceneSection& value) const {
  YAML::Node copy = map_copy(tree_->node);
  copy[key] = YAML::Clone(value.tree_->node);
  return section_of(std::move(copy));
}

std::string SceneSection::to_yaml() const {
  if (empty()) return "";
  YAML::Emitter emitter;
  emitter.SetDoublePrecision(17);
  emitter << tree_->node;
  return emitter.c_str();
}

}  // namespace tirstrain
