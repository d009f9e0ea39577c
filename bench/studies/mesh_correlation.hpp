#pragma once
// Global (finite-element) digital image correlation: one continuous displacement field over a region of a
// reference frame, bilinear on square elements (Q4), solved for all nodes at once by Gauss–Newton on the sum
// of squared differences of every pixel in the region, with a gain and an offset field of the illumination
// on the same mesh. Where subset correlation visits each pixel once per overlapping subset (10–30 times on a
// 9 px grid), this visits it once per iteration; the price is that a node is pinned by the pixels of its
// four elements only, so a weak penalty on the field's second differences (which leaves uniform strain
// free) carries nodes across texture-poor pixels.
//
// A study, not part of the pipeline (bench/studies/README.md): flow_bench's --mesh rows measure it against
// the subset tracker. With one ridge system a 9–12 px element barely pins the motion along the ridges, and
// that error grows with the displacement, so the tracker keeps its subsets.
//
// Pixels whose current position leaves the current frame's usable mask (the contact, eroded for the
// interpolation kernel) are removed from the sums, so material leaving the contact never pulls the field
// towards zero motion.
#include <Eigen/Core>
#include <Eigen/SparseCholesky>
#include <opencv2/core.hpp>

#include <array>
#include <vector>

#include "core/tensor2.hpp"

namespace tirstrain::studies {

struct MeshCorrelationOptions {
  int element_px = 9;  // side of a square element (node spacing)
  int max_iterations = 30;
  double convergence_px = 1e-3;  // largest nodal displacement step
  // Penalty on the field's second differences along mesh lines, relative to a node's mean data weight. On the
  // goal trial 0.002 / 0.02 / 0.2 / 2 gave 0.48 / 0.26 / 0.16 / 0.13 px over 8 frames (BENCHMARKS.md).
  double smoothness = 0.2;
  double brightness_smoothness = 1.0;  // the same for the gain and offset fields
  bool brightness = true;              // solve for a gain and an offset field as well
  int min_element_pixels = 8;          // elements with fewer usable pixels hold no data of their own
  // Re-evaluate the Jacobian with the reference gradient carried by each element's deformation every
  // iteration (full Gauss–Newton; costs a re-assembly and factorisation per iteration).
  bool update_gradient = false;
};

struct MeshCorrelationResult {
  int iterations = 0;
  bool converged = false;
  double rms_residual = 0.0;  // image units (full scale 1)
  int pixels_used = 0;
  int refactorisations = 0;
};

class MeshCorrelation {
 public:
  // `reference` CV_32F (full scale 1), `region` CV_8U (non-zero = material to follow) of the same size.
  MeshCorrelation(const cv::Mat& reference, const cv::Mat& region, const MeshCorrelationOptions& options);

  int node_count() const { return static_cast<int>(node_x_.size()); }
  Vec2 node_px(int node) const {
    return {node_x_[static_cast<std::size_t>(node)], node_y_[static_cast<std::size_t>(node)]};
  }

  // Solves for the displacement field from the reference to `current` (CV_32F, same size), starting from
  // `displacement_px` (one entry per node; in/out). `current_mask` CV_8U: where `current` may be sampled.
  MeshCorrelationResult solve(const cv::Mat& current, const cv::Mat& current_mask,
                              std::vector<Vec2>& displacement_px);

  // The field at reference position X; false outside the meshed region or in an element without data.
  bool displacement_at(const std::vector<Vec2>& displacement_px, Vec2 X, Vec2& u) const;

 private:
  struct Pixel {
    float x, y;
    float n[4];  // shape function values of the element's nodes
    float f, gx, gy;
    int element;
  };
  using LocalMatrix = Eigen::Matrix<double, 16, 16>;

  void assemble(const std::vector<char>& valid);
  int dofs_per_node() const { return options_.brightness ? 4 : 2; }

  MeshCorrelationOptions options_;
  int origin_x_ = 0, origin_y_ = 0, cols_ = 0, rows_ = 0;  // element grid
  std::vector<int> element_nodes_;                         // 4 per element (−1: element not meshed)
  std::vector<int> grid_node_;                             // (cols+1)·(rows+1) → node or −1
  std::vector<double> node_x_, node_y_;
  std::vector<Pixel> pixels_;
  std::vector<int> element_pixel_begin_;   // pixels sorted by element
  std::vector<LocalMatrix> element_full_;  // all pixels of the element
  std::vector<char> element_has_data_;
  Eigen::SparseMatrix<double> regulariser_;
  Eigen::SparseMatrix<double> system_;
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> solver_;
  bool analysed_ = false;
  std::vector<char> assembled_valid_;
  std::vector<std::array<double, 4>> element_transform_;  // F⁻ᵀ per element (row-major)
  std::vector<double> brightness_;                        // gain, offset per node (kept between frames)
};

}  // namespace tirstrain::studies
