#pragma once
// Cholesky factorisation and solves of a small symmetric positive definite matrix of compile-time size, for
// the local fit's windows (flow/local_fit.cpp): thousands of 12 × 12 systems per frame, where the general
// dense kernels' set-up costs more than the arithmetic. Reads the lower triangle only.
#include <Eigen/Core>

#include <algorithm>
#include <cmath>

namespace tirstrain::flow::detail {

template <int N>
class SmallCholesky {
 public:
  using Matrix = Eigen::Matrix<double, N, N>;

  // Factorises A = L Lᵀ; false when A is not positive definite (a pivot not above 0, or not a number).
  bool compute(const Matrix& a) {
    for (int j = 0; j < N; ++j) {
      double d = a(j, j);
      for (int k = 0; k < j; ++k) d -= l_(j, k) * l_(j, k);
      if (!(d > 0.0)) return false;
      const double pivot = std::sqrt(d);
      l_(j, j) = pivot;
      inverse_pivot_[j] = 1.0 / pivot;
      for (int i = j + 1; i < N; ++i) {
        double s = a(i, j);
        for (int k = 0; k < j; ++k) s -= l_(i, k) * l_(j, k);
        l_(i, j) = s * inverse_pivot_[j];
      }
    }
    l1_norm_ = symmetric_l1_norm(a);
    return true;
  }

  // Overwrites each column of b with the solution x of A x = b.
  template <int M>
  void solve_in_place(Eigen::Matrix<double, N, M>& b) const {
    for (int c = 0; c < M; ++c) {
      for (int i = 0; i < N; ++i) {  // L y = b
        double s = b(i, c);
        for (int k = 0; k < i; ++k) s -= l_(i, k) * b(k, c);
        b(i, c) = s * inverse_pivot_[i];
      }
      for (int i = N - 1; i >= 0; --i) {  // Lᵀ x = y
        double s = b(i, c);
        for (int k = i + 1; k < N; ++k) s -= l_(k, i) * b(k, c);
        b(i, c) = s * inverse_pivot_[i];
      }
    }
  }

  // A cheaper and looser bound than rcond_lower_bound(): |L⁻¹| ≤ M⁻¹ elementwise for the comparison matrix M
  // of L (|L_ii| on the diagonal, −|L_ij| off it), and M⁻¹ is non-negative, so ‖L⁻¹‖_∞ ≤ max(M⁻¹ 1) and
  // ‖L⁻¹‖₁ ≤ max(M⁻ᵀ 1): two triangular solves instead of L⁻¹. Never above rcond_lower_bound().
  double rcond_comparison_bound() const {
    double forward[N], backward[N];
    double norm_inf = 0.0, norm1 = 0.0;
    for (int i = 0; i < N; ++i) {
      double s = 1.0;
      for (int k = 0; k < i; ++k) s += std::abs(l_(i, k)) * forward[k];
      forward[i] = s * inverse_pivot_[i];
      norm_inf = std::max(norm_inf, forward[i]);
    }
    for (int i = N - 1; i >= 0; --i) {
      double s = 1.0;
      for (int k = i + 1; k < N; ++k) s += std::abs(l_(k, i)) * backward[k];
      backward[i] = s * inverse_pivot_[i];
      norm1 = std::max(norm1, backward[i]);
    }
    return 1.0 / (l1_norm_ * norm1 * norm_inf);
  }

  // A lower bound of the reciprocal condition number 1 / (‖A‖₁ ‖A⁻¹‖₁): ‖A⁻¹‖₁ = ‖L⁻ᵀ L⁻¹‖₁ is at most
  // ‖L⁻¹‖₁ ‖L⁻¹‖_∞. Any estimate of ‖A⁻¹‖₁ from below (Eigen's LLT::rcond) gives a value at least this.
  double rcond_lower_bound() const {
    Matrix inverse = Matrix::Zero();  // L⁻¹, lower triangular
    for (int c = 0; c < N; ++c) {
      inverse(c, c) = inverse_pivot_[c];
      for (int i = c + 1; i < N; ++i) {
        double s = 0.0;
        for (int k = c; k < i; ++k) s -= l_(i, k) * inverse(k, c);
        inverse(i, c) = s * inverse_pivot_[i];
      }
    }
    const double norm1 = inverse.cwiseAbs().colwise().sum().maxCoeff();
    const double norm_inf = inverse.cwiseAbs().rowwise().sum().maxCoeff();
    return 1.0 / (l1_norm_ * norm1 * norm_inf);
  }

 private:
  // ‖A‖₁ of the symmetric matrix whose lower triangle is given.
  static double symmetric_l1_norm(const Matrix& a) {
    double norm = 0.0;
    for (int c = 0; c < N; ++c) {
      double sum = 0.0;
      for (int r = 0; r < N; ++r) sum += std::abs(r >= c ? a(r, c) : a(c, r));
      norm = std::max(norm, sum);
    }
    return norm;
  }

  Matrix l_ = Matrix::Zero();
  double inverse_pivot_[N] = {};  // 1 / L(j, j)
  double l1_norm_ = 0.0;
};

}  // namespace tirstrain::flow::detail
