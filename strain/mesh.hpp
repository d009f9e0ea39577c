#pragma once
// Delaunay triangulation (CGAL) of feature reference positions, and the explicit quality criteria that keep
// ill-conditioned triangles out of the strain computation.
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "core/tensor2.hpp"

namespace tirstrain::strain {

// Vertex indices into the point array, counter-clockwise in the usual mathematical sense of (x, y) —
// i.e. positive signed area (x2−x1)(y3−y1) − (x3−x1)(y2−y1) > 0 (with y down this looks clockwise on screen).
using Triangle = std::array<std::int32_t, 3>;

// Delaunay triangulation of `points`. Fewer than three distinct points, or all points collinear, give no
// triangles; duplicate points keep the first occurrence's index. Triangles are sorted for a stable order.
std::vector<Triangle> delaunay(std::span<const Vec2> points);

// Why a triangle was excluded from a frame's strain (0 = used).
enum class TriangleStatus : std::uint8_t {
  kValid = 0,
  kMissingVertex = 1,  // a vertex is not tracked in this frame (NaN position)
  kSmallArea = 2,      // reference area below min_area_px2
  kSmallAngle = 3,     // reference minimum angle below min_angle_deg
  kHighAspect = 4,     // longest edge / shortest altitude above max_aspect
  kInverted = 5,       // det F <= 0 in the current frame (element turned inside out)
};

const char* to_string(TriangleStatus status);

struct QualityCriteria {
  double min_area_px2 = 2.0;    // smaller triangles are not used, px²; default 2
  double min_angle_deg = 15.0;  // triangles with a smaller angle are not used, degrees; default 15
  double max_aspect = 10.0;     // longest edge over the altitude onto it (1.15 equilateral); default 10
  // Throws Error naming the first value out of range.
  void check() const;
};

// Signed area (positive counter-clockwise in x–y), px².
double signed_area(const Vec2& a, const Vec2& b, const Vec2& c);
// Smallest interior angle, degrees.
double min_angle_deg(const Vec2& a, const Vec2& b, const Vec2& c);
// Longest edge divided by the altitude onto it.
double aspect_ratio(const Vec2& a, const Vec2& b, const Vec2& c);
// Reference-shape check (area, angle, aspect); does not look at the current frame.
TriangleStatus check_reference_shape(const Vec2& a, const Vec2& b, const Vec2& c,
                                     const QualityCriteria& criteria);

}  // namespace tirstrain::strain
