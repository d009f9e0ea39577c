#pragma once
// Contact segmentation of TIR fingertip images.
//
// Where skin touches the glass the image carries the ridge texture; elsewhere it shows the smooth
// background of the optics. Detection is therefore "texture in the ridge band", whatever the polarity:
// band-pass around the ridge period (measured from the spectrum unless the scene fixes it), rectify, grey
// closing (fills the zero crossings between ridges and valleys) then opening (removes specks of noise), Otsu
// threshold, the largest connected region (plus regions >= merge_fraction of it, e.g. a contact split by a
// sweat patch), convex hull. That decides contact / no contact and gives a coarse outline.
//
// The outline is then placed where the contact ends rather than where the texture is half as strong. The
// frame is first flat-fielded: divided by a quadratic surface fitted to the background around the contact
// (vignetting, the light's tilt; only when that background surrounds the contact), because grey closing
// flattens a background that rises outward beside the contact and the edge level is then reached too early.
// When the ridge texture's SNR is low (below border_average_snr), the flat-fielded frame is also averaged
// along the border over 0.7 ridge period: ridges near the border run along it, so the profile across the
// border is kept and the faint outermost crest rises out of the noise. With ridges made bright, grey closing
// then opening over one period merges ridges and valleys into a plateau whose outer edge is the outermost
// crest; along the ray from the centre through each of 200 outline samples the edge is where that level falls
// to crest_edge_level of the way from the local background to the outermost crest's own height. Relative to
// the crest, not to the contact's plateau: ridge contrast fades towards the border (skin only nearly touches
// there), so the last crest is fainter than the plateau and a plateau-relative level cuts it several pixels
// inside the edge. Levels stay clear of the pixel noise measured beyond the edge. A valley lying along the
// border is invisible (it reflects like the background), so there the edge can only be placed statistically:
// crest_edge_level below one half puts it part-way into that valley, and one-sided dips are found against an
// outer-envelope ellipse and bridged by it. Single-ray outward spikes (noise) are clipped to their
// neighbours' median. Convex hull, 50 points equally spaced along its perimeter, area, then the direct
// ellipse fit and the ridge orientation field. The code follows these steps in
// ContactSegmenter::segment_region (contact/segmenter.cpp); each step lives in its own file: working_image,
// texture_regions, flat_field and level_edge, outline_repair, label_refinement (with ridge_labels and
// border_band).
//
// Working resolution (the design choice that sets the speed): everything runs on the frame averaged over
// f x f blocks with f = floor(ridge period / 5.5 px), i.e. about 5.5-8 working pixels per ridge period
// (f = 4 at 52 px/mm and a 0.45 mm period: 1280x1024 -> 320x256). That is the coarsest sampling at which
// the ridge band stays well below the Nyquist limit after block averaging (gain sinc(f/P) > 0.9), so the
// texture decision is unchanged, while the outline is still found to sub-pixel accuracy by interpolating
// along the rays. The cost drops ~f^2. `downsample = 1` runs at full resolution, for comparison (see
// bench/contact_bench.cpp and BENCHMARKS.md).
//
// Region tracking (the other half of the speed): a contact moves little between frames, so after a frame
// with a contact the next ones are segmented only in a region around it (bounding box grown by 4 ridge
// periods or 15 % of its size, snapped to whole orientation blocks; used when at most 60 % of the frame).
// The block average reads only that part of the frame, and every later step works on the smaller image
// (1280x1024 with the bench's contact: about 40 % of the frame, half the instructions per frame). The
// whole frame is segmented again when the contact is lost or its outline reaches a side of the region
// (same frame: nothing is missed), and every full_frame_every frames, which is when a new region elsewhere
// (a second blob) is seen. Otsu's threshold is taken over the region, not the frame; the outline moves by
// ~0.1 px for it (tests/contact/segmenter_test.cpp). A contact smaller than small_contact_periods is
// segmented again at half the working factor on its own bounding box plus 4 periods, not on the frame.
#include <opencv2/core.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "contact/ellipse.hpp"
#include "contact/level_edge.hpp"
#include "contact/segmenter_options.hpp"
#include "contact/texture_regions.hpp"
#include "contact/working_image.hpp"

namespace tirstrain {
class Archive;
}

