#pragma once
// The predicted standard deviation of a linear triangle's Green–Lagrange strain, from its vertices'
// position covariances (first-order propagation through E = ½(FᵀF − I)).
//
// The vertices' errors are taken as independent. Neighbouring subsets share pixels, so their errors are
// positively correlated, and a common error of the three vertices moves the triangle without straining
// it: the independent propagation is an upper bound of the strain's noise, not an estimate of its bias.
#include <array>

#include "core/tensor2.hpp"

namespace tirstrain::strain {

// One vertex's position covariance in px² (xx, xy, yy).
using PositionCovariance = std::array<double, 3>;

// σ of E_xx, E_yy and E_xy (tensor shear); NaN when a covariance is missing (NaN) or the reference
// triangle is degenerate.
Strain2 strain_standard_deviation(const std::array<Vec2, 3>& reference_px,
                                  const std::array<Vec2, 3>& current_px,
                                  const std::array<PositionCovariance, 3>& covariance_px2);

}  // namespace tirstrain::strain
