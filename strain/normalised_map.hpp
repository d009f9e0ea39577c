#pragma once
// Maps of per-triangle quantities on a regular grid over the standard normalised ellipse (the contact's
// similarity transform of the reference frame, contact/ellipse.hpp): the grid spans [-1, 1] x [-1, 1] in
// normalised units (x along the major axis, semi-major axis 1) with cell centres at −1 + 2i/(cells − 1), so
// for odd `cells` the middle cell sits on the ellipse centre. Each cell takes
// the value of the reference triangle that contains its centre (the strain of a linear triangle is
// constant over it, so this is the field the mesh represents, without smoothing); cells outside every
// usable triangle are NaN. Maps from trials on the same grid can be averaged cell by cell.
#include <opencv2/core.hpp>

#include <span>
#include <vector>

#include "core/tensor2.hpp"
#include "strain/mesh.hpp"

namespace tirstrain::strain {

// Normalised coordinates of a reference point: q = A · (X, 1), A a 2x3 similarity matrix.
struct NormalisedGrid {
  int cells = 65;
  cv::Matx23d to_normalised;  // reference px -> normalised units

  double coordinate(int i) const { return -1.0 + 2.0 * i / (cells - 1); }
};

// For each cell (row-major, rows = normalised y), the index into `triangles` of the triangle covering it,
// or −1. Only triangles with `usable[t]` are drawn.
std::vector<std::int32_t> rasterise_triangles(const NormalisedGrid& grid, std::span<const Triangle> triangles,
                                              std::span<const Vec2> reference_px,
                                              std::span<const std::uint8_t> usable);

// Averages maps cell by cell, ignoring NaN; cells with no finite value stay NaN. `count` (optional) gets
// the number of maps that contributed per cell.
cv::Mat nan_mean(std::span<const cv::Mat> maps, cv::Mat* count = nullptr);

}  // namespace tirstrain::strain
