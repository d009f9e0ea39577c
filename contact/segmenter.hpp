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
// flattens a background that rises outward beside the contact and the edge level is then reached too early
// (30 % vignetting moved a low-contrast contact's axes by 5 %). When the ridge texture's SNR is low (below
// border_average_snr), the flat-fielded frame is also averaged along the border over 0.7 ridge period:
// ridges near the border run along it, so the profile across the border is kept and the faint outermost
// crest rises out of the noise. With ridges made bright, grey closing then opening over one period merges
// ridges and valleys into a plateau whose outer edge is the outermost crest; along the ray from the centre
// through each of 200 outline samples the edge is where that level falls to crest_edge_level of the way from
// the local background to the outermost crest's own height. Relative to the crest, not to the contact's
// plateau: ridge contrast fades towards the border (skin only nearly touches there), so the last crest is
// fainter than the plateau and a plateau-relative level cuts it several pixels inside the edge (the contact's
// axes came out ~3 % short and a contact two ridge periods across lost a tenth of its radius). Levels stay
// clear of the pixel noise measured beyond the edge. A valley lying along the border is invisible (it
// reflects like the background), so there the edge can only be placed statistically: crest_edge_level below
// one half puts it part-way into that valley, and one-sided dips are found against an outer-envelope ellipse
// and bridged by it. Single-ray outward spikes (noise) are clipped to their neighbours' median. Convex hull,
// 50 points equally spaced along its perimeter, area, then the direct ellipse fit and the ridge orientation
// field.
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

