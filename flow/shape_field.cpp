#include "flow/shape_field.hpp"

#include <Eigen/Dense>
#include <opencv2/core/utility.hpp>

#include <algorithm>
#include <cmath>
#include <numeric>
#include <vector>

#include "flow/bicubic.hpp"

namespace tirstrain::flow {
namespace {

using Coef = Eigen::Matrix<double, 6, 2>;
using Vector6 = Eigen::Matrix<double, 6, 1>;

// u(a, b) of a node polynomial and its derivatives in a and b.
inline Vec2 evaluate(const Coef& c, double a, double b) {
  return {c(0, 0) + c(1, 0) * a + c(2, 0) * b + c(3, 0) * a * a + c(4, 0) * a * b + c(5, 0) * b * b,
          c(0, 1) + c(1, 1) * a + c(2, 1) * b + c(3, 1) * a * a + c(4, 1) * a * b + c(5, 1) * b * b};
}

bool finite(Vec2 p) {
  return std::isfinite(p.x) && std::isfinite(p.y);
}
bool same_position(Vec2 p, Vec2 q) {
  return p.x == q.x && p.y == q.y;
}
bool before(Vec2 p, Vec2 q) {
  return p.y != q.y ? p.y < q.y : p.x < q.x;
}

// The samples' indices in order of position (then of index, for equal positions).
std::vector<int> sorted_by_position(const std::vector<Vec2>& points) {
  std::vector<int> order(points.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int i, int j) {
    const Vec2 p = points[static_cast<std::size_t>(i)], q = points[static_cast<std::size_t>(j)];
    return before(p, q) || (!before(q, p) && i < j);
  });
  return order;
}

std::int64_t node_key(double x, double y) {
  return (static_cast<std::int64_t>(std::llround(4.0 * y)) << 32) ^
         (static_cast<std::int64_t>(std::llround(4.0 * x)) & 0xffffffffLL);
}

}  // namespace

// Samples in buckets one fit radius wide: a node's samples lie in its bucket and the eight around it. The
// buckets sit on multiples of the radius and take their samples in order of position, so a node meets its
// samples in the same order whatever the region and the samples' order in the list (equal sample lists
// give the same sums to the last bit).
struct ShapeField::SampleBuckets {
  double radius = 1.0;
  int x0 = 0, y0 = 0, cols = 0, rows = 0;
  std::vector<int> start, items;  // bucket b holds items[start[b] .. start[b + 1])

  SampleBuckets(cv::Rect region, double fit_radius) : radius(fit_radius) {
    x0 = static_cast<int>(std::floor((region.x - radius) / radius));
    y0 = static_cast<int>(std::floor((region.y - radius) / radius));
    cols = static_cast<int>(std::floor((region.x + region.width + 2.0 * radius) / radius)) - x0 + 1;
    rows = static_cast<int>(std::floor((region.y + region.height + 2.0 * radius) / radius)) - y0 + 1;
  }
  bool bucket_of(double x, double y, int& bx, int& by) const {
    bx = static_cast<int>(std::floor(x / radius)) - x0;
    by = static_cast<int>(std::floor(y / radius)) - y0;
    return bx >= 0 && by >= 0 && bx < cols && by < rows;
  }
  void fill(const std::vector<Vec2>& anchor_px, const std::vector<int>& order) {
    start.assign(static_cast<std::size_t>(cols * rows) + 1, 0);
    items.resize(anchor_px.size());
    std::vector<int> bucket(anchor_px.size(), -1);
    for (std::size_t s = 0; s < anchor_px.size(); ++s) {
      int bx, by;
      const Vec2 p = anchor_px[s];
      if (!finite(p) || !bucket_of(p.x, p.y, bx, by)) continue;
      bucket[s] = by * cols + bx;
      ++start[static_cast<std::size_t>(bucket[s]) + 1];
    }
    for (std::size_t b = 1; b < start.size(); ++b) start[b] += start[b - 1];
    std::vector<int> next(start.begin(), start.end() - 1);
    for (int s : order) {
      const int b = bucket[static_cast<std::size_t>(s)];
      if (b >= 0) items[static_cast<std::size_t>(next[static_cast<std::size_t>(b)]++)] = s;
    }
  }
  // The samples within the fit radius of node (nx, ny), in bucket order, and the quadrants they occupy.
  int gather(const std::vector<Vec2>& anchor_px, double nx, double ny, std::vector<int>& members) const {
    int bx, by;
    bucket_of(nx, ny, bx, by);
    members.clear();
    int quadrants = 0;
    for (int y = std::max(0, by - 1); y <= std::min(rows - 1, by + 1); ++y)
      for (int x = std::max(0, bx - 1); x <= std::min(cols - 1, bx + 1); ++x) {
        const std::size_t b = static_cast<std::size_t>(y * cols + x);
        for (int k = start[b]; k < start[b + 1]; ++k) {
          const int s = items[static_cast<std::size_t>(k)];
          const double dx = anchor_px[static_cast<std::size_t>(s)].x - nx;
          const double dy = anchor_px[static_cast<std::size_t>(s)].y - ny;
          if (dx * dx + dy * dy > radius * radius) continue;
          members.push_back(s);
          quadrants |= 1 << ((dx >= 0.0 ? 1 : 0) + (dy >= 0.0 ? 2 : 0));
        }
      }
    return quadrants;
  }
};

