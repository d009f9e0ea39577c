#include "bench/studies/mesh_correlation.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

#include "core/error.hpp"
#include "flow/bicubic.hpp"

namespace tirstrain::studies {
namespace {

using Triplet = Eigen::Triplet<double>;

// Row of the Jacobian of one pixel's residual r = g(x + u(x)) − (1 + a(x)) f(x) − b(x) with respect to the
// element's 16 unknowns (node k: u, v, a, b at 4k … 4k + 3), the current image's gradient approximated by
// the reference's (modified Gauss–Newton: the Hessian stays fixed while the pixel set does).
inline void jacobian_row(const float n[4], float f, float gx, float gy, int dofs, double j[16]) {
  for (int k = 0; k < 4; ++k) {
    double* jk = j + k * dofs;
    jk[0] = n[k] * gx;
    jk[1] = n[k] * gy;
    if (dofs == 4) {
      jk[2] = -n[k] * f;
      jk[3] = -n[k];
    }
  }
}

}  // namespace

MeshCorrelation::MeshCorrelation(const cv::Mat& reference, const cv::Mat& region,
                                 const MeshCorrelationOptions& options)
    : options_(options) {
  if (reference.type() != CV_32F || region.type() != CV_8U || region.size() != reference.size())
    throw Error("MeshCorrelation: needs a CV_32F reference and a CV_8U region of the same size");
  if (options.element_px < 2) throw Error("MeshCorrelation: element_px must be at least 2");
  const int h = options.element_px;
  const int dofs = dofs_per_node();
  cv::Mat gx, gy, usable;
  cv::Sobel(reference, gx, CV_32F, 1, 0, 3, 1.0 / 8.0, 0.0, cv::BORDER_REPLICATE);
  cv::Sobel(reference, gy, CV_32F, 0, 1, 3, 1.0 / 8.0, 0.0, cv::BORDER_REPLICATE);
  // A border pixel's Sobel gradient sees the background.
  cv::erode(region, usable, cv::Mat(), cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  const cv::Rect box = cv::boundingRect(usable);
  if (box.area() == 0) throw Error("MeshCorrelation: the region is empty");
  origin_x_ = box.x;
  origin_y_ = box.y;
  cols_ = box.width / h + 1;
  rows_ = box.height / h + 1;
  const int elements = cols_ * rows_;

  std::vector<int> count(static_cast<std::size_t>(elements), 0);
  std::vector<Pixel> unsorted;
  for (int y = box.y; y < box.y + box.height; ++y) {
    const auto* m = usable.ptr<std::uint8_t>(y);
    const auto* fr = reference.ptr<float>(y);
    const auto* gxr = gx.ptr<float>(y);
    const auto* gyr = gy.ptr<float>(y);
    for (int x = box.x; x < box.x + box.width; ++x) {
      if (!m[x]) continue;
      const int ex = (x - origin_x_) / h, ey = (y - origin_y_) / h;
      const float xi = static_cast<float>(x - origin_x_ - ex * h) / static_cast<float>(h);
      const float eta = static_cast<float>(y - origin_y_ - ey * h) / static_cast<float>(h);
      Pixel p{static_cast<float>(x),
              static_cast<float>(y),
              {(1 - xi) * (1 - eta), xi * (1 - eta), (1 - xi) * eta, xi * eta},
              fr[x],
              gxr[x],
              gyr[x],
              ey * cols_ + ex};
      ++count[static_cast<std::size_t>(p.element)];
      unsorted.push_back(p);
    }
  }
  element_pixel_begin_.assign(static_cast<std::size_t>(elements) + 1, 0);
  for (int e = 0; e < elements; ++e)
    element_pixel_begin_[static_cast<std::size_t>(e) + 1] =
        element_pixel_begin_[static_cast<std::size_t>(e)] + count[static_cast<std::size_t>(e)];
  pixels_.resize(unsorted.size());
  {
    std::vector<int> next(element_pixel_begin_.begin(), element_pixel_begin_.end() - 1);
    for (const Pixel& p : unsorted)
      pixels_[static_cast<std::size_t>(next[static_cast<std::size_t>(p.element)]++)] = p;
  }

  // Nodes of every element that holds pixels.
  grid_node_.assign(static_cast<std::size_t>((cols_ + 1) * (rows_ + 1)), -1);
  element_nodes_.assign(static_cast<std::size_t>(elements) * 4, -1);
  element_has_data_.assign(static_cast<std::size_t>(elements), 0);
  for (int e = 0; e < elements; ++e) {
    if (count[static_cast<std::size_t>(e)] == 0) continue;
    const int ex = e % cols_, ey = e / cols_;
    const int corner[4] = {ey * (cols_ + 1) + ex, ey * (cols_ + 1) + ex + 1, (ey + 1) * (cols_ + 1) + ex,
                           (ey + 1) * (cols_ + 1) + ex + 1};
    for (int k = 0; k < 4; ++k) {
      int& node = grid_node_[static_cast<std::size_t>(corner[k])];
      if (node < 0) {
        node = static_cast<int>(node_x_.size());
        node_x_.push_back(origin_x_ + (corner[k] % (cols_ + 1)) * h);
        node_y_.push_back(origin_y_ + (corner[k] / (cols_ + 1)) * h);
      }
      element_nodes_[static_cast<std::size_t>(e) * 4 + static_cast<std::size_t>(k)] = node;
    }
    element_has_data_[static_cast<std::size_t>(e)] =
        count[static_cast<std::size_t>(e)] >= options.min_element_pixels;
  }

  // Each element's full Hessian, and the mean data weight per node of each unknown (for the penalty).
  element_full_.assign(static_cast<std::size_t>(elements), LocalMatrix::Zero());
  std::vector<double> diagonal(static_cast<std::size_t>(node_count() * dofs), 0.0);
  double j[16];
  for (int e = 0; e < elements; ++e) {
    LocalMatrix& m = element_full_[static_cast<std::size_t>(e)];
    for (int i = element_pixel_begin_[static_cast<std::size_t>(e)];
         i < element_pixel_begin_[static_cast<std::size_t>(e) + 1]; ++i) {
      const Pixel& p = pixels_[static_cast<std::size_t>(i)];
      jacobian_row(p.n, p.f, p.gx, p.gy, dofs, j);
      for (int r = 0; r < 4 * dofs; ++r)
        for (int c = r; c < 4 * dofs; ++c) m(r, c) += j[r] * j[c];
    }
    for (int r = 0; r < 4 * dofs; ++r)
      for (int c = 0; c < r; ++c) m(r, c) = m(c, r);
    if (!element_has_data_[static_cast<std::size_t>(e)]) continue;
    for (int k = 0; k < 4; ++k)
      for (int d = 0; d < dofs; ++d)
        diagonal[static_cast<std::size_t>(
            element_nodes_[static_cast<std::size_t>(e) * 4 + static_cast<std::size_t>(k)] * dofs + d)] +=
            m(k * dofs + d, k * dofs + d);
  }
  std::vector<double> weight(static_cast<std::size_t>(dofs), 0.0);
  for (int d = 0; d < dofs; ++d) {
    double sum = 0.0;
    for (int n = 0; n < node_count(); ++n) sum += diagonal[static_cast<std::size_t>(n * dofs + d)];
    const double mean = sum / std::max(1, node_count());
    weight[static_cast<std::size_t>(d)] = mean * (d < 2 ? options.smoothness : options.brightness_smoothness);
  }

  // Second differences along mesh lines (a linear field, i.e. uniform strain, costs nothing), plus a
  // vanishing ridge on every unknown so that a node without data is still determined by its lines.
  std::vector<Triplet> reg;
  const auto line = [&](int a, int b, int c) {
    if (a < 0 || b < 0 || c < 0) return;
    const int nodes[3] = {a, b, c};
    const double coeff[3] = {1.0, -2.0, 1.0};
    for (int d = 0; d < dofs; ++d)
      for (int r = 0; r < 3; ++r)
        for (int s = 0; s < 3; ++s)
          reg.emplace_back(nodes[r] * dofs + d, nodes[s] * dofs + d,
                           weight[static_cast<std::size_t>(d)] * coeff[r] * coeff[s]);
  };
  const auto node_at = [&](int gx_, int gy_) {
    if (gx_ < 0 || gy_ < 0 || gx_ > cols_ || gy_ > rows_) return -1;
    return grid_node_[static_cast<std::size_t>(gy_ * (cols_ + 1) + gx_)];
  };
  for (int y = 0; y <= rows_; ++y)
    for (int x = 0; x <= cols_; ++x) {
      line(node_at(x - 1, y), node_at(x, y), node_at(x + 1, y));
      line(node_at(x, y - 1), node_at(x, y), node_at(x, y + 1));
    }
  const int unknowns = node_count() * dofs;
  regulariser_.resize(unknowns, unknowns);
  regulariser_.setFromTriplets(reg.begin(), reg.end());
  brightness_.assign(static_cast<std::size_t>(node_count()) * 2, 0.0);
  element_transform_.assign(static_cast<std::size_t>(elements), {1.0, 0.0, 0.0, 1.0});
}

void MeshCorrelation::assemble(const std::vector<char>& valid) {
  const int dofs = dofs_per_node();
  const int unknowns = node_count() * dofs;
  std::vector<Triplet> t;
  t.reserve(element_full_.size() * 16 * dofs * dofs + unknowns);
  double j[16];
  double ridge = 0.0;
  for (int i = 0; i < regulariser_.outerSize(); ++i) ridge = std::max(ridge, regulariser_.coeff(i, i));
  for (std::size_t e = 0; e < element_full_.size(); ++e) {
    if (element_nodes_[e * 4] < 0) continue;
    const int begin = element_pixel_begin_[e], end = element_pixel_begin_[e + 1];
    LocalMatrix m = LocalMatrix::Zero();
    if (element_has_data_[e]) {
      const bool all = std::all_of(valid.begin() + begin, valid.begin() + end, [](char v) { return v != 0; });
      if (all && !options_.update_gradient) {
        m = element_full_[e];
      } else {
        for (int i = begin; i < end; ++i) {
          if (!valid[static_cast<std::size_t>(i)]) continue;
          const Pixel& p = pixels_[static_cast<std::size_t>(i)];
          const auto& t = element_transform_[e];
          jacobian_row(p.n, p.f, static_cast<float>(t[0] * p.gx + t[1] * p.gy),
                       static_cast<float>(t[2] * p.gx + t[3] * p.gy), dofs, j);
          for (int r = 0; r < 4 * dofs; ++r)
            for (int c = r; c < 4 * dofs; ++c) m(r, c) += j[r] * j[c];
        }
      }
    }
    for (int r = 0; r < 16; ++r)
      for (int c = 0; c < r; ++c) m(r, c) = m(c, r);
    for (int a = 0; a < 4; ++a)
      for (int b = 0; b < 4; ++b)
        for (int da = 0; da < dofs; ++da)
          for (int db = 0; db < dofs; ++db)
            t.emplace_back(element_nodes_[e * 4 + static_cast<std::size_t>(a)] * dofs + da,
                           element_nodes_[e * 4 + static_cast<std::size_t>(b)] * dofs + db,
                           m(a * dofs + da, b * dofs + db));
  }
  for (int k = 0; k < regulariser_.outerSize(); ++k)
    for (Eigen::SparseMatrix<double>::InnerIterator it(regulariser_, k); it; ++it)
      t.emplace_back(static_cast<int>(it.row()), static_cast<int>(it.col()), it.value());
  for (int i = 0; i < unknowns; ++i) t.emplace_back(i, i, 1e-6 * std::max(ridge, 1e-12));
  system_.resize(unknowns, unknowns);
  system_.setFromTriplets(t.begin(), t.end());
  if (!analysed_) {
    solver_.analyzePattern(system_);
    analysed_ = true;
  }
  solver_.factorize(system_);
  assembled_valid_ = valid;
}

MeshCorrelationResult MeshCorrelation::solve(const cv::Mat& current, const cv::Mat& current_mask,
                                             std::vector<Vec2>& displacement_px) {
  if (current.type() != CV_32F ||
      (!current_mask.empty() && (current_mask.type() != CV_8U || current_mask.size() != current.size())))
    throw Error("MeshCorrelation::solve: needs a CV_32F frame and a CV_8U mask of the same size");
  if (static_cast<int>(displacement_px.size()) != node_count())
    throw Error("MeshCorrelation::solve: one displacement per node expected");
  const int dofs = dofs_per_node();
  const int unknowns = node_count() * dofs;
  const float* data = current.ptr<float>();
  const std::size_t step = current.step1();
  const int cols = current.cols, rows = current.rows;
  std::vector<char> valid(pixels_.size(), 0);
  // Nodes that see data this iteration; the others follow their mesh lines and do not decide convergence.
  std::vector<char> supported(static_cast<std::size_t>(node_count()), 0);
  Eigen::VectorXd state(unknowns), gradient(unknowns);
  for (int n = 0; n < node_count(); ++n) {
    state(n * dofs) = displacement_px[static_cast<std::size_t>(n)].x;
    state(n * dofs + 1) = displacement_px[static_cast<std::size_t>(n)].y;
    if (dofs == 4) {
      state(n * dofs + 2) = brightness_[static_cast<std::size_t>(n) * 2];
      state(n * dofs + 3) = brightness_[static_cast<std::size_t>(n) * 2 + 1];
    }
  }
  MeshCorrelationResult result;
  double j[16];
  for (int it = 0; it < options_.max_iterations; ++it) {
    gradient.setZero();
    std::fill(supported.begin(), supported.end(), 0);
    double sum_r2 = 0.0;
    int used = 0;
    for (std::size_t e = 0; e + 1 < element_pixel_begin_.size(); ++e) {
      if (element_nodes_[e * 4] < 0 || !element_has_data_[e]) continue;
      const int* nodes = &element_nodes_[e * 4];
      double u[4], v[4], a[4], b[4];
      for (int k = 0; k < 4; ++k) {
        u[k] = state(nodes[k] * dofs);
        v[k] = state(nodes[k] * dofs + 1);
        a[k] = dofs == 4 ? state(nodes[k] * dofs + 2) : 0.0;
        b[k] = dofs == 4 ? state(nodes[k] * dofs + 3) : 0.0;
      }
      // Optionally the current image's gradient at the warped pixel ≈ F⁻ᵀ ∇f (F of the element's bilinear
      // field at its centre), for the case where the skin's rotation turns across-ridge information into the
      // weak along-ridge direction; on the goal trial it changed nothing (BENCHMARKS.md). A folded element
      // keeps the reference gradient.
      auto& t = element_transform_[e];
      if (options_.update_gradient) {
        const double h = options_.element_px;
        const double uxx = 1.0 + ((u[1] - u[0]) + (u[3] - u[2])) / (2 * h),
                     uxy = ((u[2] - u[0]) + (u[3] - u[1])) / (2 * h);
        const double vxx = ((v[1] - v[0]) + (v[3] - v[2])) / (2 * h),
                     vyy = 1.0 + ((v[2] - v[0]) + (v[3] - v[1])) / (2 * h);
        const double det = uxx * vyy - uxy * vxx;
        // F = [[uxx, uxy], [vxx, vyy]]; F⁻ᵀ = [[vyy, −vxx], [−uxy, uxx]] / det
        t = det > 0.1 ? std::array<double, 4>{vyy / det, -vxx / det, -uxy / det, uxx / det}
                      : std::array<double, 4>{1.0, 0.0, 0.0, 1.0};
      }
      double local[16] = {};
      bool any_valid = false;
      for (int i = element_pixel_begin_[e]; i < element_pixel_begin_[e + 1]; ++i) {
        const Pixel& p = pixels_[static_cast<std::size_t>(i)];
        const double ux = p.n[0] * u[0] + p.n[1] * u[1] + p.n[2] * u[2] + p.n[3] * u[3];
        const double uy = p.n[0] * v[0] + p.n[1] * v[1] + p.n[2] * v[2] + p.n[3] * v[3];
        const double x = p.x + ux, y = p.y + uy;
        char ok = x >= 1.0 && y >= 1.0 && x < cols - 2 && y < rows - 2;
        if (ok && !current_mask.empty())
          ok = current_mask.ptr<std::uint8_t>(static_cast<int>(y + 0.5))[static_cast<int>(x + 0.5)] != 0;
        valid[static_cast<std::size_t>(i)] = ok;
        if (!ok) continue;
        const int ix = static_cast<int>(x), iy = static_cast<int>(y);
        const float g =
            flow::detail::interpolate_keys(data + static_cast<std::size_t>(iy - 1) * step + (ix - 1), step,
                                           static_cast<float>(x - ix), static_cast<float>(y - iy));
        const double gain = p.n[0] * a[0] + p.n[1] * a[1] + p.n[2] * a[2] + p.n[3] * a[3];
        const double offset = p.n[0] * b[0] + p.n[1] * b[1] + p.n[2] * b[2] + p.n[3] * b[3];
        const double r = g - (1.0 + gain) * p.f - offset;
        jacobian_row(p.n, p.f, static_cast<float>(t[0] * p.gx + t[1] * p.gy),
                     static_cast<float>(t[2] * p.gx + t[3] * p.gy), dofs, j);
        for (int q = 0; q < 4 * dofs; ++q) local[q] += j[q] * r;
        sum_r2 += r * r;
        ++used;
        any_valid = true;
      }
      if (any_valid)
        for (int k = 0; k < 4; ++k) supported[static_cast<std::size_t>(nodes[k])] = 1;
      for (int k = 0; k < 4; ++k)
        for (int d = 0; d < dofs; ++d) gradient(nodes[k] * dofs + d) += local[k * dofs + d];
    }
    if (used == 0) break;
    // The pixel set settles in the first iterations; later flips of a few border pixels only leave those
    // pixels out of the gradient (the modified Gauss–Newton Hessian need not be exact).
    if (!analysed_ || options_.update_gradient || (it < 2 && valid != assembled_valid_)) {
      assemble(valid);
      ++result.refactorisations;
    }
    gradient += regulariser_ * state;
    const Eigen::VectorXd delta = -solver_.solve(gradient);
    if (!delta.allFinite()) throw Error("MeshCorrelation::solve: the Gauss–Newton step is not finite");
    state += delta;
    double largest = 0.0;
    for (int n = 0; n < node_count(); ++n)
      if (supported[static_cast<std::size_t>(n)])
        largest = std::max(largest, std::hypot(delta(n * dofs), delta(n * dofs + 1)));
    result.iterations = it + 1;
    result.pixels_used = used;
    result.rms_residual = std::sqrt(sum_r2 / used);
    if (largest < options_.convergence_px) {
      result.converged = true;
      break;
    }
  }
  for (int n = 0; n < node_count(); ++n) {
    displacement_px[static_cast<std::size_t>(n)] = {state(n * dofs), state(n * dofs + 1)};
    if (dofs == 4) {
      brightness_[static_cast<std::size_t>(n) * 2] = state(n * dofs + 2);
      brightness_[static_cast<std::size_t>(n) * 2 + 1] = state(n * dofs + 3);
    }
  }
  return result;
}

bool MeshCorrelation::displacement_at(const std::vector<Vec2>& displacement_px, Vec2 X, Vec2& u) const {
  const double h = options_.element_px;
  const double fx = (X.x - origin_x_) / h, fy = (X.y - origin_y_) / h;
  if (!(fx >= 0.0 && fy >= 0.0 && fx < cols_ && fy < rows_)) return false;
  const int ex = static_cast<int>(fx), ey = static_cast<int>(fy);
  const std::size_t e = static_cast<std::size_t>(ey * cols_ + ex);
  if (element_nodes_[e * 4] < 0 || !element_has_data_[e]) return false;
  const double xi = fx - ex, eta = fy - ey;
  const double n[4] = {(1 - xi) * (1 - eta), xi * (1 - eta), (1 - xi) * eta, xi * eta};
  u = {0.0, 0.0};
  for (int k = 0; k < 4; ++k) {
    const Vec2 d =
        displacement_px[static_cast<std::size_t>(element_nodes_[e * 4 + static_cast<std::size_t>(k)])];
    u.x += n[k] * d.x;
    u.y += n[k] * d.y;
  }
  return true;
}

}  // namespace tirstrain::studies