struct SegmenterOptions {
  double px_per_mm = 52.0;
  // Fixed ridge period; without it the period is measured from the spectrum of the first frames that show
  // a clear ridge ring (and default_period_mm is used until then).
  std::optional<double> ridge_period_px;
  double default_period_mm = 0.45;
  double min_period_mm = 0.25;
  double max_period_mm = 1.2;
  double min_period_confidence = 6.0;
  int polarity = 0;    // -1: ridges in contact darker than the background, +1 brighter, 0: measure
  int downsample = 0;  // working-resolution factor f; 0 = automatic (see above), 1 = full resolution
  int hull_points = 50;
  int block_px = 32;  // orientation blocks, full-resolution pixels
  bool orientation = true;
  std::optional<cv::Rect> exclude_px;  // never contact (e.g. the reference pattern band on the glass)
  double min_area_mm2 = 0.5;           // smaller textured regions are noise, not contact
  double min_energy_ratio = 3.0;       // texture energy inside / outside needed to call it contact
  double min_energy = 0.003;           // and in absolute terms (fraction of full scale)
  // Regions joined to the largest one: at least merge_fraction of its area and no further from it than
  // merge_gap_periods ridge periods. One fingertip makes one contact; what splits it (a dry or wet patch, a
  // faint stretch of border) leaves gaps of a ridge period or so, while another textured thing in view (a
  // patterned band on the glass, an object at the image's edge) lies apart and is not contact.
  double merge_fraction = 0.1;
  double merge_gap_periods = 2.0;
  double saturated_fraction = 0.02;
  // Flat field: the level edge is searched on the frame divided by a quadratic surface fitted to the
  // background around the contact (vignetting, the light's tilt). Without it, grey closing flattens a
  // background that rises outward next to the contact, which puts the edge too far in wherever the ridge
  // contrast is small against that slope (1.4 % on the low-contrast scene's minor axis; BENCHMARKS.md).
  bool flat_field = true;
  // Below this texture SNR (band-pass envelope inside the contact over the background's pixel noise, the
  // noise scaled to the automatic working resolution of 5.5 pixels per ridge period), the ridges-bright image
  // is averaged along the border over border_average_periods ridge periods before the edge search: ridges
  // near the border run along it, so its profile across the border is kept while the noise that pulls the
  // faint outermost crest under the noise margins drops.
  double border_average_snr = 20.0;
  double border_average_periods = 0.7;
  // The outline is where the merged ridge level falls to crest_edge_level of the way from the background to
  // the outermost crest (ridge contrast fades towards the border where skin only nearly touches, so that
  // crest is fainter than the contact's plateau). Below one half, because where a valley runs along the
  // border the edge lies somewhere in that valley, beyond the crest's flank. Rays that cannot see that crest
  // clearly (window leaving the view, crest lost in noise) use edge_level of the way to the plateau.
  double crest_edge_level = 0.18;
  double edge_level = 0.14;
  // Outline dips deeper than this (in ridge periods) inside the outer-envelope ellipse are valleys along
  // the border and are bridged by the ellipse (see bridge_valleys in segmenter.cpp).
  double valley_gap_periods = 0.1;
  // A single ray's edge further out than the median of its neighbours by more than this (in ridge periods)
  // is a noise spike and is clipped back (see clip_spikes in segmenter.cpp).
  double spike_periods = 0.1;
  // With automatic resolution, a contact whose equivalent radius is below this many ridge periods is
  // segmented again at half the working factor (about 11 working pixels per period).
  double small_contact_periods = 3.0;
  // The centre from where ridges show near the border (contact/ridge_labels.hpp): the outline is moved so
  // that the ellipse's centre is the one the ridge labels give. The level edge works from the crests, so
  // where a ridge valley runs along the border it stops at the last crest, and the centre follows where the
  // fingerprint happens to lie (over 19 synthetic trials, every frame, centre RMS up to 1.7-2.0 px on the
  // tiny contact and on sliding ones; 0.97 px RMS of the scenes' RMS). Contacts whose equivalent radius
  // sqrt(a b) is under ridge_label_below_periods ridge periods get the logistic ellipse fit to the labels
  // (the tiny contact: 1.70 -> 0.37 px; the brackets there: 0.77); larger ones, when ridge_label_centre,
  // the per-sector brackets (there the logistic fit drifts outward along valley arcs: direction_proximal
  // 0.90 px against the brackets' 0.54). Together: 0.97 -> 0.48 px (BENCHMARKS.md, contact/, sessions 21
  // and 23). The brackets also give the outline's size (from the sectors where ridges end at the border) and
  // its shape (the border's cos 2 phi and sin 2 phi terms): worst semi-axis error of the large contacts over
  // the 19 trials 2.87 -> 1.83 %, their worst IoU 0.965 -> 0.978; the default scene with nine fingerprints
  // (seeds), worst IoU 0.951-0.976 -> 0.972-0.980 (BENCHMARKS.md, contact/, session 24).
  // Never applied when the contact touches the frame's edge, the frame is saturated or was averaged along
  // the border (the labels would be clipped or noise-limited), or the shift would exceed half a ridge
  // period. Costs about 0.9 ms a frame on a large contact (session 22), 3 ms on a small one.
  double ridge_label_below_periods = 5.0;
  bool ridge_label_centre = true;
  // Small contacts (the logistic fit): the ellipse's elongation and its direction are this weight of the
  // fit's, the rest the level edge's; the size stays the level edge's (the fit's axes run ~2.5 px long). Each
  // errs by where the fingerprint's valleys lie along the border, partly independently: on the tiny contact
  // with four fingerprints the axes' RMS error went 1.31 -> 1.19 % and the shipped trial's worst frame 2.08
  // -> 1.70 % (BENCHMARKS.md, contact/, session 27). 0: the level edge's shape.
  double ridge_label_shape_weight = 0.5;
  // The border band's intensity fit (contact/border_band.hpp) for large contacts, with ridge_label_centre:
  // the centre becomes the mean of the brackets' and the fit's, and on frames averaged along the border (too
  // noisy for labels) the fit's alone. Over 13 fingerprints (the default scene's seeds and two more scenes)
  // the worst frame's centre error went 2.60 -> 1.66 px, on the two noisy scenes' other seeds 6.4 -> 2.3 px,
  // with a stronger contrast fade than the generator's 5.0 -> 2.7 px, and no shipped trial has a frame above
  // 1 px (1.11 -> 0.93); where the ridges' contrast fades little towards the border it costs (1.80 -> 1.91
  // px; BENCHMARKS.md, contact/, sessions 26 and 28). On by default since session 28: the accuracy
  // targets hold on every shipped trial only with it. It costs ~2.2 ms a frame, ~4 ms on frames averaged
  // along the border; SegmentationPreset::balanced turns it off.
  bool border_band_centre = true;
  double low_contrast = 0.02;  // texture energy (≈ 0.6 x ridge amplitude) below this: low contrast
  // Region tracking: after a frame with a contact, the next frames are segmented only around it (its
  // bounding box grown by the larger of region_margin_periods ridge periods and region_margin_fraction of
  // its size, when that is at most 60 % of the frame); a whole frame again every full_frame_every frames
  // (a new region elsewhere is seen then), and at once when the contact is lost or reaches the region's side.
  bool track_region = true;
  int full_frame_every = 10;
  double region_margin_periods = 4.0;
  double region_margin_fraction = 0.15;
};

