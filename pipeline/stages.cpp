// The registry of stages. A new stage adds its factory here; an entry without a factory is a stage this build
// does not have, and a scene that asks for it is told so.
#include <algorithm>
#include <set>

#include "pipeline/channels_stage.hpp"
#include "pipeline/contact_stage.hpp"
#include "pipeline/fit_stage.hpp"
#include "pipeline/stage.hpp"
#include "pipeline/strain_stage.hpp"
#include "pipeline/tracking_stage.hpp"

namespace tirstrain::pipeline {

const std::vector<StageSpec>& stage_registry() {
  static const std::vector<StageSpec> registry = {
      {"contact", {}, make_contact_stage},         {"tracking", {"contact"}, make_tracking_stage},
      {"strain", {"tracking"}, make_strain_stage}, {"channels", {}, make_channels_stage},
      {"fit", {"tracking"}, make_fit_stage},
  };
  return registry;
}

StagePlan plan_stages(const Scene& scene) {
  const auto& registry = stage_registry();
  const auto find = [&](const std::string& name) {
    return std::find_if(registry.begin(), registry.end(), [&](const StageSpec& s) { return s.name == name; });
  };
  std::set<std::string> wanted;
  std::vector<std::string> pending(scene.compute.begin(), scene.compute.end());
  while (!pending.empty()) {
    const std::string name = pending.back();
    pending.pop_back();
    if (!wanted.insert(name).second) continue;
    const auto it = find(name);
    if (it != registry.end()) pending.insert(pending.end(), it->needs.begin(), it->needs.end());
  }
  StagePlan plan;
  for (const StageSpec& spec : registry) {
    if (!wanted.count(spec.name)) continue;
    if (spec.make) {
      plan.stages.push_back(spec.make(scene));
    } else {
      plan.unavailable.push_back(spec.name);
    }
  }
  return plan;
}

}  // namespace tirstrain::pipeline
