#pragma once
// Subset matching against a reference (anchor) frame, as in digital image correlation: a square subset of
// the reference image, masked to the contact, is warped by a shape function (translation, affine or
// second-order) and matched to the current frame by inverse-compositional Gauss–Newton (IC-GN) on the
// zero-normalised sum of squared differences, which is insensitive to a local offset and gain of the
// illumination. IC-GN keeps the Hessian of the reference subset fixed, so a match costs one interpolation
// pass per iteration; pixels whose warped position leaves the current contact are removed from the sums
// (and their share subtracted from the Hessian), so a subset straddling the fixed contact border is never
// pulled towards zero motion by the background.
#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <vector>

#include "core/tensor2.hpp"
#include "flow/bspline.hpp"
#include "flow/pixel_classes.hpp"

namespace tirstrain {
class Archive;
}

namespace tirstrain::flow {

namespace detail {
class Sampler;
}

enum class ShapeFunction : std::uint8_t {
  kTranslation = 2,  // u, v
  kAffine = 6,       // + first derivatives
  kQuadratic = 12,   // + second derivatives: follows the curvature of the field inside the subset
};

inline int parameter_count(ShapeFunction shape) {
  return static_cast<int>(shape);
}

// Displacement of the subset's pixels as a function of their offset ξ from the subset centre, in the
// anchor frame: u(ξ) = u + ux ξx + uy ξy + ½ uxx ξx² + uxy ξx ξy + ½ uyy ξy² (and v alike).
// Parameter order: u, v, ux, uy, vx, vy, uxx, uxy, uyy, vxx, vxy, vyy (the first N are used).
struct Warp {
  std::array<double, 12> p{};

  Vec2 displacement_px(double dx, double dy) const {
    return {p[0] + p[2] * dx + p[3] * dy + 0.5 * p[6] * dx * dx + p[7] * dx * dy + 0.5 * p[8] * dy * dy,
            p[1] + p[4] * dx + p[5] * dy + 0.5 * p[9] * dx * dx + p[10] * dx * dy + 0.5 * p[11] * dy * dy};
  }
  // du/dξ at ξ (dimensionless).
  Gradient2 gradient(double dx, double dy) const {
    return {p[2] + p[6] * dx + p[7] * dy, p[3] + p[7] * dx + p[8] * dy, p[4] + p[9] * dx + p[10] * dy,
            p[5] + p[10] * dx + p[11] * dy};
  }
  // Moves the whole subset so that offset ξ lands at displacement `u` (keeps the gradient terms).
  void set_displacement_at(double dx, double dy, Vec2 u) {
    const Vec2 now = displacement_px(dx, dy);
    p[0] += u.x - now.x;
    p[1] += u.y - now.y;
  }
};

// A frame prepared for use as an anchor: float image (full scale 1), its gradients and its contact mask.
class AnchorImage {
 public:
  // `image` CV_32F; `mask` CV_8U (non-zero = usable) of the same size, or empty (everything usable). The
  // mask is eroded by 1 px: the gradient (3×3 Sobel) of a pixel on the border sees the background.
  void assign(const cv::Mat& image, const cv::Mat& mask);
  const cv::Mat& image() const { return image_; }
  const cv::Mat& gx() const { return gx_; }
  const cv::Mat& gy() const { return gy_; }
  const cv::Mat& mask() const { return mask_; }
  // Its state in a checkpoint (core/archive.hpp).
  void archive(Archive& a);

 private:
  cv::Mat image_, gx_, gy_, mask_;
};

// What a translation step on a resampled frame reads from one subset window (Subset::translation_step), for
// every window at once: the per-pixel products of the anchor with the resampled frame g, over the anchor's
// mask, accumulated into integral images on one stride's lattice. A window's sums are then four lookups
// instead of a pass over its pixels: at the automatic preset's 9 px spacing and 20 px radius a pixel lies in
// about twenty windows, so one pass over the region replaces about twenty.
class WindowSums {
 public:
  struct Window {
    double mask = 0;     // anchor pixels in the window (must equal the subset's pixel count)
    double outside = 0;  // of those, where `valid` has no resampled value
    double g = 0, gg = 0, ig = 0, gxg = 0, gyg = 0;  // Σg, Σg², Σ I g, Σ ∂xI g, Σ ∂yI g where valid
  };
  // Over `region` (clipped to the image), windows sampled every `stride` pixels. `resampled` CV_32F and
  // `valid` CV_8U, both the anchor's size (resample_through, flow/shape_field.hpp).
  // Only the lattices in `classes` are summed (a window on another one finds no pixels).
  void build(const AnchorImage& anchor, const cv::Mat& resampled, const cv::Mat& valid, cv::Rect region,
             int stride, const PixelClasses& classes = PixelClasses());
  int stride() const { return stride_; }
  // The sums over the window of `radius` around `centre`, on the same pixels Subset::build takes (every
  // stride-th, inside the image less its 1 px border). False when the window reaches past the region's side
  // where that side is not the image's.
  bool window(cv::Point centre, int radius, Window& out) const {
    return window(centre, {-radius, -radius}, radius, out);
  }
  // The same for a window whose lattice starts at centre + first (first.x, first.y in [−radius, 0]).
  bool window(cv::Point centre, cv::Point first, int radius, Window& out) const;