// Three settings of the switches above by what they cost and give (BENCHMARKS.md, contact/, "Where contact/
// stands"; 1280x1024, the 19 shipped synthetic trials, worst frame):
//   accurate (the defaults): ~4.2 ms a frame, centre 0.93 px, semi-axes 2.0 %, IoU 0.956;
//   balanced: the border band off: ~2.0 ms, centre 1.11 px, semi-axes 2.0 %;
//   fast: the flat field, the border averaging, the ridge labels and the band off: ~1.1 ms, centre 2.5 px,
//         semi-axes 3.5 % (the default scene's IoU 0.975).
enum class SegmentationPreset { fast, balanced, accurate };

// `options` with the preset's switches (flat_field, border_average_snr, ridge_label_centre,
// ridge_label_below_periods, ridge_label_shape_weight, border_band_centre) set; everything else kept.
SegmenterOptions with_preset(SegmenterOptions options, SegmentationPreset preset);

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
  struct Buffers {
    cv::Mat work, bright, measure, blur_small, blur_large, band, energy, level, scratch, mask, labels, stats,
        centroids, hull_mask, scratch_u8;
    std::vector<float> row_sum;
    std::vector<std::uint16_t> sum_u16;
    std::vector<std::uint32_t> sum_u32;
  };

  double period_for_frame(const cv::Mat& image, double full_scale);
  // One segmentation of `region` (full-resolution pixels; snapped outward to whole orientation blocks);
  // results in frame coordinates. Sets *left_region when the outline reaches a side of the region that is not
  // a side of the frame.
  ContactResult segment_region(const cv::Mat& image, cv::Rect region, bool* left_region);
  void update_region(const ContactResult& result, const cv::Rect& frame);
  // Working image of `image` at `factor`; returns the number of pixels at full scale (0 for float images).
  std::size_t to_working(const cv::Mat& image, int factor, double full_scale, cv::Mat& out);

  SegmenterOptions options_;
  std::vector<float> ray_;
  std::optional<double> period_px_;
  bool period_measured_ = false;
  int factor_ = 1;
  bool small_contact_pass_ = false;
  cv::Rect roi_;        // region tracked from the last frame (empty: whole frame)
  cv::Size roi_frame_;  // frame size it belongs to
  int frames_since_full_ = 0;
  Buffers buf_;
};

// Full scale of an image's values: 255 for 8-bit; for 16-bit the smallest of 2^10-1, 2^12-1, 2^14-1,
// 2^16-1 not below the frame's maximum (cameras store 10-14 bit data in 16-bit files); 1 for float.
double full_scale_of(const cv::Mat& image);

}  // namespace tirstrain::contact
