#pragma once
// Not a public header: core's YAML implementation (scene_section.cpp, yaml_reader.cpp, scene.cpp) reaches
// the YAML library's node behind SceneSection here.
#include <yaml-cpp/yaml.h>

#include "core/scene_section.hpp"

namespace tirstrain {

struct SceneSection::Tree {
  YAML::Node node;
};

inline const YAML::Node& yaml_node(const SceneSection& section) {
  return section.tree().node;
}

inline SceneSection section_of(YAML::Node node) {
  return SceneSection(std::make_shared<const SceneSection::Tree>(SceneSection::Tree{std::move(node)}));
}

}  // namespace tirstrain
