#pragma once
// Where the contact ends: the level edge along rays (docs/contact.md, "Level edge along rays").
//
// With ridges made bright, grey closing over one period merges ridges and valleys into a plateau whose
// outer edge is the outermost crest; along the ray from the coarse hull's centre through each outline sample
// the edge is where that level falls to crest_edge_level of the way from the local background to the
// outermost crest's own height (ridge contrast fades towards the border, so that crest is fainter than the
// plateau). Levels stay clear of the pixel noise measured beyond the edge.
#include <opencv2/core.hpp>

#include <cstdint>
#include <optional>
#include <vector>

#include "contact/ellipse.hpp"
#include "contact/flat_field.hpp"
#include "contact/segmenter_options.hpp"

namespace tirstrain::contact {

// A region of the frame and its working image: where its outline points lie against the view's limits.
struct RegionView {
  cv::Rect region_px;   // full-resolution pixels, on the working and orientation-block grids
  cv::Size frame_size;  // full-resolution pixels
  int factor = 1;       // working-resolution factor
  cv::Size size_w;      // the working image's size
  cv::Rect excluded_w;  // the excluded band in working pixels (empty: none)
  // Region sides that are frame sides: only there is an outline point on the side a cut (elsewhere the
  // contact has left the region).
  bool frame_left = true, frame_top = true, frame_right = true, frame_bottom = true;

  cv::Point2d origin() const { return {static_cast<double>(region_px.x), static_cast<double>(region_px.y)}; }
  // Working pixel centre -> full-resolution frame pixel coordinates.
  cv::Point2d to_frame(const cv::Point2d& p_w) const {
    return cv::Point2d((p_w.x + 0.5) * factor - 0.5, (p_w.y + 0.5) * factor - 0.5) + origin();
  }
  bool near_left(const cv::Point2d& p) const { return p.x < 1.0; }
  bool near_top(const cv::Point2d& p) const { return p.y < 1.0; }
  bool near_right(const cv::Point2d& p) const { return p.x > size_w.width - 2.0; }
  bool near_bottom(const cv::Point2d& p) const { return p.y > size_w.height - 2.0; }
  // Within a pixel of the frame border or of the excluded band: the outline there is where the view ends,
  // not where the contact ends.
  bool on_cut(const cv::Point2d& p_w) const;
  // On a side of the region that is not a frame side: the contact has outgrown the region.
  bool leaves_region(const cv::Point2d& p_w) const;
};

// The images the edge search reads, working pixels, CV_32FC1.
struct LevelImages {
  cv::Mat bright;  // ridges made bright (flattened, maybe averaged along the border)
  cv::Mat level;   // `bright` closed over a period, opened over half: the merged crest plateau
  cv::Mat scratch;
};

// How the level edge is set up for a frame (prepare_level_edge).
struct LevelEdgeSetup {
  bool use_level_edge = false;  // false: the outline stays where the texture energy crosses its threshold
  double level_drop_min = 0.0;  // the least drop from plateau to background that counts as the edge
  std::optional<QuadraticSurface> background;  // the flat field's surface (working pixels), if fitted
  double texture_snr = 0.0;
  bool border_averaged = false;
};

// The inputs of prepare_level_edge that describe the frame's contact so far.
struct CoarseContact {
  const cv::Mat* work = nullptr;       // the working image
  const cv::Mat* hull_mask = nullptr;  // the coarse hull filled (CV_8UC1)
  const std::vector<cv::Point2d>* hull_w = nullptr;
  cv::Point2d centroid_w;
  int polarity = 0;             // -1 dark ridges, +1 bright, 0 unknown (no level edge)
  double texture_energy = 0.0;  // mean band-pass envelope inside the contact, fraction of full scale
};

// Flat field (when options.flat_field), ridges made bright, border averaging (when the texture SNR is low)
// and the merged level, into `images`. `period_px`: the ridge period in frame pixels; `reach_w`: how far
// each ray looks either side of the coarse hull (working pixels); `mask_scratch`: a CV_8UC1 buffer.
LevelEdgeSetup prepare_level_edge(const CoarseContact& contact, const RegionView& view, double period_px,
                                  double reach_w, const SegmenterOptions& options, LevelImages& images,
                                  cv::Mat& mask_scratch);

// Ridges near the contact border run along it, so averaging along the border keeps their profile across it
// while the pixel noise drops by up to sqrt(2 half_taps + 1). "Along the border" is along the ellipse
// through the pixel that is concentric with and similar to `shape` (2 half_taps + 1 samples about one pixel
// apart). Only pixels within `band_px` of `shape` (in its normalised radius) are averaged, the others copied:
// the edge search and the closing before it look no further. Never closer to the centre than 0.3 of the
// radius: there the arcs are short and, at the centre itself, undefined.
void average_along_border(const cv::Mat& src, const Ellipse& shape, int half_taps, double band_px,
                          cv::Mat& dst);

// What one ray's edge search reads.
struct EdgeSearch {
  const cv::Mat* energy = nullptr;  // texture energy, and its Otsu threshold
  float threshold = 0.0f;
  const LevelImages* images = nullptr;  // read only with a level edge
  const LevelEdgeSetup* setup = nullptr;
  double reach_w = 0.0, period_w = 0.0;  // working pixels
  double edge_level = 0.0, crest_edge_level = 0.0;
};

// The outline refined along rays, in frame pixels, one point per sample of the coarse hull.
struct RefinedOutline {
  std::vector<cv::Point2d> points_px;
  std::vector<std::uint8_t> cut;  // 1: on a cut (frame edge, excluded band), pushed onto it
  bool touches_edge = false;      // some point is on a cut
  bool left_region = false;       // some point is on a side of the region that is not a frame side
};

// Sub-pixel outline along the ray from `centroid_w` through each of `samples_w` (working pixels): first
// where the texture energy falls through the threshold (pixel-centre hulls sit ~half a working pixel inside
// it), then, where the level step is clear, where the merged level falls to the edge level. `ray`: a buffer.
RefinedOutline refine_outline(const std::vector<cv::Point2d>& samples_w, cv::Point2d centroid_w,
                              const RegionView& view, const EdgeSearch& search, std::vector<float>& ray);

}  // namespace tirstrain::contact