// The previous list's samples found in the new one (renumber[old] = new, −1 where gone) and the positions
// that came or went. `all_changed` when no one-to-one renumbering exists (a position twice).
struct ShapeField::Renumbering {
  std::vector<int> renumber;
  std::vector<Vec2> changed;
  bool all_changed = false;
};

ShapeField::Renumbering ShapeField::renumber_samples(const std::vector<Vec2>& previous,
                                                     const std::vector<Vec2>& anchor_px,
                                                     const std::vector<int>& order, bool all_changed) {
  Renumbering r;
  r.renumber.assign(previous.size(), -1);
  r.all_changed = all_changed;
  for (std::size_t k = 1; k < order.size() && !r.all_changed; ++k)
    r.all_changed = same_position(anchor_px[static_cast<std::size_t>(order[k - 1])],
                                  anchor_px[static_cast<std::size_t>(order[k])]);
  if (r.all_changed) return r;
  const std::vector<int> old_order = sorted_by_position(previous);
  std::size_t i = 0, j = 0;
  while (i < old_order.size() || j < order.size()) {
    const int o = i < old_order.size() ? old_order[i] : -1, n = j < order.size() ? order[j] : -1;
    const Vec2 p = o >= 0 ? previous[static_cast<std::size_t>(o)] : Vec2{};
    const Vec2 q = n >= 0 ? anchor_px[static_cast<std::size_t>(n)] : Vec2{};
    if (o >= 0 && n >= 0 && same_position(p, q)) {
      r.renumber[static_cast<std::size_t>(o)] = n;
      ++i, ++j;
    } else if (n < 0 || (o >= 0 && before(p, q))) {
      if (finite(p)) r.changed.push_back(p);
      ++i;
    } else {
      if (finite(q)) r.changed.push_back(q);
      ++j;
    }
  }
  return r;
}

