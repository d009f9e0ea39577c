#pragma once
// Globally adaptive Gauss–Kronrod (7/15) quadrature for the model tests: the reference integrals must not
// share code with the closed forms they check, and the tests take no numerical library.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <queue>
#include <vector>

namespace tirstrain::model::quadrature {

// Kronrod nodes on [0, 1) (symmetric about 0, the last is the centre); the odd-indexed ones are the
// 7-point Gauss nodes.
inline constexpr std::array<double, 8> kKronrodNodes = {
    0.991455371120812639206854697526329, 0.949107912342758524526189684047851,
    0.864864423359769072789712788640926, 0.741531185599394439863864773280788,
    0.586087235467691130294144845693013, 0.405845151377397166906606412076961,
    0.207784955007898467600689403773245, 0.0};
inline constexpr std::array<double, 8> kKronrodWeights = {
    0.022935322010529224963732008058970, 0.063092092629978553290700663189204,
    0.104790010322250183839876322541518, 0.140653259715525918745189590510238,
    0.169004726639267902826583426598550, 0.190350578064785409913256402421014,
    0.204432940075298892414161999234649, 0.209482141084727828012999174891714};
// Weights of the Gauss nodes kKronrodNodes[1], [3], [5], [7].
inline constexpr std::array<double, 4> kGaussWeights = {
    0.129484966168869693270611432679082, 0.279705391489276667901467771423780,
    0.381830050505118944950369775488975, 0.417959183673469387755102040816327};

struct Segment {
  double lo = 0.0, hi = 0.0, value = 0.0, error = 0.0;
  bool operator<(const Segment& other) const { return error < other.error; }
};

template <class F>
Segment gauss_kronrod_15(const F& f, double lo, double hi) {
  const double mid = 0.5 * (lo + hi);
  const double half = 0.5 * (hi - lo);
  const double centre = f(mid);
  double kronrod = kKronrodWeights[7] * centre;
  double gauss = kGaussWeights[3] * centre;
  for (std::size_t i = 0; i < 7; ++i) {
    const double dx = half * kKronrodNodes[i];
    const double pair = f(mid - dx) + f(mid + dx);
    kronrod += kKronrodWeights[i] * pair;
    if (i % 2 == 1) gauss += kGaussWeights[i / 2] * pair;
  }
  return {lo, hi, kronrod * half, std::abs((kronrod - gauss) * half)};
}

struct QuadratureResult {
  double value = 0.0;
  double error = 0.0;
  std::size_t segments = 0;
  bool converged = false;
};

// Bisects the segment with the largest error estimate until the summed estimate is below
// max(abs_tol, rel_tol·|integral|). |K15 − G7| is a pessimistic estimate for smooth integrands, so the
// true error is usually far below the requested one.
template <class F>
QuadratureResult integrate(const F& f, double lo, double hi, double rel_tol, double abs_tol = 0.0,
                           std::size_t max_segments = 4000) {
  std::priority_queue<Segment> heap;
  heap.push(gauss_kronrod_15(f, lo, hi));
  double value = heap.top().value;
  double error = heap.top().error;
  while (error > std::max(abs_tol, rel_tol * std::abs(value)) && heap.size() < max_segments) {
    const Segment worst = heap.top();
    heap.pop();
    const double mid = 0.5 * (worst.lo + worst.hi);
    const Segment left = gauss_kronrod_15(f, worst.lo, mid);
    const Segment right = gauss_kronrod_15(f, mid, worst.hi);
    value += left.value + right.value - worst.value;
    error += left.error + right.error - worst.error;
    heap.push(left);
    heap.push(right);
  }
  // Re-sum: the running totals drift by rounding over many updates.
  QuadratureResult result;
  result.segments = heap.size();
  while (!heap.empty()) {
    result.value += heap.top().value;
    result.error += heap.top().error;
    heap.pop();
  }
  result.converged = result.error <= std::max(abs_tol, rel_tol * std::abs(result.value));
  return result;
}

}  // namespace tirstrain::model::quadrature