 private:
  static constexpr int kChannels = 7;
  // One integral image per summed lattice class (x mod stride, y mod stride), on that lattice's own pixels:
  // a full-resolution table with a quarter of its cells used (stride 2) was mostly zeroing (7 % of the
  // tracker's instructions on the goal trial).
  double at(int plane, int j, int i, int c) const {
    return sums_[((static_cast<std::size_t>(plane) * static_cast<std::size_t>(plane_rows_) +
                   static_cast<std::size_t>(j)) *
                      static_cast<std::size_t>(plane_cols_) +
                  static_cast<std::size_t>(i)) *
                     kChannels +
                 static_cast<std::size_t>(c)];
  }
  cv::Rect region_;
  cv::Size image_;
  int stride_ = 0;
  int plane_cols_ = 0,
      plane_rows_ = 0;               // a plane: ceil(region / stride) lattice points plus a zero row/column
  std::vector<int> plane_of_class_;  // per class (cy · stride + cx): its plane, or −1 when not summed
  std::vector<double> sums_;
};

struct MatchOptions {
  int max_iterations = 20;       // Gauss–Newton iterations at most; default 20
  double convergence_px = 2e-3;  // largest change of the displacement over the subset in the last step
  // ... or the last step changed the normalised SSD by less than this: along the ridges a subset barely
  // constrains the motion and Gauss–Newton creeps there; such a match is converged in every direction the
  // texture determines, and what it leaves undetermined is weighted down by translation_information().
  double convergence_ssd = 1e-6;
  double min_valid_fraction = 0.5;  // less of the subset inside the current mask and image: no match; 0.5
  // Solve for the translation only and keep the warp's shape (its gradient and curvature terms, e.g. taken
  // from the neighbours) fixed: the shape terms are correlated with the along-ridge translation, so with
  // them free the noise of both frames moves a subset along its ridges several times further.
  bool translation_only = false;
  // How the current frame is read between pixels; for the B-spline the caller passes the frame's spline
  // coefficients (cubic_bspline_coefficients) as `current`.
  Interpolation interpolation = Interpolation::kKeys;
  // Throws Error naming the first value out of range.
  void check() const;
};

struct MatchResult {
  bool converged = false;
  int iterations = 0;
  double zncc = 0.0;            // zero-normalised cross-correlation at the solution, in [-1, 1]
  double valid_fraction = 0.0;  // share of the reference subset still inside the current mask and image
  bool degenerate = false;      // too few pixels or no texture left to solve for the parameters
};

class Subset {
 public:
  // Builds the reference subset of (2 radius + 1)² pixels (every `stride`-th pixel) around the integer
  // centre. Returns false (and stays empty) when fewer than `min_pixels` are inside the anchor's mask or
  // the texture cannot determine the shape function's parameters.
  // Where the every-stride-th pixels lie: on the window's own lattice (from its corner, centre − radius) or
  // on the image's (multiples of the stride, so that subsets whose centres differ by an odd amount still
  // read the same pixels; the window is then symmetric but one sample shorter per odd side).
  enum class Lattice { kWindow, kImage };
  bool build(const AnchorImage& anchor, cv::Point centre, int radius_px, int stride, ShapeFunction shape,
             int min_pixels, Lattice lattice = Lattice::kWindow);
  // The first sample's offset from the centre (−radius each way on the window's lattice).
  cv::Point first_offset() const { return first_; }
  bool empty() const { return count_ == 0; }
  cv::Point centre() const { return centre_; }
  int radius_px() const { return radius_px_; }
  int stride() const { return stride_; }
  ShapeFunction shape() const { return shape_; }
  std::size_t pixel_count() const { return count_; }
  // Frees the per-pixel copy of the reference and keeps the sums: what the box-sum translation step needs
  // (translation_step reads the reference from the anchor). match() and correlation() then report a
  // degenerate subset until it is built again.
  //
  // Why: a wide subset holds ~9 kB of pixels, and seeding ~1500 of them put ~3000 fresh pages in the first
  // frame, at ~12 µs a page fault on the CI's virtual machines.
  void release_pixels() { std::vector<Pixel>().swap(points_); }
  bool has_pixels() const { return !points_.empty(); }
  // How well the subset's texture pins down its translation (2×2, the Hessian's translation block with the
  // other shape parameters eliminated), normalised by the texture's energy: large across the ridges, small
  // along them.
  const Eigen::Matrix2d& translation_information() const { return information_; }
  // Σ f² over the subset's pixels (each minus the subset's mean): what the informations are normalised by.
  double reference_energy() const { return sum_ff_; }
  // The same with the shape fixed (the Hessian's translation block, normalised alike): what a
  // translation_only match pins down.
  const Eigen::Matrix2d& fixed_shape_information() const { return fixed_information_; }

