#pragma once
// Statistics of axial directions (a ridge or a principal strain axis: θ and θ + π are the same direction),
// as used to compare orientation distributions between conditions or instants (Fisher, Statistical
// Analysis of Circular Data, 1993). Every axial angle is doubled, φ = 2θ, and analysed as a circular
// angle:
//   - mean direction θ̄ = ½·atan2(Σ sin φ, Σ cos φ), in [0, π);
//   - mean resultant length R = |Σ e^{iφ}| / n in [0, 1], circular variance 1 − R;
//   - circular kurtosis (Fisher) k = (R₂·cos(μ₂ − 2μ₁) − R⁴) / (1 − R)², with R₂, μ₂ the second trigonometric
//     moment of φ about zero: 0 for a wrapped normal, negative for flatter, positive for more peaked;
//   - Kuiper's two-sample test on φ: V = max(F₁ − F₂) + max(F₂ − F₁) over the empirical distribution
//     functions, which does not depend on where the circle is cut; p from Stephens' asymptotic series with
//     λ = (√nₑ + 0.155 + 0.24/√nₑ)·V, nₑ = n₁n₂/(n₁ + n₂), p = 2 Σ_j (4j²λ² − 1)·e^{−2j²λ²} (clamped to [0,
//     1]).
#include <cstddef>
#include <vector>

namespace tirstrain {

struct AxialSummary {
  std::size_t count = 0;
  double mean_direction_rad = 0.0;  // θ̄ in [0, π)
  double resultant_length = 0.0;    // R of the doubled angles
  double circular_variance = 0.0;   // 1 − R
  double kurtosis = 0.0;            // Fisher's circular kurtosis of the doubled angles (0 when R = 1)
};

// Throws Error when `angles_rad` is empty or holds a non-finite angle.
AxialSummary axial_summary(const std::vector<double>& angles_rad);

struct KuiperResult {
  double statistic = 0.0;  // V
  double p_value = 1.0;
  std::size_t count_a = 0, count_b = 0;
};

// Kuiper's two-sample test of two sets of axial angles; throws Error when either set is empty.
KuiperResult kuiper_two_sample_axial(const std::vector<double>& a_rad, const std::vector<double>& b_rad);

// Counts of axial angles in `bins` equal sectors of [0, π).
std::vector<std::size_t> axial_histogram(const std::vector<double>& angles_rad, std::size_t bins);

}  // namespace tirstrain