void ShapeField::prepare(const std::vector<Vec2>& anchor_px, cv::Rect region, double spacing_px,
                         double sigma_px) {
  if (std::max(1.0, spacing_px) != spacing_ || sigma_px != sigma_) operators_.clear();
  region_ = region;
  spacing_ = std::max(1.0, spacing_px);
  sigma_ = sigma_px;
  const std::vector<Vec2> previous = std::move(anchors_);
  anchors_ = anchor_px;
  scale_ = 2.0 * sigma_px;  // the fit radius
  cols_ = static_cast<int>(std::ceil(region.width / spacing_)) + 1;
  rows_ = static_cast<int>(std::ceil(region.height / spacing_)) + 1;
  node_operator_.assign(static_cast<std::size_t>(cols_) * static_cast<std::size_t>(rows_), nullptr);
  reused_ = 0;
  ++generation_;
  if (anchor_px.empty() || region.area() <= 0 || !(sigma_px > 0.0)) {
    operators_.clear();
    return;
  }
  SampleBuckets buckets(region, scale_);
  const std::vector<int> order = sorted_by_position(anchor_px);
  const Renumbering renumbering = renumber_samples(previous, anchor_px, order, operators_.empty());
  std::vector<std::uint8_t> gather = nodes_near(renumbering);
  assign_operators(buckets, gather);
  if (std::find(gather.begin(), gather.end(), std::uint8_t{1}) != gather.end())
    buckets.fill(anchor_px, order);
  build_operators(buckets, gather, renumbering.renumber, previous);
}

// Only the nodes within a fit radius of a position that came or went gather their samples again (every
// node when no renumbering exists). A position that went may lie beyond this frame's region (the region
// follows the contact): it reaches no node, or only those at the region's edge.
std::vector<std::uint8_t> ShapeField::nodes_near(const Renumbering& renumbering) const {
  std::vector<std::uint8_t> gather(node_operator_.size(), renumbering.all_changed ? 1 : 0);
  for (const Vec2 p : renumbering.changed) {
    const int c0 = std::max(0, static_cast<int>(std::floor((p.x - scale_ - region_.x) / spacing_)));
    const int c1 = std::min(cols_ - 1, static_cast<int>(std::ceil((p.x + scale_ - region_.x) / spacing_)));
    const int r0 = std::max(0, static_cast<int>(std::floor((p.y - scale_ - region_.y) / spacing_)));
    const int r1 = std::min(rows_ - 1, static_cast<int>(std::ceil((p.y + scale_ - region_.y) / spacing_)));
    if (c0 > c1 || r0 > r1) continue;
    for (int r = r0; r <= r1; ++r)
      std::fill(gather.begin() + r * cols_ + c0, gather.begin() + r * cols_ + c1 + 1, std::uint8_t{1});
  }
  return gather;
}

// Every node in reach of the buckets gets its operator (kept by node position, new ones gather), before the
// parallel part: each thread then writes only its own nodes' entries. Operators no node uses are dropped.
void ShapeField::assign_operators(const SampleBuckets& buckets, std::vector<std::uint8_t>& gather) {
  for (int r = 0; r < rows_; ++r)
    for (int c = 0; c < cols_; ++c) {
      const double nx = region_.x + c * spacing_, ny = region_.y + r * spacing_;
      int bx, by;
      if (!buckets.bucket_of(nx, ny, bx, by)) continue;
      const std::size_t node = static_cast<std::size_t>(r * cols_ + c);
      const auto [it, added] = operators_.try_emplace(node_key(nx, ny));
      if (added) gather[node] = 1;
      it->second.generation = generation_;
      node_operator_[node] = &it->second;
    }
  for (auto it = operators_.begin(); it != operators_.end();)
    it = it->second.generation == generation_ ? std::next(it) : operators_.erase(it);
}

