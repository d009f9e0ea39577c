#include "strain/mesh.hpp"

#include <CGAL/Delaunay_triangulation_2.h>
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Triangulation_vertex_base_with_info_2.h>

#include <algorithm>
#include <cmath>
#include <numbers>

namespace tirstrain::strain {
namespace {

using Kernel = CGAL::Exact_predicates_inexact_constructions_kernel;
using VertexBase = CGAL::Triangulation_vertex_base_with_info_2<std::int32_t, Kernel>;
using DataStructure = CGAL::Triangulation_data_structure_2<VertexBase>;
using Delaunay = CGAL::Delaunay_triangulation_2<Kernel, DataStructure>;

}  // namespace

std::vector<Triangle> delaunay(std::span<const Vec2> points) {
  std::vector<std::pair<Kernel::Point_2, std::int32_t>> input;
  input.reserve(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    if (std::isfinite(points[i].x) && std::isfinite(points[i].y))
      input.emplace_back(Kernel::Point_2(points[i].x, points[i].y), static_cast<std::int32_t>(i));
  std::vector<Triangle> triangles;
  if (input.size() < 3) return triangles;
  // Range insertion sorts spatially (fast). With duplicate points CGAL keeps one vertex carrying whichever
  // index came first in its sorted order, so in that case each vertex is given the smallest index at its
  // location explicitly.
  Delaunay dt;
  dt.insert(input.begin(), input.end());
  if (dt.number_of_vertices() < input.size()) {
    for (auto v = dt.finite_vertices_begin(); v != dt.finite_vertices_end(); ++v) v->info() = -1;
    Delaunay::Vertex_handle hint;
    for (const auto& [point, index] : input) {
      hint = dt.nearest_vertex(point,
                               hint == Delaunay::Vertex_handle() ? Delaunay::Face_handle() : hint->face());
      if (hint->point() == point && (hint->info() < 0 || hint->info() > index)) hint->info() = index;
    }
  }
  if (dt.dimension() < 2) return triangles;
  for (auto face = dt.finite_faces_begin(); face != dt.finite_faces_end(); ++face) {
    Triangle t{face->vertex(0)->info(), face->vertex(1)->info(), face->vertex(2)->info()};
    if (signed_area(points[t[0]], points[t[1]], points[t[2]]) < 0) std::swap(t[1], t[2]);
    // Rotate so the smallest index comes first: a canonical form independent of CGAL's internal order.
    const auto smallest = std::min_element(t.begin(), t.end()) - t.begin();
    std::rotate(t.begin(), t.begin() + smallest, t.end());
    triangles.push_back(t);
  }
  std::sort(triangles.begin(), triangles.end());
  return triangles;
}

const char* to_string(TriangleStatus status) {
  switch (status) {
    case TriangleStatus::kValid:
      return "valid";
    case TriangleStatus::kMissingVertex:
      return "missing_vertex";
    case TriangleStatus::kSmallArea:
      return "small_area";
    case TriangleStatus::kSmallAngle:
      return "small_angle";
    case TriangleStatus::kHighAspect:
      return "high_aspect";
    case TriangleStatus::kInverted:
      return "inverted";
  }
  return "unknown";
}

double signed_area(const Vec2& a, const Vec2& b, const Vec2& c) {
  return 0.5 * ((b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y));
}

double min_angle_deg(const Vec2& a, const Vec2& b, const Vec2& c) {
  const auto angle_at = [](const Vec2& p, const Vec2& q, const Vec2& r) {
    const double ux = q.x - p.x, uy = q.y - p.y, vx = r.x - p.x, vy = r.y - p.y;
    // atan2 of cross and dot keeps full accuracy for tiny angles, where acos of a normalised dot does not.
    return std::atan2(std::abs(ux * vy - uy * vx), ux * vx + uy * vy);
  };
  const double smallest = std::min({angle_at(a, b, c), angle_at(b, c, a), angle_at(c, a, b)});
  return smallest * 180.0 / std::numbers::pi;
}

double aspect_ratio(const Vec2& a, const Vec2& b, const Vec2& c) {
  const double ab = std::hypot(b.x - a.x, b.y - a.y), bc = std::hypot(c.x - b.x, c.y - b.y),
               ca = std::hypot(a.x - c.x, a.y - c.y);
  const double longest = std::max({ab, bc, ca});
  const double area = std::abs(signed_area(a, b, c));
  if (area == 0.0) return std::numeric_limits<double>::infinity();
  const double altitude = 2.0 * area / longest;
  return longest / altitude;
}

TriangleStatus check_reference_shape(const Vec2& a, const Vec2& b, const Vec2& c,
                                     const QualityCriteria& criteria) {
  if (std::abs(signed_area(a, b, c)) < criteria.min_area_px2) return TriangleStatus::kSmallArea;
  if (min_angle_deg(a, b, c) < criteria.min_angle_deg) return TriangleStatus::kSmallAngle;
  if (aspect_ratio(a, b, c) > criteria.max_aspect) return TriangleStatus::kHighAspect;
  return TriangleStatus::kValid;
}

}  // namespace tirstrain::strain
