#pragma once
// A YAML document or one section of it (a scene's `tracking:`, a study file): an immutable tree that the
// module owning the section reads with YamlSection (core/yaml_reader.hpp). The YAML library stays behind
// this type: no public header of the project names it.
#include <memory>
#include <string>

namespace tirstrain {

class SceneSection {
 public:
  SceneSection();  // an absent section (reads as an empty map)

  // Parses YAML text; a syntax error or a key given twice throws Error naming `origin` and the line.
  static SceneSection parse(const std::string& yaml, const std::string& origin = "");
  // Reads a YAML file (the same checks, the file and line in the error).
  static SceneSection load(const std::string& path);

  bool empty() const;   // absent or null
  bool is_map() const;  // a mapping of keys to values
  // The section under `key` (absent when this is not a map or has no such key).
  SceneSection at(const std::string& key) const;
  // A copy with `key` set to a text value (e.g. a preset name or a path, taken as it is) or to another
  // section. Turns an absent section into a map.
  SceneSection with(const std::string& key, const std::string& text) const;
  SceneSection with(const std::string& key, const SceneSection& value) const;
  // Block-style YAML that parse() reads back to the same tree; "" for an absent section. Numbers keep 17
  // significant digits.
  std::string to_yaml() const;

  struct Tree;  // defined where the YAML library is used (core/detail/yaml_tree.hpp)
  explicit SceneSection(std::shared_ptr<const Tree> tree);
  const Tree& tree() const { return *tree_; }

 private:
  std::shared_ptr<const Tree> tree_;
};

}  // namespace tirstrain