// Each node's operator: kept (its samples renumbered) where its samples are the same as before, built
// again from its gathered samples otherwise.
void ShapeField::build_operators(const SampleBuckets& buckets, const std::vector<std::uint8_t>& gather,
                                 const std::vector<int>& renumber, const std::vector<Vec2>& previous) {
  std::vector<int> row_reused(static_cast<std::size_t>(rows_), 0);
  cv::parallel_for_(cv::Range(0, rows_), [&](const cv::Range& range) {
    std::vector<int> members;
    std::vector<Vector6> basis;
    for (int r = range.start; r < range.end; ++r) {
      for (int c = 0; c < cols_; ++c) {
        const std::size_t node = static_cast<std::size_t>(r * cols_ + c);
        NodeOperator* op = node_operator_[node];
        if (!op) continue;
        if (!gather[node]) {
          // The same samples as last time, renumbered.
          bool kept = true;
          for (int& s : op->samples) {
            s = renumber[static_cast<std::size_t>(s)];
            kept = kept && s >= 0;
          }
          if (kept) {
            if (!op->rows.empty()) ++row_reused[static_cast<std::size_t>(r)];
            continue;
          }
        }
        const double nx = region_.x + c * spacing_, ny = region_.y + r * spacing_;
        const int quadrants = buckets.gather(anchors_, nx, ny, members);
        // Samples at the same positions as the operator's (its indices still those of the previous list).
        const bool same_samples =
            op->samples.size() == members.size() &&
            std::equal(members.begin(), members.end(), op->samples.begin(), [&](int m, int s) {
              return s >= 0 && static_cast<std::size_t>(s) < previous.size() &&
                     same_position(anchors_[static_cast<std::size_t>(m)],
                                   previous[static_cast<std::size_t>(s)]);
            });
        op->samples = members;
        if (same_samples && !op->rows.empty()) {
          ++row_reused[static_cast<std::size_t>(r)];
          continue;
        }
        build_operator(nx, ny, quadrants, *op, basis);
      }
    }
  });
  for (int n : row_reused) reused_ += n;
}

// The least-squares operator of one node from its samples (op.samples): coef = N⁻¹ Σ w_k b_k u_k, so its
// rows are a_k = N⁻¹ (w_k b_k); quadratic where at least 10 samples lie on two sides or more, affine
// otherwise or where the quadratic is ill-posed; no rows where neither holds.
void ShapeField::build_operator(double nx, double ny, int quadrants, NodeOperator& op,
                                std::vector<Eigen::Matrix<double, 6, 1>>& basis) const {
  op.rows.clear();
  const int count = static_cast<int>(op.samples.size());
  if (count < 6) return;
  basis.resize(static_cast<std::size_t>(count));
  // The upper triangle of N = Σ w_k b_k b_kᵀ by hand: Eigen's rank update of a fixed 6×6 takes 4 times the
  // instructions.
  double upper[21] = {};
  for (int k = 0; k < count; ++k) {
    const Vec2 p = anchors_[static_cast<std::size_t>(op.samples[static_cast<std::size_t>(k)])];
    const double dx = p.x - nx, dy = p.y - ny;
    const double w = std::exp(-0.5 * (dx * dx + dy * dy) / (sigma_ * sigma_));
    const double a = dx / scale_, bb = dy / scale_;
    const double v[6] = {1.0, a, bb, a * a, a * bb, bb * bb};
    for (int i = 0, e = 0; i < 6; ++i) {
      const double wv = w * v[i];
      for (int j = i; j < 6; ++j, ++e) upper[e] += wv * v[j];
    }
    Vector6& wb = basis[static_cast<std::size_t>(k)];
    for (int i = 0; i < 6; ++i) wb[i] = w * v[i];
  }
  Eigen::Matrix<double, 6, 6> normal;
  for (int i = 0, e = 0; i < 6; ++i)
    for (int j = i; j < 6; ++j, ++e) normal(i, j) = normal(j, i) = upper[e];
  const int sides =
      (quadrants & 1) + ((quadrants >> 1) & 1) + ((quadrants >> 2) & 1) + ((quadrants >> 3) & 1);
  Eigen::Matrix<double, 6, 6> inverse = Eigen::Matrix<double, 6, 6>::Zero();
  bool solved = false;
  if (count >= 10 && sides >= 2) {
    const Eigen::LDLT<Eigen::Matrix<double, 6, 6>> f(normal);
    if (f.info() == Eigen::Success && f.isPositive() && f.rcond() >= 1e-8) {
      inverse = f.solve(Eigen::Matrix<double, 6, 6>::Identity());
      solved = true;
    }
  }
  if (!solved) {  // affine; e.g. samples along one line, where the quadratic is ill-posed
    const Eigen::LDLT<Eigen::Matrix3d> f(normal.topLeftCorner<3, 3>());
    if (f.info() == Eigen::Success && f.isPositive() && f.rcond() >= 1e-8) {
      inverse.topLeftCorner<3, 3>() = f.solve(Eigen::Matrix3d::Identity());
      solved = true;
    }
  }
  if (!solved || !inverse.allFinite()) return;
  op.rows.resize(static_cast<std::size_t>(count));
  for (int k = 0; k < count; ++k) {
    const Vector6 a = inverse * basis[static_cast<std::size_t>(k)];
    for (int i = 0; i < 6; ++i) op.rows[static_cast<std::size_t>(k)][static_cast<std::size_t>(i)] = a[i];
  }
}

