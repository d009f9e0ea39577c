#include "contact/segmenter.hpp"

#include "core/archive.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numbers>
#include <numeric>

#include "contact/geometry.hpp"
#include "contact/image_stats.hpp"
#include "contact/label_refinement.hpp"
#include "contact/orientation.hpp"
#include "contact/outline_repair.hpp"
#include "contact/ridge_period.hpp"
#include "core/error.hpp"
#include "core/full_scale.hpp"
#include "core/image_noise.hpp"

namespace tirstrain::contact {

void ContactSegmenter::archive(Archive& a) {
  a(period_px_, period_measured_, factor_, small_contact_pass_, roi_, roi_frame_, frames_since_full_,
    noise_energy_period_w_, noise_energy_per_sigma_);
}
namespace {

// A result with the orientation field's blocks all 0 (what every result starts from).
ContactResult empty_result(cv::Size frame_size, int block_px) {
  ContactResult result;
  const cv::Size blocks((frame_size.width + block_px - 1) / block_px,
                        (frame_size.height + block_px - 1) / block_px);
  result.orientation_rad = cv::Mat::zeros(blocks, CV_32FC1);
  result.coherence = cv::Mat::zeros(blocks, CV_32FC1);
  return result;
}

// No contact: what was measured of the frame so far (period, texture, saturation), nothing of a contact.
ContactResult no_contact(const ContactResult& measured, std::uint32_t saturated_flag) {
  ContactResult empty;
  empty.status = kNoContact | saturated_flag;
  empty.orientation_rad = measured.orientation_rad;
  empty.coherence = measured.coherence;
  empty.ridge_period_px = measured.ridge_period_px;
  empty.texture_energy = measured.texture_energy;
  empty.energy_ratio = measured.energy_ratio;
  empty.saturated_fraction = measured.saturated_fraction;
  return empty;
}

// The working image of `region` into `work`; returns the fraction of the frame's pixels at full scale
// (counted in the same pass when the region is the whole frame).
double working_image_of(const cv::Mat& image, const cv::Rect& region, int f, double full_scale, cv::Mat& work,
                        WorkingImageBuffers& buffers) {
  std::size_t saturated_pixels = to_working_image(image(region), f, full_scale, work, buffers);
  if (region != cv::Rect(0, 0, image.cols, image.rows) && image.depth() != CV_32F)
    saturated_pixels = count_at_full_scale(image, full_scale, buffers);
  return static_cast<double>(saturated_pixels) / static_cast<double>(image.total());
}

// The working-resolution factor: the option's, else about 5.5 working pixels per ridge period (11 on the
// small-contact pass).
int working_factor(int downsample, bool small_contact_pass, double period_px) {
  if (downsample > 0) return downsample;
  if (small_contact_pass) return std::max(1, static_cast<int>(std::floor(period_px / 11.0)));
  return std::max(1, static_cast<int>(std::floor(period_px / 5.5)));
}

// The region snapped outward to whole orientation blocks that are whole working pixels (its origin on that
// grid, so blocks and working pixels line up with those of the whole frame).
cv::Rect snap_region(const cv::Rect& region, const cv::Rect& frame, int factor, int block_px) {
  const int grid = std::lcm(factor, block_px);
  const int x0 = region.x / grid * grid, y0 = region.y / grid * grid;
  const int x1 = (region.x + region.width + grid - 1) / grid * grid,
            y1 = (region.y + region.height + grid - 1) / grid * grid;
  return cv::Rect(x0, y0, x1 - x0, y1 - y0) & frame;
}

RegionView region_view(const cv::Rect& region, const cv::Rect& frame, int factor, cv::Size size_w,
                       const std::optional<cv::Rect>& exclude_px) {
  RegionView view;
  view.region_px = region;
  view.frame_size = frame.size();
  view.factor = factor;
  view.size_w = size_w;
  view.frame_left = region.x == 0;
  view.frame_top = region.y == 0;
  view.frame_right = region.x + region.width == frame.width;
  view.frame_bottom = region.y + region.height == frame.height;
  if (exclude_px) {
    const cv::Rect& r = *exclude_px;
    const auto down = [&](int v) { return static_cast<int>(std::floor(static_cast<double>(v) / factor)); };
    const auto up = [&](int v) { return static_cast<int>(std::ceil(static_cast<double>(v) / factor)); };
    view.excluded_w = cv::Rect(cv::Point(down(r.x - region.x), down(r.y - region.y)),
                               cv::Point(up(r.x + r.width - region.x), up(r.y + r.height - region.y))) &
                      cv::Rect(0, 0, size_w.width, size_w.height);
  }
  return view;
}

// The texture's mean energy and its contrast (inside over outside, at most 1e9) from Otsu's split.
void record_texture(const OtsuSplit& split, ContactResult& result) {
  result.texture_energy = split.mean_high;
  result.energy_ratio =
      split.mean_low > 0.0 ? split.mean_high / split.mean_low : (split.mean_high > 0.0 ? 1e9 : 0.0);
  result.energy_ratio = std::min(result.energy_ratio, 1e9);
}

cv::Point2d mean_point(const std::vector<cv::Point2d>& points) {
  cv::Point2d mean(0.0, 0.0);
  for (const auto& p : points) mean += p;
  mean *= 1.0 / static_cast<double>(std::max<std::size_t>(1, points.size()));
  return mean;
}

// This frame's polarity: the mean level inside the coarse hull against outside it, when the difference is
// clear against the texture (0 otherwise).
int measured_polarity(const cv::Mat& work, const cv::Mat& hull_mask, double texture_energy) {
  const MaskedMeans means = masked_means(work, hull_mask);
  if (means.inside_count > 0 && means.outside_count > static_cast<double>(work.total() / 100)) {
    const double difference = means.inside - means.outside;
    if (std::abs(difference) > 0.25 * texture_energy) return difference < 0.0 ? -1 : 1;
  }
  return 0;
}

// The outline's bounding box, clipped to the frame.
cv::Rect clipped_bounding_box(const std::vector<cv::Point2d>& outline_px, cv::Size frame_size) {
  const cv::Rect box = cv::boundingRect(std::vector<cv::Point2f>(outline_px.begin(), outline_px.end()));
  return box & cv::Rect(0, 0, frame_size.width, frame_size.height);
}

// The refined outline repaired (spikes clipped, valleys bridged) and its convex hull as the contact's
// outline, with its area, resampled hull and bounding box.
void set_outline(RefinedOutline& outline, cv::Point2d centre_px, double period_px,
                 const SegmenterOptions& options, cv::Size frame_size, ContactResult& result) {
  clip_spikes(outline.points_px, outline.cut, centre_px, options.spike_periods * period_px);
  bridge_valleys(outline.points_px, outline.cut, options.valley_gap_periods * period_px);
  result.outline_px = convex_hull(outline.points_px);
  result.area_mm2 = polygon_area_px2(result.outline_px) / (options.px_per_mm * options.px_per_mm);
  result.hull_px = resample_closed_polygon(result.outline_px, options.hull_points);
  result.bounding_box_px = clipped_bounding_box(result.outline_px, frame_size);
}

// The outline of a small contact from its ellipse (SegmenterOptions::small_contact_ellipse_outline):
// polygons with the ellipse's area (vertices at equal steps of the ellipse's parameter on the ellipse scaled
// by sqrt(2π / (n sin(2π/n))), so that the chords' lost area is given back), dense as the traced outline was.
void set_outline_from_ellipse(const Ellipse& e, const SegmenterOptions& options, cv::Size frame_size,
                              ContactResult& result) {
  const auto polygon = [&e](std::size_t n) {
    const double step = 2.0 * std::numbers::pi / static_cast<double>(n);
    const double scale = std::sqrt(step / std::sin(step));
    const Ellipse scaled{e.cx_px, e.cy_px, scale * e.semi_major_px, scale * e.semi_minor_px, e.angle_rad};
    return sample_ellipse(scaled, static_cast<int>(n), 0.0, step * static_cast<double>(n - 1));
  };
  const std::size_t hull_points = static_cast<std::size_t>(std::max(3, options.hull_points));
  result.outline_px = polygon(std::max(result.outline_px.size(), 4 * hull_points));
  result.hull_px = polygon(hull_points);
  result.area_mm2 =
      std::numbers::pi * e.semi_major_px * e.semi_minor_px / (options.px_per_mm * options.px_per_mm);
  result.bounding_box_px = clipped_bounding_box(result.outline_px, frame_size);
}

// Whether a hull point lies clear (by `margin_px`) of the frame's border and of the excluded band.
bool clear_of_cuts(const cv::Point2d& p, double margin_px, cv::Size frame_size,
                   const std::optional<cv::Rect>& exclude_px) {
  bool free = p.x > margin_px - 0.5 && p.y > margin_px - 0.5 && p.x < frame_size.width - 0.5 - margin_px &&
              p.y < frame_size.height - 0.5 - margin_px;
  if (free && exclude_px) {
    const cv::Rect& r = *exclude_px;
    free = !(p.x > r.x - margin_px - 0.5 && p.x < r.x + r.width + margin_px - 0.5 &&
             p.y > r.y - margin_px - 0.5 && p.y < r.y + r.height + margin_px - 0.5);
  }
  return free;
}

// The ellipse fitted to the hull points off the cuts (which lie on the border rather than the contact); with
// short free arcs, to the dense refined outline's free points. Nothing with fewer than 6 points, or when the
// ellipse is much larger than the frame (an extrapolation from a nearly straight arc).
std::optional<Ellipse> fit_free_outline(const ContactResult& result, const RefinedOutline& outline,
                                        int factor, cv::Size frame_size,
                                        const std::optional<cv::Rect>& exclude_px) {
  std::vector<cv::Point2d> fit_points;
  const double cut_margin_px = 1.5 * factor;
  for (const auto& p : result.hull_px)
    if (clear_of_cuts(p, cut_margin_px, frame_size, exclude_px)) fit_points.push_back(p);
  if (outline.touches_edge && fit_points.size() < 20) {
    fit_points.clear();
    for (std::size_t i = 0; i < outline.points_px.size(); ++i)
      if (outline.cut[i] == 0) fit_points.push_back(outline.points_px[i]);
  }
  std::optional<Ellipse> ellipse;
  if (fit_points.size() >= 6) ellipse = fit_ellipse_direct(fit_points);
  if (ellipse && ellipse->semi_major_px > 2.0 * std::hypot(frame_size.width, frame_size.height))
    ellipse.reset();
  return ellipse;
}

// A contact only a few ridge periods across is mostly fading border: it is segmented again at twice the
// resolution (automatic resolution only, not from the small-contact pass itself), on the kept regions'
// bounding box plus 4 ridge periods, so the extra pass costs little. That box, when due.
std::optional<cv::Rect> small_contact_box(int largest_area_w, const cv::Rect& kept_box_w,
                                          const cv::Rect& region, int f, double period_px,
                                          const SegmenterOptions& options, bool small_contact_pass) {
  const double radius_px = std::sqrt(largest_area_w / std::numbers::pi) * f;
  if (options.downsample != 0 || small_contact_pass || f < 4 ||
      !(radius_px < options.small_contact_periods * period_px))
    return std::nullopt;
  const int margin = static_cast<int>(std::ceil(4.0 * period_px));
  return cv::Rect(region.x + kept_box_w.x * f - margin, region.y + kept_box_w.y * f - margin,
                  kept_box_w.width * f + 2 * margin, kept_box_w.height * f + 2 * margin);
}

// A contact whose equivalent radius sqrt(a b) is under ridge_label_below_periods ridge periods: the logistic
// fit to the ridge labels (the brackets otherwise).
bool is_small_contact(const std::optional<Ellipse>& ellipse, double period_px,
                      const SegmenterOptions& options) {
  return ellipse && std::sqrt(ellipse->semi_major_px * ellipse->semi_minor_px) <
                        options.ridge_label_below_periods * period_px;
}

// Whether the ridge labels set the centre: asked for (or a small contact), a known polarity, an outline off
// the frame's edge, no saturation, and no border averaging unless the band fit can use the frame alone (the
// labels would be clipped or noise-limited).
bool ridge_labels_apply(const ContactResult& result, std::uint32_t status, int polarity, bool small_contact,
                        const SegmenterOptions& options) {
  return result.ellipse && (options.ridge_label_centre || small_contact) && polarity != 0 &&
         (status & (kTouchesEdge | kSaturated)) == 0 &&
         (!result.border_averaged || (options.border_band_centre && !small_contact));
}

// The flat field's surface, from working pixels of the region to frame pixels (empty without a flat field).
std::function<double(double, double)> illumination_in_frame(const std::optional<QuadraticSurface>& background,
                                                            const RegionView& view) {
  if (!background) return {};
  const cv::Point2d origin = view.origin();
  const int f = view.factor;
  return [surface = *background, origin, f](double x_px, double y_px) {
    return surface((x_px - origin.x + 0.5) / f - 0.5, (y_px - origin.y + 0.5) / f - 0.5);
  };
}

// The ridge orientation field inside the final outline, into the frame's blocks of `result` (the region's
// blocks are whole blocks of the frame: its origin is on the block grid).
void orientation_in_contact(const cv::Mat& band, const RegionView& view, int block_px, cv::Mat& hull_mask,
                            ContactResult& result) {
  std::vector<cv::Point2d> outline_w;
  outline_w.reserve(result.outline_px.size());
  const cv::Point2d origin = view.origin();
  const int f = view.factor;
  for (const auto& p : result.outline_px)
    outline_w.emplace_back((p.x - origin.x + 0.5) / f - 0.5, (p.y - origin.y + 0.5) / f - 0.5);
  hull_mask = rasterize_polygon(outline_w, view.size_w);
  OrientationField field = block_orientation(band, f, view.region_px.size(), block_px, hull_mask);
  const cv::Rect target(view.region_px.x / block_px, view.region_px.y / block_px, field.orientation_rad.cols,
                        field.orientation_rad.rows);
  const cv::Rect inside = target & cv::Rect(0, 0, result.orientation_rad.cols, result.orientation_rad.rows);
  const cv::Rect source(0, 0, inside.width, inside.height);
  field.orientation_rad(source).copyTo(result.orientation_rad(inside));
  field.coherence(source).copyTo(result.coherence(inside));
}

}  // namespace

std::string contact_status_text(std::uint32_t status) {
  if (status == kContactOk) return "ok";
  static const std::array<const char*, 7> names = {"no_contact",   "touches_edge", "multiple_blobs",
                                                   "saturated",    "low_contrast", "no_ellipse",
                                                   "frame_skipped"};
  std::string text;
  for (std::size_t bit = 0; bit < names.size(); ++bit) {
    if ((status & (1u << bit)) == 0) continue;
    // Appended piecewise: GCC 12 at -O3 reports a false -Wrestrict on `"|" + std::string(...)`.
    if (!text.empty()) text.push_back('|');
    text.append(names[bit]);
  }
  return text.empty() ? "unknown" : text;
}

ContactSegmenter::ContactSegmenter(SegmenterOptions options) : options_(std::move(options)) {
  options_.check();
  if (options_.ridge_period_px) period_px_ = *options_.ridge_period_px;
}

double ContactSegmenter::period_for_frame(const cv::Mat& image, double full_scale) {
  if (period_px_) return *period_px_;
  const double ppmm = options_.px_per_mm;
  // Measured at a resolution where the shortest plausible period still spans >= 3 pixels.
  const int factor = std::max(1, static_cast<int>(std::floor(options_.min_period_mm * ppmm / 3.0)));
  to_working_image(image, factor, full_scale, buf_.measure, buf_.working);
  const auto estimate =
      estimate_ridge_period(buf_.measure, std::max(2.0, options_.min_period_mm * ppmm / factor),
                            options_.max_period_mm * ppmm / factor);
  if (estimate && estimate->confidence >= options_.min_period_confidence) {
    period_px_ = estimate->period_px * factor;
    period_measured_ = true;
    return *period_px_;
  }
  return options_.default_period_mm * ppmm;
}

ContactResult ContactSegmenter::segment(const cv::Mat& image) {
  if (image.channels() != 1 || (image.depth() != CV_8U && image.depth() != CV_16U && image.depth() != CV_32F))
    throw Error("contact segmentation needs a grey 8-bit, 16-bit or float image");
  const cv::Rect frame(0, 0, image.cols, image.rows);
  // Tracking: around the last contact, unless a whole frame is due or the region is no longer usable.
  if (options_.track_region && roi_.area() > 0 && image.size() == roi_frame_ &&
      frames_since_full_ + 1 < std::max(1, options_.full_frame_every)) {
    bool left_region = false;
    ContactResult tracked = segment_region(image, roi_, &left_region);
    if (!left_region && (tracked.status & (kNoContact | kNoEllipse)) == 0) {
      ++frames_since_full_;
      update_region(tracked, frame);
      return tracked;
    }
  }
  bool unused = false;
  ContactResult result = segment_region(image, frame, &unused);
  frames_since_full_ = 0;
  update_region(result, frame);
  return result;
}

void ContactSegmenter::update_region(const ContactResult& result, const cv::Rect& frame) {
  roi_ = cv::Rect();
  roi_frame_ = frame.size();
  if (!options_.track_region || (result.status & (kNoContact | kNoEllipse)) != 0) return;
  const cv::Rect& box = result.bounding_box_px;
  const int margin = static_cast<int>(
      std::ceil(std::max(options_.region_margin_periods * result.ridge_period_px,
                         options_.region_margin_fraction * std::max(box.width, box.height))));
  const cv::Rect grown =
      cv::Rect(box.x - margin, box.y - margin, box.width + 2 * margin, box.height + 2 * margin) & frame;
  // Not worth it when the region is most of the frame.
  if (grown.area() <= 0.6 * frame.area()) roi_ = grown;
}

ContactResult ContactSegmenter::segment_small_contact(const cv::Mat& image, const cv::Rect& box_px,
                                                      std::uint32_t multiple_blobs) {
  const cv::Rect frame(0, 0, image.cols, image.rows);
  small_contact_pass_ = true;
  bool fine_left = false;
  ContactResult fine = segment_region(image, box_px & frame, &fine_left);
  if (fine_left) fine = segment_region(image, frame, &fine_left);
  small_contact_pass_ = false;
  if ((fine.status & kNoContact) == 0) fine.status |= multiple_blobs;
  return fine;
}

double ContactSegmenter::region_noise_energy(const RegionView& view, double period_w) {
  if (period_w != noise_energy_period_w_) {
    noise_energy_per_sigma_ = noise_energy_per_sigma(period_w);
    noise_energy_period_w_ = period_w;
  }
  cv::Mat counted;
  if (view.excluded_w.area() > 0) {
    counted = cv::Mat(buf_.work.size(), CV_8U, cv::Scalar(1));
    counted(view.excluded_w).setTo(0);
  }
  return noise_energy_per_sigma_ * immerkaer_noise_sigma(buf_.work, counted);
}

// The steps of one segmentation, in order (docs/contact.md, "The steps of one frame"): working image,
// texture energy and the contact / no contact decision, the textured regions joined into a coarse hull,
// polarity, the level edge prepared (flat field, border averaging, merged level), the outline refined along
// rays and repaired, the ellipse, the ridge labels' centre, size and shape, the orientation field.
ContactResult ContactSegmenter::segment_region(const cv::Mat& image, cv::Rect region, bool* left_region) {
  const int block_px = std::max(1, options_.block_px);
  ContactResult result = empty_result(image.size(), block_px);
  if (image.empty()) return result;
  const double full_scale = full_scale_of(image);
  const double period_px = period_for_frame(image, full_scale);
  result.ridge_period_px = period_px;
  factor_ = working_factor(options_.downsample, small_contact_pass_, period_px);
  const int f = factor_;
  const cv::Rect frame(0, 0, image.cols, image.rows);
  region = snap_region(region, frame, f, block_px);

  result.saturated_fraction = working_image_of(image, region, f, full_scale, buf_.work, buf_.working);
  const std::uint32_t saturated_flag =
      result.saturated_fraction >= options_.saturated_fraction ? kSaturated : 0u;
  if (region.width / f < 8 || region.height / f < 8) return no_contact(result, saturated_flag);
  const RegionView view = region_view(region, frame, f, buf_.work.size(), options_.exclude_px);
  const double period_w = period_px / f;
  const double reach_w = std::max(3.0, 1.5 * period_w);  // how far each ray looks either side of the hull

  // Texture: is there contact, and which regions make it.
  ridge_texture_energy(buf_.work, period_w, view.excluded_w, buf_.texture);
  const OtsuSplit split = otsu(buf_.texture.energy);
  record_texture(split, result);
  if (split.mean_high < options_.min_energy) return no_contact(result, saturated_flag);
  float threshold = split.threshold;
  if (result.energy_ratio < options_.min_energy_ratio) {
    // Otsu's low class is no background: either there is no contact, or the contact fills the region and
    // both classes are ridges. The low class against what the region's own noise gives decides, by the
    // same ratio a background would have to keep below the texture.
    const double noise_energy = region_noise_energy(view, period_w);
    if (split.mean_low < options_.min_energy_ratio * noise_energy) return no_contact(result, saturated_flag);
    threshold = static_cast<float>(options_.min_energy_ratio * noise_energy);
  }
  label_texture_regions(buf_.texture.energy, threshold, buf_.regions);
  const double mm2_per_working_px = (f * f) / (options_.px_per_mm * options_.px_per_mm);
  if (buf_.regions.largest == 0 || buf_.regions.largest_area * mm2_per_working_px < options_.min_area_mm2)
    return no_contact(result, saturated_flag);
  const JoinedRegions joined =
      join_to_largest(buf_.regions, options_.merge_fraction, options_.merge_gap_periods * period_w,
                      mm2_per_working_px, options_.min_area_mm2);
  std::uint32_t status = saturated_flag | (joined.multiple_blobs ? kMultipleBlobs : 0u);
  if (const auto box = small_contact_box(buf_.regions.largest_area, joined.box_w, region, f, period_px,
                                         options_, small_contact_pass_))
    return segment_small_contact(image, *box, status & kMultipleBlobs);
  const std::vector<cv::Point2d> hull_w = convex_hull(kept_boundary(buf_.regions.labels, joined.keep));
  const cv::Point2d centroid_w = mean_point(hull_w);

  // Polarity: the scene's, or this frame's; then the level edge's images.
  buf_.hull_mask = rasterize_polygon(hull_w, buf_.work.size());
  result.polarity = measured_polarity(buf_.work, buf_.hull_mask, split.mean_high);
  const int polarity = options_.polarity != 0 ? options_.polarity : result.polarity;
  const CoarseContact coarse{&buf_.work, &buf_.hull_mask, &hull_w, centroid_w, polarity, split.mean_high};
  const LevelEdgeSetup setup =
      prepare_level_edge(coarse, view, period_px, reach_w, options_, buf_.level, buf_.mask_scratch);
  result.texture_snr = setup.texture_snr;
  result.border_averaged = setup.border_averaged;

  // The outline along rays through 4x hull_points samples of the coarse hull, repaired; its ellipse.
  const EdgeSearch search{
      &buf_.texture.energy, split.threshold,          &buf_.level, &setup, reach_w, period_w,
      options_.edge_level,  options_.crest_edge_level};
  const std::vector<cv::Point2d> samples_w =
      resample_closed_polygon(hull_w, 4 * std::max(options_.hull_points, 8));
  RefinedOutline outline = refine_outline(samples_w, centroid_w, view, search, buf_.ray);
  if (outline.left_region) *left_region = true;
  if (outline.touches_edge) status |= kTouchesEdge;
  set_outline(outline, view.to_frame(centroid_w), period_px, options_, image.size(), result);
  result.ellipse = fit_free_outline(result, outline, f, image.size(), options_.exclude_px);

  // The centre (and size and shape) from where ridges show near the border.
  const bool small_contact = is_small_contact(result.ellipse, period_px, options_);
  if (ridge_labels_apply(result, status, polarity, small_contact, options_)) {
    const LabelRefinementFrame label_frame{&image,        full_scale,
                                           period_px,     polarity,
                                           small_contact, illumination_in_frame(setup.background, view)};
    refine_with_ridge_labels(label_frame, options_, result);
  }
  if (small_contact && result.ellipse && !(status & kTouchesEdge) && options_.small_contact_ellipse_outline)
    set_outline_from_ellipse(*result.ellipse, options_, image.size(), result);
  if (result.ellipse) {
    result.normalization = EllipseNormalization(*result.ellipse);
  } else {
    status |= kNoEllipse;
  }
  if (options_.orientation) orientation_in_contact(buf_.texture.band, view, block_px, buf_.hull_mask, result);
  if (split.mean_high < options_.low_contrast) status |= kLowContrast;
  result.status = status;
  return result;
}

}  // namespace tirstrain::contact
