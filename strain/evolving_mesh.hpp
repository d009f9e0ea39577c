#pragma once
// A Delaunay mesh of tracked features that follows births and retirements. Each time the set of live tracks
// changes, their reference positions are re-triangulated; a triangle whose three vertices (track ids) were
// already joined keeps its identity, so per-triangle histories stay continuous where the mesh did not
// change. The union of every triangle ever used is kept (index = identity), which is what /mesh/triangles
// stores.
#include <array>
#include <cstdint>
#include <map>
#include <span>
#include <vector>

#include "core/archive.hpp"
#include "core/tensor2.hpp"
#include "strain/mesh.hpp"

namespace tirstrain::strain {

class EvolvingMesh {
 public:
  // `alive_ids`: ids of the live tracks (any order); `reference_px`: reference position of every track,
  // indexed by id. Re-triangulates only when the live set differs from the last call's. Returns true when
  // the active triangle list changed.
  bool update(std::span<const std::int32_t> alive_ids, std::span<const Vec2> reference_px);

  // Every triangle ever active, in track ids, counter-clockwise in (x, y) reference coordinates.
  const std::vector<Triangle>& triangles() const { return triangles_; }
  // Indices into triangles() of the current mesh.
  const std::vector<std::int32_t>& active() const { return active_; }
  // The current mesh's triangles themselves (track ids), aligned with active().
  const std::vector<Triangle>& active_triangles() const { return active_triangles_; }
  // Number of re-triangulations so far.
  int rebuilds() const { return rebuilds_; }
  // Its state in a checkpoint (core/archive.hpp).
  void archive(Archive& a) { a(alive_, triangles_, index_of_, active_, active_triangles_, rebuilds_); }

 private:
  std::vector<std::int32_t> alive_;  // sorted
  std::vector<Triangle> triangles_;
  std::map<std::array<std::int32_t, 3>, std::int32_t> index_of_;  // sorted vertex ids -> identity
  std::vector<std::int32_t> active_;
  std::vector<Triangle> active_triangles_;
  int rebuilds_ = 0;
};

}  // namespace tirstrain::strain