void ShapeField::fit(const std::vector<Vec2>& anchor_px, const std::vector<Vec2>& displacement_px,
                     cv::Rect region, double spacing_px, double sigma_px) {
  CV_Assert(anchor_px.size() == displacement_px.size());
  const auto same = [](const std::vector<Vec2>& a, const std::vector<Vec2>& b) {
    return a.size() == b.size() &&
           std::equal(a.begin(), a.end(), b.begin(), [](Vec2 p, Vec2 q) { return p.x == q.x && p.y == q.y; });
  };
  if (region != region_ || spacing_px != spacing_ || sigma_px != sigma_ || !same(anchor_px, anchors_) ||
      node_operator_.empty())
    prepare(anchor_px, region, spacing_px, sigma_px);
  nodes_.assign(static_cast<std::size_t>(cols_) * static_cast<std::size_t>(rows_), Node{});
  fitted_ = 0;
  for (std::size_t node = 0; node < nodes_.size(); ++node) {
    const NodeOperator* op = node_operator_[node];
    if (!op || op->rows.empty()) continue;
    double su[6] = {}, sv[6] = {};
    for (std::size_t k = 0; k < op->rows.size(); ++k) {
      const Vec2 u = displacement_px[static_cast<std::size_t>(op->samples[k])];
      const std::array<double, 6>& a = op->rows[k];
      for (int i = 0; i < 6; ++i) {
        su[i] += a[static_cast<std::size_t>(i)] * u.x;
        sv[i] += a[static_cast<std::size_t>(i)] * u.y;
      }
    }
    Eigen::Matrix<double, 6, 2> coef;
    for (int i = 0; i < 6; ++i) coef(i, 0) = su[i], coef(i, 1) = sv[i];
    if (!coef.allFinite()) continue;
    nodes_[node].coef = coef;
    nodes_[node].fitted = true;
    ++fitted_;
  }
}

bool ShapeField::displacement(double x, double y, Vec2& u, Eigen::Matrix2d* gradient) const {
  if (nodes_.empty()) return false;
  const double fx = (x - region_.x) / spacing_, fy = (y - region_.y) / spacing_;
  if (!(fx >= 0.0 && fy >= 0.0 && fx <= cols_ - 1 && fy <= rows_ - 1)) return false;
  const int c = std::min(static_cast<int>(fx), cols_ - 2 < 0 ? 0 : cols_ - 2);
  const int r = std::min(static_cast<int>(fy), rows_ - 2 < 0 ? 0 : rows_ - 2);
  const double tx = fx - c, ty = fy - r;
  double wsum = 0.0;
  Vec2 sum;
  Eigen::Matrix2d g = Eigen::Matrix2d::Zero();
  for (int k = 0; k < 4; ++k) {
    const int nc = c + (k & 1), nr = r + (k >> 1);
    if (nc >= cols_ || nr >= rows_) continue;
    const Node& node = nodes_[static_cast<std::size_t>(nr * cols_ + nc)];
    if (!node.fitted) continue;
    const double w = ((k & 1) ? tx : 1.0 - tx) * ((k >> 1) ? ty : 1.0 - ty);
    const double a = (x - (region_.x + nc * spacing_)) / scale_,
                 b = (y - (region_.y + nr * spacing_)) / scale_;
    const Vec2 v = evaluate(node.coef, a, b);
    sum.x += w * v.x;
    sum.y += w * v.y;
    if (gradient) {
      const Coef& q = node.coef;
      g(0, 0) += w * (q(1, 0) + 2.0 * q(3, 0) * a + q(4, 0) * b) / scale_;
      g(0, 1) += w * (q(2, 0) + q(4, 0) * a + 2.0 * q(5, 0) * b) / scale_;
      g(1, 0) += w * (q(1, 1) + 2.0 * q(3, 1) * a + q(4, 1) * b) / scale_;
      g(1, 1) += w * (q(2, 1) + q(4, 1) * a + 2.0 * q(5, 1) * b) / scale_;
    }
    wsum += w;
  }
  if (!(wsum > 1e-9)) return false;
  u = {sum.x / wsum, sum.y / wsum};
  if (gradient) *gradient = g / wsum;
  return true;
}