namespace tirstrain::contact {

// Per-frame contact status: bit flags; 0 is a clean measurement. Written as /contact/status.
enum ContactFlag : std::uint32_t {
  kContactOk = 0,
  kNoContact = 1u << 0,      // no ridge texture above the noise: area 0, hull, ellipse and field all 0
  kTouchesEdge = 1u << 1,    // contact runs off the frame or into the excluded band: the hull is cut
                             // there, and the ellipse is fitted to the free part of the outline only
  kMultipleBlobs = 1u << 2,  // more than one textured region; those >= merge_fraction of the largest
                             // and within merge_gap_periods of it are joined in one hull
  kSaturated = 1u << 3,      // >= saturated_fraction of the pixels at full scale
  kLowContrast = 1u << 4,    // ridge amplitude below low_contrast (fraction of full scale): kept, less sure
  kNoEllipse = 1u << 5,      // contact found but too little free outline to fit an ellipse: ellipse 0
  kFrameSkipped = 1u << 6,   // not segmented (corrupt or unreadable frame); set by the pipeline
};

// "ok", or the set flags joined by '|', e.g. "touches_edge|low_contrast".
std::string contact_status_text(std::uint32_t status);

struct ContactResult {
  std::uint32_t status = kNoContact;
  double area_mm2 = 0.0;                // area inside the (dense) convex hull
  std::vector<cv::Point2d> hull_px;     // hull_points points along the hull perimeter (empty: no contact)
  std::vector<cv::Point2d> outline_px;  // the dense refined hull the above is resampled from
  std::optional<Ellipse> ellipse;       // fit to the free part of the outline
  EllipseNormalization normalization;   // identity when there is no ellipse
  cv::Mat orientation_rad;              // blocks, CV_32FC1 (see orientation.hpp); 0 outside the contact
  cv::Mat coherence;                    // blocks, CV_32FC1; 0 outside the contact
  cv::Rect bounding_box_px;             // of the outline, clipped to the frame
  double ridge_period_px = 0.0;         // period used for this frame
  double texture_energy = 0.0;          // mean band-pass envelope inside the contact, fraction of full scale
  double energy_ratio = 0.0;            // inside over outside
  double saturated_fraction = 0.0;
  // Texture SNR behind the border averaging (0 when the background could not be fitted) and whether it ran.
  double texture_snr = 0.0;
  bool border_averaged = false;
  // Shift of the outline and ellipse to the centre fitted to the ridge labels (SegmenterOptions::
  // ridge_label_centre), px; nothing when it was not applied.
  std::optional<cv::Point2d> ridge_label_shift_px;
  // With the brackets (large contacts), the border's radial change size + cos2 cos 2 phi + sin2 sin 2 phi
  // (phi about the centre) fitted to the same labels, (size, cos2, sin2) px, also applied to the outline,
  // hull, area and ellipse (contact/ridge_labels.hpp). With the logistic fit (small contacts), (0, cos2,
  // sin2): the ellipse's elongation change from ridge_label_shape_weight, in the same form to first order.
  std::optional<cv::Vec3d> ridge_label_shape_px;
  // The border band's intensity fit (SegmenterOptions::border_band_centre) set or shared in that centre.
  bool border_band_used = false;
  int polarity = 0;  // -1: contact darker than background (dark ridges), +1 brighter, 0 unknown
};

class ContactSegmenter {
 public:
  explicit ContactSegmenter(SegmenterOptions options = {});
  // What it carries from frame to frame (the period, the tracked region), in a checkpoint
  // (core/archive.hpp); the options are the caller's to give again.
  void archive(Archive& a);

  // `image`: CV_8UC1, CV_16UC1 or CV_32FC1 (0..1). Never throws for image content; throws Error for a wrong
  // image type.
  ContactResult segment(const cv::Mat& image);

  // Ridge period in full-resolution pixels once known (fixed or measured), and whether it was measured.
  std::optional<double> ridge_period_px() const { return period_px_; }
  bool period_measured() const { return period_measured_; }
  // Working-resolution factor used for the last frame.
  int downsample() const { return factor_; }
  const SegmenterOptions& options() const { return options_; }

 private:
  // Images and buffers reused from frame to frame (no allocation per frame once sizes settle).
  struct Buffers {
    cv::Mat work;     // the working image of the region being segmented
    cv::Mat measure;  // the working image the ridge period is measured on
    cv::Mat hull_mask, mask_scratch;
    WorkingImageBuffers working;
    TextureImages texture;
    TextureRegions regions;
    LevelImages level;
    std::vector<float> ray;
  };

  double period_for_frame(const cv::Mat& image, double full_scale);
  // One segmentation of `region` (full-resolution pixels; snapped outward to whole orientation blocks);
  // results in frame coordinates. Sets *left_region when the outline reaches a side of the region that is not
  // a side of the frame.
  ContactResult segment_region(const cv::Mat& image, cv::Rect region, bool* left_region);
  // A contact only a few ridge periods across, segmented again at twice the resolution on `box_px` (the
  // whole frame if its outline reaches that box's side); `multiple_blobs` is added to a contact found.
  ContactResult segment_small_contact(const cv::Mat& image, const cv::Rect& box_px,
                                      std::uint32_t multiple_blobs);
  void update_region(const ContactResult& result, const cv::Rect& frame);
  // The texture energy the working image's own pixel noise gives (Immerkær's σ, outside the excluded band,
  // times noise_energy_per_sigma at this period, computed once per period).
  double region_noise_energy(const RegionView& view, double period_w);

  SegmenterOptions options_;
  std::optional<double> period_px_;
  bool period_measured_ = false;
  int factor_ = 1;
  bool small_contact_pass_ = false;
  cv::Rect roi_;        // region tracked from the last frame (empty: whole frame)
  cv::Size roi_frame_;  // frame size it belongs to
  int frames_since_full_ = 0;
  double noise_energy_period_w_ = 0.0, noise_energy_per_sigma_ = 0.0;
  Buffers buf_;
};

}  // namespace tirstrain::contact
