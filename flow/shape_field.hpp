#pragma once
// A smooth displacement field over an anchor frame, made from scattered tracks, and the current frame
// resampled through it into the anchor's coordinates.
//
// Why: the fixed-shape pass matches each track's wide subset for its translation alone, the shape taken
// from a fit of its neighbours. Done subset by subset, every contact pixel is interpolated once per
// overlapping subset and iteration (≈ 25 subsets of 41×41 px on a 8 px grid). Resampling the current frame
// once through the neighbours' fitted field and reading every subset from that image does the
// interpolation once per pixel; the translation step of a subset is then a sum over stored values (see
// Subset::translation_step and docs/flow.md, step 7).
#include <Eigen/Core>
#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

#include "core/tensor2.hpp"
#include "flow/bspline.hpp"
#include "flow/pixel_classes.hpp"

namespace tirstrain::flow {

class ShapeField {
 public:
  // Fits the displacement at the nodes of a grid `spacing_px` apart covering `region` (anchor px): at each
  // node a Gaussian-weighted (σ = sigma_px, out to 2σ) least-squares polynomial of the samples (anchor
  // positions and their displacements, same length), quadratic where at least 10 samples lie in two
  // quadrants around the node or more, affine where at least 6 do (or the quadratic is ill-posed), none
  // otherwise. The fit is linear in the displacements: called again with the same positions, region and
  // spacing (the rounds of one frame), only the displacements are summed.
  void fit(const std::vector<Vec2>& anchor_px, const std::vector<Vec2>& displacement_px, cv::Rect region,
           double spacing_px, double sigma_px);
  // u at anchor point (x, y): the polynomials of the (up to four) fitted nodes around it, blended with
  // bilinear weights. False where no surrounding node has a fit. `gradient` (optional): the nodes' du/dX
  // blended alike. That is not the derivative of the blend, which adds the nodes' disagreement divided by
  // their spacing: noise, which the fusion would carry into the positions it moves with this gradient.
  bool displacement(double x, double y, Vec2& u, Eigen::Matrix2d* gradient = nullptr) const;
  // displacement() along image row y for x = x_begin … x_end − 1, into u[x − x_begin], with ok[…] = 0
  // where it is undefined: the per-pixel cost of resampling a frame. Only the columns x ≡ x_phase
  // (mod x_stride) are evaluated (the others are left undefined): a pass reading one lattice class.
  void displacement_row(int y, int x_begin, int x_end, Vec2* u, std::uint8_t* ok, int x_stride = 1,
                        int x_phase = 0) const;
  int fitted_nodes() const { return fitted_; }
  // Of the nodes the last change of sample positions fitted, those whose samples within their reach were
  // the same as before (their operators were kept rather than built again).
  int reused_nodes() const { return reused_; }

 private:
  void prepare(const std::vector<Vec2>& anchor_px, cv::Rect region, double spacing_px, double sigma_px);

  struct Node {
    bool fitted = false;
    // u and v as polynomials in (X − node) / scale: 1, a, b, a², ab, b².
    Eigen::Matrix<double, 6, 2> coef = Eigen::Matrix<double, 6, 2>::Zero();
  };
  cv::Rect region_;
  double spacing_ = 1.0, sigma_ = 0.0, scale_ = 1.0;
  int cols_ = 0, rows_ = 0, fitted_ = 0, reused_ = 0;
  std::vector<Vec2> anchors_;  // what the operators were built for
  // Per node, its samples (indices into anchors_, in a fixed order: by bucket, then by position) and the
  // rows of its least-squares operator, coef = Σ_k rows_k u_k; no rows: the node has no fit.
  //
  // Why kept by node position from one call to the next: from one frame to the next only the nodes within
  // a fit radius of a retired or newborn track see other samples. The others keep their operator and only
  // renumber their samples; gathering every node's samples again and copying its operator out was 15 % of
  // the tracker's instructions after building the operators had been cut the same way (12 %).
  struct NodeOperator {
    std::vector<int> samples;
    std::vector<std::array<double, 6>> rows;
    std::uint64_t generation = 0;  // the last prepare() that used it
  };
  std::unordered_map<std::int64_t, NodeOperator> operators_;
  std::uint64_t generation_ = 0;
  std::vector<NodeOperator*> node_operator_;  // per node of the grid; null: fewer than 6 samples
  std::vector<Node> nodes_;

  // prepare()'s steps (shape_field.cpp).
  struct SampleBuckets;
  struct Renumbering;
  static Renumbering renumber_samples(const std::vector<Vec2>& previous, const std::vector<Vec2>& anchor_px,
                                      const std::vector<int>& order, bool all_changed);
  std::vector<std::uint8_t> nodes_near(const Renumbering& renumbering) const;
  void assign_operators(const SampleBuckets& buckets, std::vector<std::uint8_t>& gather);
  void build_operators(const SampleBuckets& buckets, const std::vector<std::uint8_t>& gather,
                       const std::vector<int>& renumber, const std::vector<Vec2>& previous);
  void build_operator(double nx, double ny, int quadrants, NodeOperator& op,
                      std::vector<Eigen::Matrix<double, 6, 1>>& basis) const;
};

// `out` (CV_32F) and `valid` (CV_8U), the size of `current`: at every anchor pixel X of `region` where
// `anchor_mask` is set, the value of `current` at X + u(X) interpolated by `kernel` (`current` holds the
// spline coefficients for the B-spline), valid where the field is defined there, the 4×4 support lies in
// the image and the nearest pixel in `current_mask` (if not empty). Pixels outside `region` or
// `anchor_mask`, or not in `classes`, are left invalid.
void resample_through(const cv::Mat& current, const cv::Mat& current_mask, const ShapeField& field,
                      const cv::Mat& anchor_mask, cv::Rect region, cv::Mat& out, cv::Mat& valid,
                      const PixelClasses& classes = PixelClasses(),
                      Interpolation kernel = Interpolation::kKeys);

}  // namespace tirstrain::flow
