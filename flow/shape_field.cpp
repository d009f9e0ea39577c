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

}  // namespace

void ShapeField::prepare(const std::vector<Vec2>& anchor_px, cv::Rect region, double spacing_px,
                         double sigma_px) {
  if (std::max(1.0, spacing_px) != spacing_ || sigma_px != sigma_) cache_.clear();
  region_ = region;
  spacing_ = std::max(1.0, spacing_px);
  sigma_ = sigma_px;
  anchors_ = anchor_px;
  const double radius = 2.0 * sigma_px;
  scale_ = radius;
  cols_ = static_cast<int>(std::ceil(region.width / spacing_)) + 1;
  rows_ = static_cast<int>(std::ceil(region.height / spacing_)) + 1;
  const std::size_t node_count = static_cast<std::size_t>(cols_) * static_cast<std::size_t>(rows_);
  term_start_.assign(node_count + 1, 0);
  terms_.clear();
  reused_ = 0;
  if (anchor_px.empty() || region.area() <= 0 || !(sigma_px > 0.0)) return;
  // Samples in buckets one fit radius wide: a node's samples lie in its bucket and the eight around it. The
  // buckets sit on multiples of the radius and take their samples in order of position, so a node meets its
  // samples in the same order whatever the region and the samples' order in the list (the cache below
  // compares sample lists, and equal lists give the same sums to the last bit).
  const int bx0 = static_cast<int>(std::floor((region.x - radius) / radius));
  const int by0 = static_cast<int>(std::floor((region.y - radius) / radius));
  const int bcols = static_cast<int>(std::floor((region.x + region.width + 2.0 * radius) / radius)) - bx0 + 1;
  const int brows =
      static_cast<int>(std::floor((region.y + region.height + 2.0 * radius) / radius)) - by0 + 1;
  const auto bucket_of = [&](double x, double y, int& bx, int& by) {
    bx = static_cast<int>(std::floor(x / radius)) - bx0;
    by = static_cast<int>(std::floor(y / radius)) - by0;
    return bx >= 0 && by >= 0 && bx < bcols && by < brows;
  };
  std::vector<int> order(anchor_px.size());
  std::iota(order.begin(), order.end(), 0);
  std::sort(order.begin(), order.end(), [&](int i, int j) {
    const Vec2 p = anchor_px[static_cast<std::size_t>(i)], q = anchor_px[static_cast<std::size_t>(j)];
    return p.y != q.y ? p.y < q.y : (p.x != q.x ? p.x < q.x : i < j);
  });
  std::vector<int> start(static_cast<std::size_t>(bcols * brows) + 1, 0), items(anchor_px.size());
  std::vector<int> bucket(anchor_px.size(), -1);
  for (std::size_t s = 0; s < anchor_px.size(); ++s) {
    int bx, by;
    const Vec2 p = anchor_px[s];
    if (!(std::isfinite(p.x) && std::isfinite(p.y)) || !bucket_of(p.x, p.y, bx, by)) continue;
    bucket[s] = by * bcols + bx;
    ++start[static_cast<std::size_t>(bucket[s]) + 1];
  }
  for (std::size_t b = 1; b < start.size(); ++b) start[b] += start[b - 1];
  std::vector<int> fill(start.begin(), start.end() - 1);
  for (int s : order) {
    const int b = bucket[static_cast<std::size_t>(s)];
    if (b >= 0) items[static_cast<std::size_t>(fill[static_cast<std::size_t>(b)]++)] = s;
  }

  // Each row of nodes in parallel into its own list, joined in order afterwards.
  std::vector<std::vector<Term>> row_terms(static_cast<std::size_t>(rows_));
  std::vector<std::vector<int>> row_counts(static_cast<std::size_t>(rows_));
  std::vector<std::vector<std::pair<std::int64_t, CachedNode>>> row_cache(static_cast<std::size_t>(rows_));
  std::vector<int> row_reused(static_cast<std::size_t>(rows_), 0);
  const auto node_key = [](double x, double y) {
    return (static_cast<std::int64_t>(std::llround(4.0 * y)) << 32) ^
           (static_cast<std::int64_t>(std::llround(4.0 * x)) & 0xffffffffLL);
  };
  cv::parallel_for_(cv::Range(0, rows_), [&](const cv::Range& range) {
    Eigen::Matrix<double, 6, 6> normal;
    std::vector<Vector6> basis;
    std::vector<int> members;
    for (int r = range.start; r < range.end; ++r) {
      auto& out = row_terms[static_cast<std::size_t>(r)];
      auto& counts = row_counts[static_cast<std::size_t>(r)];
      auto& cached = row_cache[static_cast<std::size_t>(r)];
      out.clear();
      counts.assign(static_cast<std::size_t>(cols_), 0);
      for (int c = 0; c < cols_; ++c) {
        const double nx = region.x + c * spacing_, ny = region.y + r * spacing_;
        int bx, by;
        if (!bucket_of(nx, ny, bx, by)) continue;
        members.clear();
        int quadrants = 0;
        for (int y = std::max(0, by - 1); y <= std::min(brows - 1, by + 1); ++y)
          for (int x = std::max(0, bx - 1); x <= std::min(bcols - 1, bx + 1); ++x) {
            const std::size_t b = static_cast<std::size_t>(y * bcols + x);
            for (int k = start[b]; k < start[b + 1]; ++k) {
              const int s = items[static_cast<std::size_t>(k)];
              const double dx = anchor_px[static_cast<std::size_t>(s)].x - nx;
              const double dy = anchor_px[static_cast<std::size_t>(s)].y - ny;
              if (dx * dx + dy * dy > radius * radius) continue;
              members.push_back(s);
              quadrants |= 1 << ((dx >= 0.0 ? 1 : 0) + (dy >= 0.0 ? 2 : 0));
            }
          }
        const int count = static_cast<int>(members.size());
        if (count < 6) continue;
        // Each node is visited by one thread only, so its old entry can be moved from.
        const std::int64_t key = node_key(nx, ny);
        const auto same_samples = [&](const CachedNode& node) {
          if (node.samples.size() != members.size()) return false;
          for (std::size_t k = 0; k < members.size(); ++k) {
            const Vec2 p = anchor_px[static_cast<std::size_t>(members[k])], q = node.samples[k];
            if (p.x != q.x || p.y != q.y) return false;
          }
          return true;
        };
        if (const auto it = cache_.find(key); it != cache_.end() && same_samples(it->second)) {
          const CachedNode& node = it->second;
          for (std::size_t k = 0; k < node.rows.size(); ++k) out.push_back({members[k], node.rows[k]});
          counts[static_cast<std::size_t>(c)] = static_cast<int>(node.rows.size());
          cached.emplace_back(key, std::move(it->second));
          ++row_reused[static_cast<std::size_t>(r)];
          continue;
        }
        CachedNode entry;
        entry.samples.reserve(members.size());
        for (int m : members) entry.samples.push_back(anchor_px[static_cast<std::size_t>(m)]);
        basis.resize(static_cast<std::size_t>(count));
        normal.setZero();
        for (int k = 0; k < count; ++k) {
          const Vec2 p = anchor_px[static_cast<std::size_t>(members[static_cast<std::size_t>(k)])];
          const double dx = p.x - nx, dy = p.y - ny;
          const double w = std::exp(-0.5 * (dx * dx + dy * dy) / (sigma_px * sigma_px));
          const double a = dx / scale_, bb = dy / scale_;
          Vector6& v = basis[static_cast<std::size_t>(k)];
          v << 1.0, a, bb, a * a, a * bb, bb * bb;
          normal.selfadjointView<Eigen::Upper>().rankUpdate(v, w);
          v *= w;
        }
        normal.triangularView<Eigen::StrictlyLower>() = normal.transpose();
        const int sides =
            (quadrants & 1) + ((quadrants >> 1) & 1) + ((quadrants >> 2) & 1) + ((quadrants >> 3) & 1);
        // The operator rows: coef = N⁻¹ Σ w_k b_k u_k, so a_k = N⁻¹ (w_k b_k).
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
        if (solved && inverse.allFinite()) {
          entry.rows.resize(static_cast<std::size_t>(count));
          for (int k = 0; k < count; ++k) {
            Term t;
            t.sample = members[static_cast<std::size_t>(k)];
            const Vector6 a = inverse * basis[static_cast<std::size_t>(k)];
            for (int i = 0; i < 6; ++i) t.a[static_cast<std::size_t>(i)] = a[i];
            entry.rows[static_cast<std::size_t>(k)] = t.a;
            out.push_back(t);
          }
          counts[static_cast<std::size_t>(c)] = count;
        }
        cached.emplace_back(key, std::move(entry));
      }
    }
  });
  for (int r = 0; r < rows_; ++r) {
    for (int c = 0; c < cols_; ++c) {
      const std::size_t node = static_cast<std::size_t>(r * cols_ + c);
      term_start_[node + 1] =
          term_start_[node] + row_counts[static_cast<std::size_t>(r)][static_cast<std::size_t>(c)];
    }
    terms_.insert(terms_.end(), row_terms[static_cast<std::size_t>(r)].begin(),
                  row_terms[static_cast<std::size_t>(r)].end());
  }
  for (int n : row_reused) reused_ += n;
  cache_.clear();
  for (auto& row : row_cache)
    for (auto& [key, node] : row) cache_.emplace(key, std::move(node));
}

