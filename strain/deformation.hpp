#pragma once
// Per-triangle kinematics of a linear (constant-strain) triangle: deformation gradient against the
// reference configuration, exact Green–Lagrange strain, principal strains, rotations, area change, energy;
// and the per-frame increment for the paper's incremental mode.
#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include "core/tensor2.hpp"
#include "strain/mesh.hpp"

namespace tirstrain::strain {

// H = F − I with F = [x2−x1, x3−x1]·[X2−X1, X3−X1]⁻¹. The reference triangle must have non-zero area.
Gradient2 displacement_gradient(const std::array<Vec2, 3>& reference, const std::array<Vec2, 3>& current);

// det F: current area over reference area.
inline double area_ratio(const Gradient2& h) {
  return (1.0 + h.xx) * (1.0 + h.yy) - h.xy * h.yx;
}

// Rotation of the polar decomposition F = R·U (exact for any strain, det F > 0), radians from +x to +y.
double polar_rotation_rad(const Gradient2& h);

// Composition of gradients: the gradient of x_t w.r.t. x_{t−1} from gradients w.r.t. the reference,
// F_inc = F_t · F_{t−1}⁻¹.
Gradient2 incremental_gradient(const Gradient2& current, const Gradient2& previous);

struct StrainOptions {
  QualityCriteria quality;  // triangles kept (`min_area_px2`, `min_angle_deg`, `max_aspect`)
  double px_per_mm = 52.0;  // the scene's calibration, px/mm; default 52
  double young_Pa = 1.0e6;  // the tissue's Young's modulus E, Pa; default 1 MPa
  double poisson = 0.4;     // the tissue's Poisson ratio ν; default 0.4
  double depth_m = 0.002;   // thickness for the plane-strain energy U = depth · Σ u_i A_i, m; default 2 mm
  // `stick_tolerance_px`: a triangle is stuck when its centroid follows the plate this closely, px; 0.5
  double stick_tolerance_px = 0.5;
  // Throws Error naming the first value out of range.
  void check() const;
};

struct FrameInput {
  std::span<const Triangle> triangles;
  std::span<const Vec2> reference_px;  // per track: reference position X
  std::span<const Vec2> current_px;    // per track: position in this frame, NaN where not alive
  std::span<const Vec2> previous_px;   // per track: position in the previous frame; empty for the first frame
  double dt_s = 0.0;                   // time since the previous frame
  Vec2 plate_displacement_px;          // plate displacement since the reference frame
  bool plate_known = false;            // without a plate measurement no stick labels are computed
};

struct TriangleCounts {
  std::int32_t valid = 0;
  std::int32_t missing_vertex = 0;
  std::int32_t small_area = 0;
  std::int32_t small_angle = 0;
  std::int32_t high_aspect = 0;
  std::int32_t inverted = 0;
  std::int32_t excluded() const { return small_area + small_angle + high_aspect + inverted; }
};

// Per triangle arrays ([T]); values are NaN where status != kValid.
struct FrameStrain {
  std::vector<TriangleStatus> status;
  std::vector<Gradient2> gradient;
  std::vector<Strain2> total;  // exact Green–Lagrange strain against the reference
  std::vector<Principal2> principal;
  std::vector<double> rotation_small_rad;
  std::vector<double> rotation_polar_rad;
  std::vector<double> area_ratio;
  std::vector<double> energy_density_J_m3;
  std::vector<double> reference_area_m2;
  std::vector<Strain2> increment;   // Green–Lagrange strain of frame t−1 → t (previous configuration)
  std::vector<Strain2> rate_per_s;  // increment / dt
  std::vector<std::int8_t> stuck;   // 1 stuck, 0 slipping, −1 unknown
  TriangleCounts counts;
  double total_energy_J = 0.0;  // depth · Σ W_i A_i over valid triangles (reference areas)
  double stick_ratio = 0.0;     // stuck area / valid area (NaN when unknown)
};

// Throws Error when `settings` has a value out of range (StrainOptions::check), when current_px (or a
// non-empty previous_px) does not have one position per reference_px, or a triangle names a track beyond
// them.
FrameStrain compute_frame_strain(const FrameInput& input, const StrainOptions& settings);

// The paper's total strain: a running sum of per-frame increments, kept per triangle. Triangles not valid
// in a frame keep their sum (their increment is unknown and treated as zero; counted in `gaps`).
class IncrementalStrain {
 public:
  explicit IncrementalStrain(std::size_t triangle_count = 0);
  void resize(std::size_t triangle_count);
  void add(const FrameStrain& frame);
  const std::vector<Strain2>& total() const { return sum_; }
  const std::vector<std::int32_t>& gaps() const { return gaps_; }

 private:
  std::vector<Strain2> sum_;
  std::vector<std::int32_t> gaps_;
};

}  // namespace tirstrain::strain