// One piece on purpose: it is the per-pixel loop of resampling every frame, and the column reduction feeds
// that loop through its locals.
void ShapeField::displacement_row(int y, int x_begin, int x_end, Vec2* u, std::uint8_t* ok, int x_stride,
                                  int x_phase) const {
  if (x_end <= x_begin) return;
  std::fill(ok, ok + (x_end - x_begin), std::uint8_t{0});
  if (nodes_.empty()) return;
  const double fy = (y - region_.y) / spacing_;
  if (!(fy >= 0.0 && fy <= rows_ - 1)) return;
  x_stride = std::max(1, x_stride);
  const int last_c = cols_ - 2 < 0 ? 0 : cols_ - 2;
  const int r = std::min(static_cast<int>(fy), rows_ - 2 < 0 ? 0 : rows_ - 2);
  const double ty = fy - r;
  // Along a row each node's polynomial is a quadratic in x and its weight the row's weight times a linear
  // one. Per node column, the fitted nodes of the two node rows around y are reduced once, to a quadratic
  // Q(s) in s = (x − column) / spacing and a weight sum W (each column serves the cells on both its sides);
  // per cell, the blend's numerators are cubics in s and its weight sum linear, and a pixel costs two
  // Horner evaluations and a division.
  const double ratio = spacing_ / scale_;
  const int first_c = std::max(0, static_cast<int>(std::floor((x_begin - region_.x) / spacing_)));
  const int end_c = std::min(cols_ - 1, static_cast<int>(std::ceil((x_end - region_.x) / spacing_)) + 1);
  struct Column {
    double q[2][3] = {};  // u and v
    double w = 0.0;
  };
  std::vector<Column> columns(static_cast<std::size_t>(std::max(0, end_c - first_c + 1)));
  for (int c = first_c; c <= end_c; ++c) {
    Column& col = columns[static_cast<std::size_t>(c - first_c)];
    for (int k = 0; k < 2; ++k) {
      const int nr = r + k;
      if (nr >= rows_) continue;
      const Node& node = nodes_[static_cast<std::size_t>(nr * cols_ + c)];
      if (!node.fitted) continue;
      const double wy = k ? ty : 1.0 - ty;
      const double b = (y - (region_.y + nr * spacing_)) / scale_;
      const Coef& q = node.coef;
      // a = s · spacing / scale
      for (int j = 0; j < 2; ++j) {
        col.q[j][0] += wy * (q(0, j) + q(2, j) * b + q(5, j) * b * b);
        col.q[j][1] += wy * (q(1, j) + q(4, j) * b) * ratio;
        col.q[j][2] += wy * q(3, j) * ratio * ratio;
      }
      col.w += wy;
    }
  }
  int x = x_begin + ((x_phase - x_begin) % x_stride + x_stride) % x_stride;
  while (x < x_end) {
    const double fx = (x - region_.x) / spacing_;
    if (fx < 0.0) {
      x += x_stride;
      continue;
    }
    if (fx > cols_ - 1) break;
    const int c = std::min(static_cast<int>(fx), last_c);
    // s from node column c: left weight 1 − s, right weight s (the right column's s' = s − 1).
    const Column& left = columns[static_cast<std::size_t>(c - first_c)];
    const Column empty{};
    const Column& right = c + 1 < cols_ ? columns[static_cast<std::size_t>(c + 1 - first_c)] : empty;
    double cu[2][4], sw[2];
    for (int j = 0; j < 2; ++j) {
      const double* L = left.q[j];
      // The right quadratic in s: R(s − 1).
      const double* R0 = right.q[j];
      const double R[3] = {R0[0] - R0[1] + R0[2], R0[1] - 2.0 * R0[2], R0[2]};
      // (1 − s) L(s) + s R(s)
      cu[j][0] = L[0];
      cu[j][1] = L[1] - L[0] + R[0];
      cu[j][2] = L[2] - L[1] + R[1];
      cu[j][3] = -L[2] + R[2];
    }
    sw[0] = left.w;
    sw[1] = right.w - left.w;
    // The pixels of this cell: fx < c + 1, or up to the last node column in the last cell.
    int cell_end;
    if (c < last_c) {
      cell_end = static_cast<int>(std::ceil(region_.x + (c + 1) * spacing_));
    } else {
      cell_end = static_cast<int>(std::floor(region_.x + (cols_ - 1) * spacing_)) + 1;
    }
    cell_end = std::clamp(cell_end, x + 1, x_end);
    const double column_x = region_.x + c * spacing_;
    for (; x < cell_end; x += x_stride) {
      const double s = (x - column_x) / spacing_;
      const double wsum = sw[0] + sw[1] * s;
      if (!(wsum > 1e-9)) continue;
      const double inverse = 1.0 / wsum;
      const double sx = ((cu[0][3] * s + cu[0][2]) * s + cu[0][1]) * s + cu[0][0];
      const double sy = ((cu[1][3] * s + cu[1][2]) * s + cu[1][1]) * s + cu[1][0];
      u[x - x_begin] = {sx * inverse, sy * inverse};
      ok[x - x_begin] = 1;
    }
  }
}