void ShapeField::fit(const std::vector<Vec2>& anchor_px, const std::vector<Vec2>& displacement_px,
                     cv::Rect region, double spacing_px, double sigma_px) {
  CV_Assert(anchor_px.size() == displacement_px.size());
  const auto same = [](const std::vector<Vec2>& a, const std::vector<Vec2>& b) {
    return a.size() == b.size() &&
           std::equal(a.begin(), a.end(), b.begin(), [](Vec2 p, Vec2 q) { return p.x == q.x && p.y == q.y; });
  };
  if (region != region_ || spacing_px != spacing_ || sigma_px != sigma_ || !same(anchor_px, anchors_) ||
      term_start_.empty())
    prepare(anchor_px, region, spacing_px, sigma_px);
  nodes_.assign(static_cast<std::size_t>(cols_) * static_cast<std::size_t>(rows_), Node{});
  fitted_ = 0;
  for (std::size_t node = 0; node < nodes_.size(); ++node) {
    if (term_start_[node + 1] == term_start_[node]) continue;
    Eigen::Matrix<double, 6, 2> coef = Eigen::Matrix<double, 6, 2>::Zero();
    for (int k = term_start_[node]; k < term_start_[node + 1]; ++k) {
      const Term& t = terms_[static_cast<std::size_t>(k)];
      const Vec2 u = displacement_px[static_cast<std::size_t>(t.sample)];
      for (int i = 0; i < 6; ++i) {
        coef(i, 0) += t.a[static_cast<std::size_t>(i)] * u.x;
        coef(i, 1) += t.a[static_cast<std::size_t>(i)] * u.y;
      }
    }
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

void ShapeField::displacement_row(int y, int x_begin, int x_end, Vec2* u, std::uint8_t* ok) const {
  if (x_end <= x_begin) return;
  std::fill(ok, ok + (x_end - x_begin), std::uint8_t{0});
  if (nodes_.empty()) return;
  const double fy = (y - region_.y) / spacing_;
  if (!(fy >= 0.0 && fy <= rows_ - 1)) return;
  const int last_c = cols_ - 2 < 0 ? 0 : cols_ - 2;
  const int r = std::min(static_cast<int>(fy), rows_ - 2 < 0 ? 0 : rows_ - 2);
  const double ty = fy - r;
  // Along a row, within one cell, each node's weight is linear and its polynomial quadratic in the column
  // offset t from the cell's first pixel, so the blend's numerators are cubics and its weight sum linear in
  // t: their coefficients are summed once per cell, and a pixel costs two Horner evaluations and a division.
  int x = x_begin;
  while (x < x_end) {
    const double fx = (x - region_.x) / spacing_;
    if (fx < 0.0) {
      ++x;
      continue;
    }
    if (fx > cols_ - 1) break;
    const int c = std::min(static_cast<int>(fx), last_c);
    const double x0 = x;  // t = 0
    double su[4] = {0.0, 0.0, 0.0, 0.0}, sv[4] = {0.0, 0.0, 0.0, 0.0}, sw[2] = {0.0, 0.0};
    for (int k = 0; k < 4; ++k) {
      const int nc = c + (k & 1), nr = r + (k >> 1);
      if (nc >= cols_ || nr >= rows_) continue;
      const Node& node = nodes_[static_cast<std::size_t>(nr * cols_ + nc)];
      if (!node.fitted) continue;
      const double wy = (k >> 1) ? ty : 1.0 - ty;
      // w(t) = alpha + beta t, from tx = (x0 + t − region x) / spacing − c.
      const double tx0 = (x0 - region_.x) / spacing_ - c;
      const double alpha = wy * ((k & 1) ? tx0 : 1.0 - tx0);
      const double beta = wy * ((k & 1) ? 1.0 : -1.0) / spacing_;
      const double b = (y - (region_.y + nr * spacing_)) / scale_;
      const double a0 = (x0 - (region_.x + nc * spacing_)) / scale_;
      const Coef& q = node.coef;
      // The node's polynomial on this row, p0 + p1 a + p2 a², rewritten in t (a = a0 + t / scale).
      const auto in_t = [&](int j, double out[3]) {
        const double p0 = q(0, j) + q(2, j) * b + q(5, j) * b * b, p1 = q(1, j) + q(4, j) * b, p2 = q(3, j);
        out[0] = p0 + (p1 + p2 * a0) * a0;
        out[1] = (p1 + 2.0 * p2 * a0) / scale_;
        out[2] = p2 / (scale_ * scale_);
      };
      double pu[3], pv[3];
      in_t(0, pu);
      in_t(1, pv);
      su[0] += alpha * pu[0];
      su[1] += alpha * pu[1] + beta * pu[0];
      su[2] += alpha * pu[2] + beta * pu[1];
      su[3] += beta * pu[2];
      sv[0] += alpha * pv[0];
      sv[1] += alpha * pv[1] + beta * pv[0];
      sv[2] += alpha * pv[2] + beta * pv[1];
      sv[3] += beta * pv[2];
      sw[0] += alpha;
      sw[1] += beta;
    }
    // The pixels of this cell: fx < c + 1, or up to the last node column in the last cell.
    int cell_end;
    if (c < last_c) {
      cell_end = static_cast<int>(std::ceil(region_.x + (c + 1) * spacing_));
    } else {
      cell_end = static_cast<int>(std::floor(region_.x + (cols_ - 1) * spacing_)) + 1;
    }
    cell_end = std::clamp(cell_end, x + 1, x_end);
    for (; x < cell_end; ++x) {
      const double t = x - x0;
      const double wsum = sw[0] + sw[1] * t;
      if (!(wsum > 1e-9)) continue;
      const double inverse = 1.0 / wsum;
      const double sx = ((su[3] * t + su[2]) * t + su[1]) * t + su[0];
      const double sy = ((sv[3] * t + sv[2]) * t + sv[1]) * t + sv[0];
      u[x - x_begin] = {sx * inverse, sy * inverse};
      ok[x - x_begin] = 1;
    }
  }
}

void resample_through(const cv::Mat& current, const cv::Mat& current_mask, const ShapeField& field,
                      const cv::Mat& anchor_mask, cv::Rect region, cv::Mat& out, cv::Mat& valid,
                      const PixelClasses& classes) {
  CV_Assert(current.type() == CV_32F && anchor_mask.type() == CV_8U && anchor_mask.size() == current.size());
  out.create(current.size(), CV_32F);
  valid.create(current.size(), CV_8U);
  valid.setTo(cv::Scalar(0));
  region &= cv::Rect(0, 0, current.cols, current.rows);
  const detail::Sampler image(current, current_mask);
  cv::parallel_for_(cv::Range(region.y, region.y + region.height), [&](const cv::Range& range) {
    std::vector<Vec2> u(static_cast<std::size_t>(region.width));
    std::vector<std::uint8_t> defined(static_cast<std::size_t>(region.width));
    for (int y = range.start; y < range.end; ++y) {
      if (!classes.has_row(y)) continue;
      const std::uint8_t* m = anchor_mask.ptr<std::uint8_t>(y);
      float* o = out.ptr<float>(y);
      std::uint8_t* v = valid.ptr<std::uint8_t>(y);
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
