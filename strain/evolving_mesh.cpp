#include "strain/evolving_mesh.hpp"

#include <algorithm>

namespace tirstrain::strain {

bool EvolvingMesh::update(std::span<const std::int32_t> alive_ids, std::span<const Vec2> reference_px) {
  std::vector<std::int32_t> alive(alive_ids.begin(), alive_ids.end());
  std::sort(alive.begin(), alive.end());
  if (rebuilds_ > 0 && alive == alive_) return false;
  alive_ = std::move(alive);
  ++rebuilds_;

  std::vector<Vec2> points;
  points.reserve(alive_.size());
  for (const std::int32_t id : alive_) points.push_back(reference_px[static_cast<std::size_t>(id)]);
  const std::vector<Triangle> local = delaunay(points);

  std::vector<std::int32_t> active;
  std::vector<Triangle> active_triangles;
  active.reserve(local.size());
  active_triangles.reserve(local.size());
  for (const Triangle& t : local) {
    const Triangle ids = {alive_[static_cast<std::size_t>(t[0])], alive_[static_cast<std::size_t>(t[1])],
                          alive_[static_cast<std::size_t>(t[2])]};
    std::array<std::int32_t, 3> key = ids;
    std::sort(key.begin(), key.end());
    const auto [it, inserted] = index_of_.try_emplace(key, static_cast<std::int32_t>(triangles_.size()));
    if (inserted) triangles_.push_back(ids);
    active.push_back(it->second);
    active_triangles.push_back(triangles_[static_cast<std::size_t>(it->second)]);
  }
  const bool changed = active != active_;
  active_ = std::move(active);
  active_triangles_ = std::move(active_triangles);
  return changed;
}

}  // namespace tirstrain::strain