void resample_through(const cv::Mat& current, const cv::Mat& current_mask, const ShapeField& field,
                      const cv::Mat& anchor_mask, cv::Rect region, cv::Mat& out, cv::Mat& valid,
                      const PixelClasses& classes, Interpolation kernel) {
  CV_Assert(current.type() == CV_32F && anchor_mask.type() == CV_8U && anchor_mask.size() == current.size());
  out.create(current.size(), CV_32F);
  valid.create(current.size(), CV_8U);
  valid.setTo(cv::Scalar(0));
  region &= cv::Rect(0, 0, current.cols, current.rows);
  const detail::Sampler image(current, current_mask, kernel);
  cv::parallel_for_(cv::Range(region.y, region.y + region.height), [&](const cv::Range& range) {
    std::vector<Vec2> u(static_cast<std::size_t>(region.width));
    std::vector<std::uint8_t> defined(static_cast<std::size_t>(region.width));
    for (int y = range.start; y < range.end; ++y) {
      if (!classes.has_row(y)) continue;
      const std::uint8_t* m = anchor_mask.ptr<std::uint8_t>(y);
      float* o = out.ptr<float>(y);
      std::uint8_t* v = valid.ptr<std::uint8_t>(y);
      const int column_class = classes.single_column_class(y);
      if (column_class >= 0)
        field.displacement_row(y, region.x, region.x + region.width, u.data(), defined.data(),
                               classes.stride(), column_class);
      else
        field.displacement_row(y, region.x, region.x + region.width, u.data(), defined.data());
      classes.for_each_in_row(y, region.x, region.x + region.width, [&](int x) {
        const std::size_t k = static_cast<std::size_t>(x - region.x);
        if (m[x] == 0 || !defined[k]) return;
        float g;
        if (!image.sample(x + u[k].x, y + u[k].y, g)) return;
        o[x] = g;
        v[x] = 1;
      });
    }
  });
}

}  // namespace tirstrain::flow