  // Refines `warp` (in/out) so that the subset matches `current` (CV_32F) where `current_mask` (CV_8U, may
  // be empty) allows. The warp's unused parameters (beyond the shape function) are left at zero.
  MatchResult match(const cv::Mat& current, const cv::Mat& current_mask, Warp& warp,
                    const MatchOptions& options) const;
  // One translation-only Gauss–Newton step of a match whose shape is already applied: `resampled` (CV_32F,
  // anchor coordinates) holds the current frame at each anchor pixel's warped position and `valid` (CV_8U)
  // says where it has one (resample_through, flow/shape_field.hpp). `step_px` is the inverse-compositional
  // step Δ: the warp's argument moves by it, W(ξ) ← W(ξ − Δ). `converged` in the result: a step was
  // computed (its zncc is at the warp before the step). The reference pixels are read from `anchor`, which
  // must be the one the subset was built from (else: degenerate): overlapping subsets then share them in
  // cache instead of each streaming its own copy.
  MatchResult translation_step(const AnchorImage& anchor, const cv::Mat& resampled, const cv::Mat& valid,
                               double min_valid_fraction, Vec2& step_px) const;
  // The same step with the window's sums looked up in `sums` (built from the same anchor, resampled frame
  // and valid mask) when its stride is the subset's, the window lies in its region and every pixel has a
  // resampled value; otherwise the pass over the window above.
  MatchResult translation_step(const WindowSums& sums, const AnchorImage& anchor, const cv::Mat& resampled,
                               const cv::Mat& valid, double min_valid_fraction, Vec2& step_px) const;
  // ZNCC of the subset against `current` at `warp`, without iterating.
  double correlation(const cv::Mat& current, const cv::Mat& current_mask, const Warp& warp,
                     Interpolation kernel = Interpolation::kKeys) const;
  // Its state in a checkpoint (core/archive.hpp).
  void archive(Archive& a);

 private:
  struct Pixel {
    float dx, dy;  // offset from the centre
    float f;       // reference intensity minus the subset mean
    float gx, gy;  // reference gradient
  };
  using Vector = Eigen::Matrix<double, 12, 1>;
  using Matrix = Eigen::Matrix<double, 12, 12>;
  // A translation step's sums: over the visible pixels (g terms) and over the masked-out ones (the rest).
  struct StepSums {
    double h_xx = 0, h_xy = 0, h_yy = 0, sj_x = 0, sj_y = 0, sjf_x = 0, sjf_y = 0, sf_out = 0, sff_out = 0;
    double sjg_x = 0, sjg_y = 0, sg = 0, sgg = 0, sfg = 0;
    long outside = 0;
  };
  MatchResult solve_translation(const StepSums& sums, double min_valid_fraction, Vec2& step_px) const;
  // An IC-GN iteration's sums (match()): over the visible pixels (g terms) and the masked-out ones (_out).
  struct IterationSums {
    Matrix h_out;
    Vector sj_out, sjf_out, sjg;
    double sf_out = 0, sff_out = 0, sg = 0, sgg = 0, sfg = 0;
    long outside = 0;
    void reset();
  };
  bool is_pure_translation(const Warp& warp) const;
  template <int N>
  void accumulate(const detail::Sampler& image, const cv::Mat& current, const cv::Mat& current_mask,
                  const Warp& warp, bool pure_translation, IterationSums& sums) const;
  bool gauss_newton_step(const IterationSums& sums, const Vector& b, int n, bool translation_only,
                         Vector& dp) const;
  double largest_corner_step(const Vector& dp, int n) const;

  std::vector<Pixel> points_;
  std::size_t count_ = 0;  // the pixels build() took (points_ may have been released)
  cv::Point centre_{0, 0};
  cv::Point first_{0, 0};
  int radius_px_ = 0;
  int stride_ = 1;
  double mean_ = 0.0;  // of the reference pixels (points_ hold them minus this)
  ShapeFunction shape_ = ShapeFunction::kAffine;
  // Sums over the whole reference subset, so the common case (nothing masked) needs no per-match setup.
  // n × n for the shape function's n parameters, on the heap: at 12 × 12 inline they were 4.6 kB of each
  // track's 5.6 kB state, fresh memory to fault in for every track seeded or born.
  Eigen::MatrixXd hessian_, hessian_inverse_;
  Vector sum_j_ = Vector::Zero();
  Vector sum_jf_ = Vector::Zero();
  double sum_ff_ = 0.0;
  Eigen::Matrix2d information_ = Eigen::Matrix2d::Zero();
  Eigen::Matrix2d fixed_information_ = Eigen::Matrix2d::Zero();
};

// The mask a match should test warped pixels against: the contact eroded by the 2 px reach of the bicubic
// kernel, so that no interpolated value mixes in the (static) background.
void erode_for_matching(const cv::Mat& mask, cv::Mat& out);

// Keys bicubic interpolation (a = −0.5) of a CV_32F image; false if the 4×4 support leaves the image.
bool sample_bicubic(const cv::Mat& image, double x, double y, float& value);

}  // namespace tirstrain::flow
