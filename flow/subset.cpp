#include "flow/subset.hpp"

#include <Eigen/Dense>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>

#include "core/archive.hpp"
#include "core/error.hpp"
#include "flow/bicubic.hpp"
#include "flow/detail/eigen_archive.hpp"

namespace tirstrain::flow {
namespace {

using Vector12 = Eigen::Matrix<double, 12, 1>;
// Directions of the scaled Hessian weaker than this fraction of the strongest are not solved for.
constexpr double kEigenFloor = 2e-3;

// Steepest-descent image of one reference pixel: ∇f · ∂W/∂p at p = 0.
inline void jacobian(float dx, float dy, float gx, float gy, double j[12]) {
  j[0] = gx;
  j[1] = gy;
  j[2] = gx * dx;
  j[3] = gx * dy;
  j[4] = gy * dx;
  j[5] = gy * dy;
  j[6] = 0.5 * gx * dx * dx;
  j[7] = gx * dx * dy;
  j[8] = 0.5 * gx * dy * dy;
  j[9] = 0.5 * gy * dx * dx;
  j[10] = gy * dx * dy;
  j[11] = 0.5 * gy * dy * dy;
}

// f.operator()<N>() with N the shape function's parameter count (2, 6 or 12): sums and solves on fixed-size
// blocks (runtime-sized ones took several times the instructions).
template <class F>
decltype(auto) with_parameter_count(int n, F&& f) {
  if (n == 2) return f.template operator()<2>();
  if (n == 6) return f.template operator()<6>();
  return f.template operator()<12>();
}

// Least-squares fit of a quadratic c0 + c1 a + c2 b + c3 a² + c4 ab + c5 b² to samples on {-1, 0, 1}².
const Eigen::Matrix<double, 6, 9>& quadratic_fit() {
  static const Eigen::Matrix<double, 6, 9> fit = [] {
    Eigen::Matrix<double, 9, 6> basis;
    int k = 0;
    for (int b = -1; b <= 1; ++b)
      for (int a = -1; a <= 1; ++a, ++k) basis.row(k) << 1, a, b, a * a, a * b, b * b;
    return Eigen::Matrix<double, 6, 9>((basis.transpose() * basis).inverse() * basis.transpose());
  }();
  return fit;
}

// W(ξ; p) ← W(W⁻¹(ξ; Δp); p). Exact for translation and affine warps; for the second-order warp the
// composite (a quartic) is projected back onto the quadratic shape function by a fit on nine nodes spanning
// the subset. At convergence Δp → 0 and the projection is exact, so the solution does not depend on it.
void compose_inverse(Warp& warp, const Vector12& dp, ShapeFunction shape, double span_px) {
  auto& p = warp.p;
  if (shape == ShapeFunction::kTranslation) {
    p[0] -= dp[0];
    p[1] -= dp[1];
    return;
  }
  if (shape == ShapeFunction::kAffine) {
    Eigen::Matrix2d a, da;
    a << 1 + p[2], p[3], p[4], 1 + p[5];
    da << 1 + dp[2], dp[3], dp[4], 1 + dp[5];
    const Eigen::Matrix2d m = a * da.inverse();
    const Eigen::Vector2d u = Eigen::Vector2d(p[0], p[1]) - m * Eigen::Vector2d(dp[0], dp[1]);
    p[0] = u[0];
    p[1] = u[1];
    p[2] = m(0, 0) - 1;
    p[3] = m(0, 1);
    p[4] = m(1, 0);
    p[5] = m(1, 1) - 1;
    return;
  }
  Warp delta;
  for (int i = 0; i < 12; ++i) delta.p[static_cast<std::size_t>(i)] = dp[i];
  Eigen::Matrix<double, 9, 1> tx, ty;
  int k = 0;
  for (int b = -1; b <= 1; ++b) {
    for (int a = -1; a <= 1; ++a, ++k) {
      const double xi = a * span_px, yi = b * span_px;
      // Solve η + Δu(η) = ξ by fixed-point iteration (Δp is small).
      double ex = xi, ey = yi;
      for (int it = 0; it < 3; ++it) {
        const Vec2 d = delta.displacement_px(ex, ey);
        ex = xi - d.x;
        ey = yi - d.y;
      }
      const Vec2 u = warp.displacement_px(ex, ey);
      tx[k] = ex + u.x - xi;
      ty[k] = ey + u.y - yi;
    }
  }
  const auto& fit = quadratic_fit();
  const Eigen::Matrix<double, 6, 1> cx = fit * tx, cy = fit * ty;
  const double s = span_px, s2 = span_px * span_px;
  p = {cx[0],          cy[0],      cx[1] / s,      cx[2] / s,      cy[1] / s,  cy[2] / s,
       2 * cx[3] / s2, cx[4] / s2, 2 * cx[5] / s2, 2 * cy[3] / s2, cy[4] / s2, 2 * cy[5] / s2};
}

// W(ξ; p) ← W(ξ − Δ; p) for a translation-only step Δ: the same physical warp, re-expanded about the
// shifted reference point (exact for every shape function).
void compose_translation(Warp& warp, double tx, double ty) {
  auto& p = warp.p;
  const Vec2 u = warp.displacement_px(-tx, -ty);
  const Gradient2 g = warp.gradient(-tx, -ty);
  p[0] = u.x - tx;
  p[1] = u.y - ty;
  p[2] = g.xx;
  p[3] = g.xy;
  p[4] = g.yx;
  p[5] = g.yy;
}

// Pseudo-inverse of a Hessian that ignores the directions its texture leaves undetermined: along
// straight ridges the SSD is flat, and a plain inverse turns the smallest model error into a large step
// there (Gauss–Newton then "converges" anywhere along the ridge). Those directions keep their starting
// value, which comes from the prediction and the neighbours. Judged on the Jacobi-scaled matrix because
// the parameters mix px, px/px and px/px².
template <int N>
struct ScaledEigen {
  Eigen::Matrix<double, N, 1> d;                                   // the Jacobi scaling: 1 / sqrt(diag h)
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix<double, N, N>> eig;  // of d h d
  explicit ScaledEigen(const Eigen::Matrix<double, N, N>& h)
      : d(h.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse()),
        eig(d.asDiagonal() * h * d.asDiagonal()) {}
};

template <int N>
Eigen::Matrix<double, N, N> truncated_inverse(const ScaledEigen<N>& s, double relative_floor) {
  const Eigen::Matrix<double, N, 1>& l = s.eig.eigenvalues();
  const double floor = relative_floor * l.maxCoeff();
  Eigen::Matrix<double, N, 1> inv;
  for (int i = 0; i < N; ++i) inv[i] = l[i] > floor ? 1.0 / l[i] : 0.0;
  return s.d.asDiagonal() * (s.eig.eigenvectors() * inv.asDiagonal() * s.eig.eigenvectors().transpose()) *
         s.d.asDiagonal();
}

template <int N>
Eigen::Matrix<double, N, N> truncated_inverse(const Eigen::Matrix<double, N, N>& h, double relative_floor) {
  return truncated_inverse<N>(ScaledEigen<N>(h), relative_floor);
}

// Visits the anchor pixels of a subset window, every `stride`-th, inside the image less its 1 px border (the
// gradient's reach) and inside the anchor's mask, in row order: visit(dx, dy, x, y, value, gx, gy). Subset
// building and the translation step on a resampled frame must agree on exactly these pixels.
template <class Visit>
void for_each_window_pixel(const AnchorImage& anchor, cv::Point centre, cv::Point first, int radius,
                           int stride, Visit&& visit) {
  const cv::Mat& img = anchor.image();
  for (int dy = first.y; dy <= radius; dy += stride) {
    const int y = centre.y + dy;
    if (y < 1 || y >= img.rows - 1) continue;
    const float* row = img.ptr<float>(y);
    const float* gxr = anchor.gx().ptr<float>(y);
    const float* gyr = anchor.gy().ptr<float>(y);
    const std::uint8_t* mrow = anchor.mask().ptr<std::uint8_t>(y);
    for (int dx = first.x; dx <= radius; dx += stride) {
      const int x = centre.x + dx;
      if (x < 1 || x >= img.cols - 1 || mrow[x] == 0) continue;
      visit(dx, dy, x, y, row[x], gxr[x], gyr[x]);
    }
  }
}

// The zero-normalised statistics of a match over its visible pixels: f has zero mean over the whole
// subset, so over the visible pixels its mean is −Σ_out f / count; false when either side has no texture
// left there.
struct Normalisation {
  double f_mean = 0.0, g_mean = 0.0, scale = 0.0, zncc = 0.0;
};

bool normalise(double count, double sum_ff, double sf_out, double sff_out, double sg, double sgg, double sfg,
               Normalisation& n) {
  n.f_mean = -sf_out / count;
  const double df2 = (sum_ff - sff_out) - count * n.f_mean * n.f_mean;
  n.g_mean = sg / count;
  const double dg2 = sgg - count * n.g_mean * n.g_mean;
  if (df2 <= 1e-12 || dg2 <= 1e-12) return false;
  n.scale = std::sqrt(df2 / dg2);
  // ZNCC: Σ(f − f̄)(g − ḡ) with Σ f g taken over the visible pixels only.
  n.zncc = (sfg - count * n.f_mean * n.g_mean) / std::sqrt(df2 * dg2);
  return true;
}

// The translation step −H⁻¹ b of a 2×2 Hessian, unless it is (nearly) singular.
bool translation_step_of(const Eigen::Matrix2d& h, const Eigen::Vector2d& b, Eigen::Vector2d& dp) {
  if (!(h.determinant() > 1e-12 * h.trace() * h.trace())) return false;
  dp = -h.inverse() * b;
  return dp.allFinite();
}

}  // namespace

bool sample_bicubic(const cv::Mat& image, double x, double y, float& value) {
  return detail::Sampler(image, cv::Mat()).sample(x, y, value);
}

void AnchorImage::archive(Archive& a) {
  a(image_, gx_, gy_, mask_);
}

void Subset::archive(Archive& a) {
  a.layout(sizeof(Pixel), "subset pixel");
  a(points_, count_, centre_, first_, radius_px_, stride_, mean_, shape_, hessian_, hessian_inverse_, sum_j_,
    sum_jf_, sum_ff_, information_, fixed_information_);
}

void AnchorImage::assign(const cv::Mat& image, const cv::Mat& mask) {
  CV_Assert(image.type() == CV_32F);
  image.copyTo(image_);
  // Sobel/8 is the central difference smoothed across: at ≥ 20 px ridge periods its gain is within 1 % of
  // the true derivative, and the smoothing halves the noise in the steepest-descent images.
  cv::Sobel(image_, gx_, CV_32F, 1, 0, 3, 1.0 / 8.0, 0.0, cv::BORDER_REPLICATE);
  cv::Sobel(image_, gy_, CV_32F, 0, 1, 3, 1.0 / 8.0, 0.0, cv::BORDER_REPLICATE);
  if (mask.empty())
    mask_ = cv::Mat(image.size(), CV_8U, cv::Scalar(1));
  else
    cv::erode(mask, mask_, cv::Mat(), cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
}

void erode_for_matching(const cv::Mat& mask, cv::Mat& out) {
  cv::erode(mask, out, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(5, 5)), cv::Point(-1, -1), 1,
            cv::BORDER_CONSTANT, cv::Scalar(0));
}

bool Subset::build(const AnchorImage& anchor, cv::Point centre, int radius_px, int stride,
                   ShapeFunction shape, int min_pixels, Lattice lattice) {
  points_.clear();
  count_ = 0;
  centre_ = centre;
  radius_px_ = radius_px;
  shape_ = shape;
  const int n = parameter_count(shape);
  stride = std::max(1, stride);
  stride_ = stride;
  first_ = {-radius_px, -radius_px};
  if (lattice == Lattice::kImage) {
    // The first pixel at or after the window's corner on the image's lattice (multiples of the stride).
    const auto up = [stride](int v) { return ((-v) % stride + stride) % stride; };
    first_ = {-radius_px + up(centre.x - radius_px), -radius_px + up(centre.y - radius_px)};
  }
  // Reserved whole: growing it pixel by pixel reallocated a few times per subset, and with ~3000 subsets
  // built at seeding, the fresh pages' faults were a visible part of the first frame.
  const std::size_t across = static_cast<std::size_t>((radius_px - first_.x) / stride + 1);
  const std::size_t down = static_cast<std::size_t>((radius_px - first_.y) / stride + 1);
  points_.reserve(across * down);
  for_each_window_pixel(anchor, centre, first_, radius_px, stride,
                        [&](int dx, int dy, int, int, float f, float gx, float gy) {
                          points_.push_back({static_cast<float>(dx), static_cast<float>(dy), f, gx, gy});
                        });
  if (static_cast<int>(points_.size()) < std::max(min_pixels, 2 * n)) {
    points_.clear();
    return false;
  }
  double mean = 0.0;
  for (const Pixel& p : points_) mean += p.f;
  mean /= static_cast<double>(points_.size());
  mean_ = mean;
  hessian_.setZero(n, n);
  sum_j_.setZero();
  sum_jf_.setZero();
  sum_ff_ = 0.0;
  // In fixed-size blocks: the runtime-sized outer product made building the plate's subsets, every frame,
  // 3 % of the tracker's instructions.
  const auto accumulate = [&]<int N>() {
    Eigen::Matrix<double, N, N> h = Eigen::Matrix<double, N, N>::Zero();
    Eigen::Matrix<double, N, 1> sj = Eigen::Matrix<double, N, 1>::Zero(), sjf = sj;
    double j[12];
    for (Pixel& p : points_) {
      p.f = static_cast<float>(p.f - mean);
      jacobian(p.dx, p.dy, p.gx, p.gy, j);
      const Eigen::Map<const Eigen::Matrix<double, N, 1>> jv(j);
      h.noalias() += jv * jv.transpose();
      sj += jv;
      sjf += jv * p.f;
      sum_ff_ += static_cast<double>(p.f) * p.f;
    }
    hessian_.template topLeftCorner<N, N>() = h;
    sum_j_.template head<N>() = sj;
    sum_jf_.template head<N>() = sjf;
  };
  with_parameter_count(n, accumulate);
  // Fixed-size blocks: the runtime-sized decompositions were a few percent of a tracking run (births).
  const auto finish = [&]<int N>() {
    using Square = Eigen::Matrix<double, N, N>;
    // The parameters mix units (px, px/px, px/px²): judge the conditioning on the scaled Hessian.
    // One decomposition for both the check and the inverse: two were a sixth of the seeding's instructions.
    const Square h = hessian_.template topLeftCorner<N, N>();
    const ScaledEigen<N> scaled(h);
    if (sum_ff_ <= 1e-12 || scaled.eig.eigenvalues()[0] < 1e-6) return false;
    hessian_inverse_ = truncated_inverse<N>(scaled, kEigenFloor);
    // The inverse of the translation block of H⁻¹ is the Schur complement: the information on (u, v) once
    // the other parameters are free.
    information_ = Eigen::Matrix2d(Square(h.inverse()).template topLeftCorner<2, 2>()).inverse() / sum_ff_;
    fixed_information_ = h.template topLeftCorner<2, 2>() / sum_ff_;
    return true;
  };
  const bool ok = with_parameter_count(n, finish);
  if (!ok) points_.clear();
  count_ = points_.size();
  return ok;
}

double Subset::correlation(const cv::Mat& current, const cv::Mat& current_mask, const Warp& warp,
                           Interpolation kernel) const {
  double sf = 0, sff = 0, sg = 0, sgg = 0, sfg = 0;
  long count = 0;
  const detail::Sampler image(current, current_mask, kernel);
  for (const Pixel& p : points_) {
    const Vec2 u = warp.displacement_px(p.dx, p.dy);
    const double x = centre_.x + p.dx + u.x, y = centre_.y + p.dy + u.y;
    float g;
    if (!image.sample(x, y, g)) continue;
    sf += p.f, sff += static_cast<double>(p.f) * p.f, sg += g, sgg += static_cast<double>(g) * g;
    sfg += static_cast<double>(p.f) * g;
    ++count;
  }
  if (count < 3) return 0.0;
  const double n = static_cast<double>(count);
  const double df2 = sff - sf * sf / n, dg2 = sgg - sg * sg / n;
  if (df2 <= 0 || dg2 <= 0) return 0.0;
  return (sfg - sf * sg / n) / std::sqrt(df2 * dg2);
}

MatchResult Subset::match(const cv::Mat& current, const cv::Mat& current_mask, Warp& warp,
                          const MatchOptions& options) const {
  MatchResult result;
  if (points_.empty()) {
    result.degenerate = true;
    return result;
  }
  const int n_shape = parameter_count(shape_);
  // A translation-only match keeps the whole shape it is given (even beyond the subset's shape function).
  if (!options.translation_only)
    for (int i = n_shape; i < 12; ++i) warp.p[static_cast<std::size_t>(i)] = 0.0;
  // The parameters solved for: all of the shape function's, or the translation alone.
  const int n = options.translation_only ? 2 : n_shape;
  const double total = static_cast<double>(points_.size());
  const detail::Sampler image(current, current_mask, options.interpolation);
  IterationSums sums;
  for (int iter = 1; iter <= options.max_iterations; ++iter) {
    result.iterations = iter;
    const bool pure_translation = n == 2 && is_pure_translation(warp);
    sums.reset();
    with_parameter_count(
        n, [&]<int N>() { accumulate<N>(image, current, current_mask, warp, pure_translation, sums); });
    const double count = total - static_cast<double>(sums.outside);
    result.valid_fraction = count / total;
    if (result.valid_fraction < options.min_valid_fraction || count < 2.0 * n) return result;
    Normalisation norm;
    if (!normalise(count, sum_ff_, sums.sf_out, sums.sff_out, sums.sg, sums.sgg, sums.sfg, norm)) {
      result.degenerate = true;
      return result;
    }
    result.zncc = norm.zncc;  // at the current parameters
    const Vector sj = sum_j_ - sums.sj_out;
    const Vector sjf = sum_jf_ - sums.sjf_out;
    const Vector b = (sjf - norm.f_mean * sj) - norm.scale * (sums.sjg - norm.g_mean * sj);
    Vector dp = Vector::Zero();
    if (!gauss_newton_step(sums, b, n, options.translation_only, dp) || !dp.allFinite()) {
      result.degenerate = true;
      return result;
    }
    if (options.translation_only)
      compose_translation(warp, dp[0], dp[1]);
    else
      compose_inverse(warp, dp, shape_, radius_px_);
    const double largest = largest_corner_step(dp, n);
    const double ssd_change = dp.head(n).dot(hessian_.topLeftCorner(n, n) * dp.head(n)) / sum_ff_;
    // The SSD criterion is for the many-parameter solve creeping along the ridges; a translation-only solve
    // is well posed and cheap, so it iterates until the step itself is small.
    if (largest < options.convergence_px ||
        (!options.translation_only && ssd_change < options.convergence_ssd)) {
      result.converged = true;
      return result;
    }
    // A step of several ridge periods means the iteration is running away, not converging.
    if (largest > 4.0 * radius_px_ + 20.0) return result;
  }
  return result;
}

void Subset::IterationSums::reset() {
  h_out.setZero();
  sj_out.setZero();
  sjf_out.setZero();
  sjg.setZero();
  sf_out = sff_out = sg = sgg = sfg = 0.0;
  outside = 0;
}

// A translation subset under a pure translation (the plate's, into its mosaic) samples every pixel at the
// same fraction of a pixel: TranslatedSampler filters separably instead.
bool Subset::is_pure_translation(const Warp& warp) const {
  if (shape_ != ShapeFunction::kTranslation) return false;
  for (int i = 2; i < 12; ++i)
    if (warp.p[static_cast<std::size_t>(i)] != 0.0) return false;
  return true;
}

// One pass over the subset for N parameters at `warp`. The sums live in locals (registers), not in Eigen
// vectors: the compiler must otherwise store and reload them for every pixel.
template <int N>
void Subset::accumulate(const detail::Sampler& image, const cv::Mat& current, const cv::Mat& current_mask,
                        const Warp& warp, bool pure_translation, IterationSums& sums) const {
  const auto& q = warp.p;
  double j[12];
  double a[N] = {};
  double a_g = 0, a_gg = 0, a_fg = 0;
  const auto take_outside = [&](const Pixel& p) {
    jacobian(p.dx, p.dy, p.gx, p.gy, j);
    const Eigen::Map<const Vector12> jv(j);
    ++sums.outside;
    // Fixed-size blocks: as runtime-sized Eigen blocks these cost 13 % of a tracking run's instructions.
    sums.h_out.template topLeftCorner<N, N>().noalias() +=
        jv.template head<N>() * jv.template head<N>().transpose();
    sums.sj_out.template head<N>() += jv.template head<N>();
    sums.sjf_out.template head<N>() += jv.template head<N>() * p.f;
    sums.sf_out += p.f;
    sums.sff_out += static_cast<double>(p.f) * p.f;
  };
  const auto take_visible = [&](const Pixel& p, double dx, double dy, float g) {
    const double ggx = static_cast<double>(p.gx) * g, ggy = static_cast<double>(p.gy) * g;
    a[0] += ggx;
    a[1] += ggy;
    if constexpr (N > 2) {
      a[2] += ggx * dx;
      a[3] += ggx * dy;
      a[4] += ggy * dx;
      a[5] += ggy * dy;
    }
    if constexpr (N > 6) {
      const double hxx = 0.5 * dx * dx, hxy = dx * dy, hyy = 0.5 * dy * dy;
      a[6] += ggx * hxx;
      a[7] += ggx * hxy;
      a[8] += ggx * hyy;
      a[9] += ggy * hxx;
      a[10] += ggy * hxy;
      a[11] += ggy * hyy;
    }
    a_g += g;
    a_gg += static_cast<double>(g) * g;
    a_fg += static_cast<double>(p.f) * g;
  };
  const auto finish = [&] {
    for (int k = 0; k < N; ++k) sums.sjg[k] = a[k];
    sums.sg = a_g;
    sums.sgg = a_gg;
    sums.sfg = a_fg;
  };
  if constexpr (N == 2) {
    // The plate's subsets: the same shift for every pixel (TranslatedSampler).
    if (pure_translation) {
      detail::TranslatedSampler shifted(current, current_mask, centre_.x + q[0], centre_.y + q[1], first_.x,
                                        radius_px_, image.kernel());
      if (shifted.ok()) {
        for (const Pixel& p : points_) {
          float g = 0.0f;
          if (!shifted.sample(static_cast<int>(p.dx), static_cast<int>(p.dy), g)) {
            take_outside(p);
            continue;
          }
          take_visible(p, p.dx, p.dy, g);
        }
        return finish();
      }
    }
  }
  for (const Pixel& p : points_) {
    const double dx = p.dx, dy = p.dy;
    const double x = centre_.x + dx + q[0] + q[2] * dx + q[3] * dy +
                     (0.5 * q[6] * dx * dx + q[7] * dx * dy + 0.5 * q[8] * dy * dy);
    const double y = centre_.y + dy + q[1] + q[4] * dx + q[5] * dy +
                     (0.5 * q[9] * dx * dx + q[10] * dx * dy + 0.5 * q[11] * dy * dy);
    float g = 0.0f;
    if (!image.sample(x, y, g)) {
      take_outside(p);
      continue;
    }
    take_visible(p, dx, dy, g);
  }
  finish();
}

// The Gauss–Newton step dp from the gradient b: the translation alone; the whole subset's precomputed
// inverse when no pixel is masked out; otherwise the Hessian of the visible pixels, truncated where it is
// nearly singular. False where the Hessian is degenerate.
bool Subset::gauss_newton_step(const IterationSums& sums, const Vector& b, int n, bool translation_only,
                               Vector& dp) const {
  if (translation_only) {
    Eigen::Vector2d step;
    if (!translation_step_of(hessian_.topLeftCorner(2, 2) - sums.h_out.topLeftCorner(2, 2), b.head(2), step))
      return false;
    dp.head(2) = step;
    return true;
  }
  if (sums.outside == 0) {
    dp.head(n).noalias() = -hessian_inverse_.topLeftCorner(n, n) * b.head(n);
    return true;
  }
  return with_parameter_count(n, [&]<int N>() {
    const Eigen::Matrix<double, N, N> hv =
        hessian_.template topLeftCorner<N, N>() - sums.h_out.template topLeftCorner<N, N>();
    if (!(hv.diagonal().minCoeff() > 0.0)) return false;
    dp.template head<N>() = -truncated_inverse<N>(hv, kEigenFloor) * b.template head<N>();
    return true;
  });
}

// Size of a step: the largest change of the displacement at the subset's corners.
double Subset::largest_corner_step(const Vector& dp, int n) const {
  const double r = radius_px_;
  Warp step;
  for (int i = 0; i < n; ++i) step.p[static_cast<std::size_t>(i)] = dp[i];
  double largest = 0.0;
  for (double cy : {-r, r})
    for (double cx : {-r, r}) {
      const Vec2 d = step.displacement_px(cx, cy);
      largest = std::max(largest, std::hypot(d.x, d.y));
    }
  return largest;
}

MatchResult Subset::translation_step(const AnchorImage& anchor, const cv::Mat& resampled,
                                     const cv::Mat& valid, double min_valid_fraction, Vec2& step_px) const {
  step_px = {};
  MatchResult result;
  if (count_ == 0) {
    result.degenerate = true;
    return result;
  }
  const cv::Mat& img = anchor.image();
  CV_Assert(resampled.type() == CV_32F && valid.type() == CV_8U && valid.size() == resampled.size() &&
            resampled.size() == img.size());
  StepSums s;
  long seen = 0;
  const float mean = static_cast<float>(mean_);
  // The same pixels as build() took (for_each_window_pixel's), row by row, summed in float within a row
  // (at most 2·radius + 1 terms) and in double across rows: per-pixel double conversions were most of this
  // loop's time when every subset ran it (WindowSums now serves most).
  const int rows = img.rows, cols = img.cols;
  for (int dy = first_.y; dy <= radius_px_; dy += stride_) {
    const int y = centre_.y + dy;
    if (y < 1 || y >= rows - 1) continue;
    const float* row = img.ptr<float>(y);
    const float* gxr = anchor.gx().ptr<float>(y);
    const float* gyr = anchor.gy().ptr<float>(y);
    const std::uint8_t* mrow = anchor.mask().ptr<std::uint8_t>(y);
    const std::uint8_t* vrow = valid.ptr<std::uint8_t>(y);
    const float* grow = resampled.ptr<float>(y);
    float r_jg_x = 0, r_jg_y = 0, r_g = 0, r_gg = 0, r_fg = 0;
    for (int dx = first_.x; dx <= radius_px_; dx += stride_) {
      const int x = centre_.x + dx;
      if (x < 1 || x >= cols - 1 || mrow[x] == 0) continue;
      ++seen;
      const float f = row[x] - mean, gx = gxr[x], gy = gyr[x];
      if (!vrow[x]) {  // rare: the subset's part outside the resampled field, subtracted from its sums
        ++s.outside;
        s.h_xx += static_cast<double>(gx) * gx;
        s.h_xy += static_cast<double>(gx) * gy;
        s.h_yy += static_cast<double>(gy) * gy;
        s.sj_x += gx;
        s.sj_y += gy;
        s.sjf_x += static_cast<double>(gx) * f;
        s.sjf_y += static_cast<double>(gy) * f;
        s.sf_out += f;
        s.sff_out += static_cast<double>(f) * f;
        continue;
      }
      const float g = grow[x];
      r_jg_x += gx * g;
      r_jg_y += gy * g;
      r_g += g;
      r_gg += g * g;
      r_fg += f * g;
    }
    s.sjg_x += r_jg_x;
    s.sjg_y += r_jg_y;
    s.sg += r_g;
    s.sgg += r_gg;
    s.sfg += r_fg;
  }
  if (seen != static_cast<long>(count_)) {  // not the anchor this subset was built from
    result.degenerate = true;
    return result;
  }
  return solve_translation(s, min_valid_fraction, step_px);
}

MatchResult Subset::translation_step(const WindowSums& sums, const AnchorImage& anchor,
                                     const cv::Mat& resampled, const cv::Mat& valid,
                                     double min_valid_fraction, Vec2& step_px) const {
  WindowSums::Window w;
  if (count_ == 0 || sums.stride() != stride_ || !sums.window(centre_, first_, radius_px_, w) ||
      w.mask != static_cast<double>(count_) || w.outside != 0.0)
    return translation_step(anchor, resampled, valid, min_valid_fraction, step_px);
  step_px = {};
  StepSums s;
  s.sjg_x = w.gxg;
  s.sjg_y = w.gyg;
  s.sg = w.g;
  s.sgg = w.gg;
  s.sfg = w.ig - mean_ * w.g;  // f is the anchor's intensity less the subset's mean
  return solve_translation(s, min_valid_fraction, step_px);
}

MatchResult Subset::solve_translation(const StepSums& s, double min_valid_fraction, Vec2& step_px) const {
  MatchResult result;
  const double total = static_cast<double>(count_);
  const double count = total - static_cast<double>(s.outside);
  result.valid_fraction = count / total;
  result.iterations = 1;
  if (result.valid_fraction < min_valid_fraction || count < 4.0) return result;
  Normalisation norm;
  if (!normalise(count, sum_ff_, s.sf_out, s.sff_out, s.sg, s.sgg, s.sfg, norm)) {
    result.degenerate = true;
    return result;
  }
  result.zncc = norm.zncc;
  const double vj_x = sum_j_[0] - s.sj_x, vj_y = sum_j_[1] - s.sj_y;
  const Eigen::Vector2d b(
      ((sum_jf_[0] - s.sjf_x) - norm.f_mean * vj_x) - norm.scale * (s.sjg_x - norm.g_mean * vj_x),
      ((sum_jf_[1] - s.sjf_y) - norm.f_mean * vj_y) - norm.scale * (s.sjg_y - norm.g_mean * vj_y));
  Eigen::Matrix2d hv;
  hv << hessian_(0, 0) - s.h_xx, hessian_(0, 1) - s.h_xy, hessian_(1, 0) - s.h_xy, hessian_(1, 1) - s.h_yy;
  Eigen::Vector2d dp;
  if (!translation_step_of(hv, b, dp)) {
    result.degenerate = true;
    return result;
  }
  step_px = {dp.x(), dp.y()};
  result.converged = true;
  return result;
}

void WindowSums::build(const AnchorImage& anchor, const cv::Mat& resampled, const cv::Mat& valid,
                       cv::Rect region, int stride, const PixelClasses& classes) {
  const cv::Mat& img = anchor.image();
  CV_Assert(resampled.type() == CV_32F && valid.type() == CV_8U && valid.size() == resampled.size() &&
            resampled.size() == img.size() && stride >= 1);
  image_ = img.size();
  region_ = region & cv::Rect(0, 0, img.cols, img.rows);
  stride_ = stride;
  // Lattice point (i, j) of class (cx, cy) is pixel (x0 + cx' + i·s, y0 + cy' + j·s), where cx' is the
  // class's first column in the region: i = (x − x0) / s for every pixel of the class.
  plane_cols_ = (region_.width + stride - 1) / stride + 1;
  plane_rows_ = (region_.height + stride - 1) / stride + 1;
  plane_of_class_.assign(static_cast<std::size_t>(stride * stride), -1);
  int planes = 0;
  for (int cy = 0; cy < stride; ++cy)
    for (int cx = 0; cx < stride; ++cx)
      if (classes.has_class(cx, cy)) plane_of_class_[static_cast<std::size_t>(cy * stride + cx)] = planes++;
  // Every cell a window or the recurrence reads is written below except the zero row and column: only those
  // are cleared (clearing the whole table was 3 % of the tracker's instructions on the goal trial).
  sums_.resize(static_cast<std::size_t>(planes) * static_cast<std::size_t>(plane_rows_) *
               static_cast<std::size_t>(plane_cols_) * kChannels);
  const std::ptrdiff_t row_step = static_cast<std::ptrdiff_t>(plane_cols_) * kChannels;
  for (int plane = 0; plane < planes; ++plane) {
    double* first = sums_.data() + static_cast<std::ptrdiff_t>(plane) * plane_rows_ * row_step;
    std::fill(first, first + row_step, 0.0);
    for (int j = 1; j < plane_rows_; ++j)
      std::fill(first + j * row_step, first + j * row_step + kChannels, 0.0);
  }
  for (int ry = 0; ry < region_.height; ++ry) {
    const int y = region_.y + ry;
    const int cy = y % stride;
    const bool row_inside = y >= 1 && y < img.rows - 1;
    const float* irow = img.ptr<float>(y);
    const float* gxr = anchor.gx().ptr<float>(y);
    const float* gyr = anchor.gy().ptr<float>(y);
    const std::uint8_t* mrow = anchor.mask().ptr<std::uint8_t>(y);
    const std::uint8_t* vrow = valid.ptr<std::uint8_t>(y);
    const float* grow = resampled.ptr<float>(y);
    const std::ptrdiff_t j = ry / stride + 1;
    for (int cx = 0; cx < stride; ++cx) {
      const int plane = plane_of_class_[static_cast<std::size_t>(cy * stride + cx)];
      if (plane < 0) continue;
      // The class's first pixel in the region, and its lattice cell (past the zero column).
      const int x_first = region_.x + ((cx - region_.x) % stride + stride) % stride;
      double* cell = sums_.data() + (static_cast<std::ptrdiff_t>(plane) * plane_rows_ + j) * row_step +
                     static_cast<std::ptrdiff_t>((x_first - region_.x) / stride + 1) * kChannels;
      // S(j, i) = v + S(j − 1, i) + S(j, i − 1) − S(j − 1, i − 1) on the class's own lattice.
      for (int x = x_first; x < region_.x + region_.width; x += stride, cell += kChannels) {
        double v[kChannels] = {0, 0, 0, 0, 0, 0, 0};
        if (row_inside && x >= 1 && x < img.cols - 1 && mrow[x] != 0) {
          v[0] = 1.0;
          if (vrow[x]) {
            const double g = grow[x];
            v[2] = g;
            v[3] = g * g;
            v[4] = irow[x] * g;
            v[5] = gxr[x] * g;
            v[6] = gyr[x] * g;
          } else {
            v[1] = 1.0;
          }
        }
        const double* above = cell - row_step;
        const double* before = cell - kChannels;
        const double* corner = above - kChannels;
        for (int c = 0; c < kChannels; ++c) cell[c] = v[c] + above[c] + before[c] - corner[c];
      }
    }
  }
}

bool WindowSums::window(cv::Point centre, cv::Point first, int radius, Window& out) const {
  if (stride_ < 1) return false;
  // The window's lattice, [x0, x1] × [y0, y1], cut to the region where the region's side is the image's
  // (nothing lies beyond it); past a side inside the image the table has not seen those pixels.
  int x0 = centre.x + first.x, x1 = x0 + stride_ * ((radius - first.x) / stride_);
  int y0 = centre.y + first.y, y1 = y0 + stride_ * ((radius - first.y) / stride_);
  const int left = region_.x, top = region_.y, right = region_.x + region_.width - 1,
            bottom = region_.y + region_.height - 1;
  const auto cut_low = [&](int& a, int side, bool image_side) {
    if (a >= side) return true;
    if (!image_side) return false;
    a += stride_ * ((side - a + stride_ - 1) / stride_);
    return true;
  };
  const auto cut_high = [&](int& b, int side, bool image_side) {
    if (b <= side) return true;
    if (!image_side) return false;
    b -= stride_ * ((b - side + stride_ - 1) / stride_);
    return true;
  };
  if (!cut_low(x0, left, left == 0) || !cut_low(y0, top, top == 0) ||
      !cut_high(x1, right, right == image_.width - 1) || !cut_high(y1, bottom, bottom == image_.height - 1))
    return false;
  out = Window{};
  if (x1 < x0 || y1 < y0) return true;
  const int plane = plane_of_class_[static_cast<std::size_t>((y0 % stride_) * stride_ + x0 % stride_)];
  if (plane < 0) return true;  // a lattice that was not summed holds no pixels
  // Plane coordinates, past the zero row and column.
  const int i1 = (x1 - left) / stride_ + 1, i0 = (x0 - left) / stride_, j1 = (y1 - top) / stride_ + 1,
            j0 = (y0 - top) / stride_;
  double* fields[kChannels] = {&out.mask, &out.outside, &out.g, &out.gg, &out.ig, &out.gxg, &out.gyg};
  for (int c = 0; c < kChannels; ++c)
    *fields[c] = at(plane, j1, i1, c) - at(plane, j0, i1, c) - at(plane, j1, i0, c) + at(plane, j0, i0, c);
  return true;
}

void MatchOptions::check() const {
  if (max_iterations < 1) throw Error("match options: max_iterations must be at least 1");
  if (!(convergence_px > 0.0)) throw Error("match options: convergence_px must be positive");
  if (!(convergence_ssd >= 0.0)) throw Error("match options: convergence_ssd must not be negative");
  if (!(min_valid_fraction > 0.0 && min_valid_fraction <= 1.0))
    throw Error("match options: min_valid_fraction must lie in (0, 1]");
}

}  // namespace tirstrain::flow
