#include "pipeline/contact_stage.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numbers>
#include <optional>

#include "core/csv.hpp"
#include "core/median.hpp"
#include "core/yaml_reader.hpp"
#include "pipeline/contact_centre_smoothing.hpp"

namespace tirstrain::pipeline {
namespace {

// What is kept per frame: small and fixed-size, so memory grows by ~11 kB per 1280x1024 frame.
struct ContactRecord {
  std::uint32_t status = contact::kNoContact;
  double area_mm2 = 0.0;
  std::vector<cv::Point2d> hull_px;
  std::array<double, 5> ellipse{};  // cx, cy, semi-major, semi-minor, angle; zeros without an ellipse
  double texture_snr = 0.0;
  bool border_averaged = false;
  bool border_band_used = false;
  std::optional<cv::Point2d> ridge_label_shift_px;
  std::optional<cv::Vec3d> ridge_label_shape_px;
  cv::Mat orientation_rad, coherence;
  // Set after the trial where the centre was smoothed in time: the segmenter's own centre (ellipse[0..1] and
  // hull_px then carry the smoothed one). Not archived: it is set after the last frame.
  std::optional<cv::Point2d> measured_centre_px;

  void archive(Archive& a) {
    a(status, area_mm2, hull_px, ellipse, texture_snr, border_averaged, border_band_used,
      ridge_label_shift_px, ridge_label_shape_px, orientation_rad, coherence);
  }
};

class ContactStage final : public Stage {
 public:
  explicit ContactStage(const Scene& scene) : ContactStage(contact_stage_options_for(scene)) {
    period_source_ = scene.ridge_period_mm ? "scene" : "measured";
  }
  explicit ContactStage(const ContactStageOptions& options)
      : options_(options.segmenter),
        segmenter_(options_),
        smooth_centre_in_time_(options.smooth_centre_in_time) {}

  std::string name() const override { return "contact"; }

  void start(const TrialInfo& info) override {
    keep_history_ = info.keep_history;
    const int block = options_.block_px;
    blocks_ =
        cv::Size((info.frame_size.width + block - 1) / block, (info.frame_size.height + block - 1) / block);
  }

  void archive(Archive& a) override {
    a(segmenter_, records_, segment_s_, segmented_, dark_votes_, bright_votes_);
  }

  void process(FrameContext& context) override {
    ContactRecord record;
    if (!context.usable) {
      record.status = contact::kFrameSkipped;
      remember(records_, std::move(record), keep_history_);
      return;
    }
    const auto t0 = std::chrono::steady_clock::now();
    contact::ContactResult result = segmenter_.segment(context.frame->image);
    segment_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ++segmented_;
    record.status = result.status;
    record.area_mm2 = result.area_mm2;
    record.hull_px = result.hull_px;
    record.texture_snr = result.texture_snr;
    record.border_averaged = result.border_averaged;
    record.border_band_used = result.border_band_used;
    record.ridge_label_shift_px = result.ridge_label_shift_px;
    record.ridge_label_shape_px = result.ridge_label_shape_px;
    if (result.ellipse) {
      const auto& e = *result.ellipse;
      record.ellipse = {e.cx_px, e.cy_px, e.semi_major_px, e.semi_minor_px, e.angle_rad};
    }
    record.orientation_rad = result.orientation_rad;
    record.coherence = result.coherence;
    if (result.polarity < 0) ++dark_votes_;
    if (result.polarity > 0) ++bright_votes_;
    remember(records_, std::move(record), keep_history_);
    context.contact = std::move(result);
  }

  // What process() gave the later stages for row `row` (the model fit reads the frame's ellipse): the
  // frame's own measurement, before any smoothing of the centres in time, as when the frames were read.
  void replay(FrameContext& context, std::size_t row) override {
    if (!keep_history_ || row >= records_.size() || !context.usable) return;
    const ContactRecord& r = records_[row];
    contact::ContactResult result;
    result.status = r.status;
    result.area_mm2 = r.area_mm2;
    result.hull_px = r.hull_px;
    result.texture_snr = r.texture_snr;
    result.border_averaged = r.border_averaged;
    result.border_band_used = r.border_band_used;
    result.ridge_label_shift_px = r.ridge_label_shift_px;
    result.ridge_label_shape_px = r.ridge_label_shape_px;
    result.orientation_rad = r.orientation_rad;
    result.coherence = r.coherence;
    if (r.ellipse[2] > 0.0) {
      const cv::Point2d centre = r.measured_centre_px.value_or(cv::Point2d(r.ellipse[0], r.ellipse[1]));
      result.ellipse = contact::Ellipse{centre.x, centre.y, r.ellipse[2], r.ellipse[3], r.ellipse[4]};
    }
    context.contact = std::move(result);
  }

  // Smooths the centres in time. The stages after this one read the contact only while the frames are
  // processed (the tracker's mask and reference ellipse), so nothing they derive changes: false.
  bool finish() override {
    if (keep_history_ && smooth_centre_in_time_) smooth_centres();
    return false;
  }

  void draw(cv::Mat& bgr, const FrameContext& context, const OverlayText& overlay) const override {
    if (!context.contact) return;
    const contact::ContactResult& r = *context.contact;
    const double thickness_scale = std::max(1.0, bgr.cols / 640.0);
    const int thick = static_cast<int>(std::lround(thickness_scale));
    constexpr int kShift = 4;
    const auto fixed = [](const cv::Point2d& p) {
      return cv::Point(static_cast<int>(std::lround(p.x * (1 << kShift))),
                       static_cast<int>(std::lround(p.y * (1 << kShift))));
    };
    // Orientation: a short segment along the ridges in every block, brighter where coherence is higher.
    const int block = options_.block_px;
    for (int by = 0; by < r.coherence.rows; ++by)
      for (int bx = 0; bx < r.coherence.cols; ++bx) {
        const float coherence = r.coherence.at<float>(by, bx);
        if (coherence < 0.2f) continue;
        const double a = r.orientation_rad.at<float>(by, bx);
        const cv::Point2d centre(bx * block + block / 2.0 - 0.5, by * block + block / 2.0 - 0.5);
        const cv::Point2d half(0.4 * block * std::cos(a), 0.4 * block * std::sin(a));
        cv::line(bgr, fixed(centre - half), fixed(centre + half),
                 cv::Scalar(0, 200.0 * coherence + 55.0, 255), thick, cv::LINE_AA, kShift);
      }
    if (!r.hull_px.empty()) {
      std::vector<cv::Point> hull;
      for (const auto& p : r.hull_px) hull.push_back(fixed(p));
      cv::polylines(bgr, hull, true, cv::Scalar(0, 220, 0), thick, cv::LINE_AA, kShift);
    }
    if (r.ellipse) {
      const auto& e = *r.ellipse;
      cv::ellipse(bgr, fixed({e.cx_px, e.cy_px}),
                  cv::Size(static_cast<int>(std::lround(e.semi_major_px * (1 << kShift))),
                           static_cast<int>(std::lround(e.semi_minor_px * (1 << kShift)))),
                  e.angle_rad * 180.0 / std::numbers::pi, 0.0, 360.0, cv::Scalar(60, 60, 255), thick,
                  cv::LINE_AA, kShift);
    }
    char text[160];
    std::snprintf(text, sizeof text, "contact: %s  area %.2f mm2",
                  contact::contact_status_text(r.status).c_str(), r.area_mm2);
    overlay.status_line(bgr, 1, text);
  }

  std::vector<std::string> csv_header() const override {
    return {"contact_status", "area_mm2", "cx_px", "cy_px", "semi_major_px", "semi_minor_px", "angle_rad"};
  }

  void csv_row(std::size_t row, std::vector<std::string>& cells) const override {
    const ContactRecord& r = records_.at(row);
    cells.push_back(std::to_string(r.status));
    cells.push_back(format_double(r.area_mm2));
    for (double v : r.ellipse) cells.push_back(format_double(v));
  }

  void write(H5Stream& out) const override {
    const std::size_t n = records_.size();
    const auto hull_points = static_cast<std::size_t>(options_.hull_points);
    const auto by = static_cast<std::size_t>(blocks_.height), bx = static_cast<std::size_t>(blocks_.width);
    std::vector<std::int32_t> status(n);
    std::vector<double> area(n), hull(n * hull_points * 2, 0.0), ellipse(n * 5, 0.0), snr(n);
    std::vector<std::int8_t> averaged(n), labelled(n), band(n);
    std::vector<double> shift(n * 2, 0.0), shape(n * 3, 0.0), measured_centre(n * 2, 0.0);
    std::vector<std::int8_t> smoothed(n, 0);
    std::vector<float> orientation(n * by * bx, 0.0f), coherence(n * by * bx, 0.0f);
    for (std::size_t i = 0; i < n; ++i) {
      const ContactRecord& r = records_[i];
      status[i] = static_cast<std::int32_t>(r.status);
      area[i] = r.area_mm2;
      snr[i] = r.texture_snr;
      averaged[i] = r.border_averaged ? 1 : 0;
      labelled[i] = r.ridge_label_shift_px ? 1 : 0;
      band[i] = r.border_band_used ? 1 : 0;
      if (r.ridge_label_shift_px) {
        shift[i * 2] = r.ridge_label_shift_px->x;
        shift[i * 2 + 1] = r.ridge_label_shift_px->y;
      }
      if (r.ridge_label_shape_px)
        for (std::size_t j = 0; j < 3; ++j) shape[i * 3 + j] = (*r.ridge_label_shape_px)[static_cast<int>(j)];
      measured_centre[i * 2] = r.measured_centre_px ? r.measured_centre_px->x : r.ellipse[0];
      measured_centre[i * 2 + 1] = r.measured_centre_px ? r.measured_centre_px->y : r.ellipse[1];
      smoothed[i] = r.measured_centre_px ? 1 : 0;
      for (std::size_t k = 0; k < r.hull_px.size() && k < hull_points; ++k) {
        hull[(i * hull_points + k) * 2] = r.hull_px[k].x;
        hull[(i * hull_points + k) * 2 + 1] = r.hull_px[k].y;
      }
      std::copy(r.ellipse.begin(), r.ellipse.end(), ellipse.begin() + static_cast<std::ptrdiff_t>(i * 5));
      if (!r.orientation_rad.empty() && r.orientation_rad.size() == blocks_) {
        const auto offset = static_cast<std::ptrdiff_t>(i * by * bx);
        std::copy(r.orientation_rad.begin<float>(), r.orientation_rad.end<float>(),
                  orientation.begin() + offset);
        std::copy(r.coherence.begin<float>(), r.coherence.end<float>(), coherence.begin() + offset);
      }
    }
    out.write("/contact/status", std::span<const std::int32_t>(status), {n});
    out.write("/contact/area_mm2", std::span<const double>(area), {n});
    out.write("/contact/hull_px", std::span<const double>(hull), {n, hull_points, 2});
    out.write("/contact/ellipse", std::span<const double>(ellipse), {n, 5});
    out.write("/contact/orientation_rad", std::span<const float>(orientation), {n, by, bx});
    out.write("/contact/coherence", std::span<const float>(coherence), {n, by, bx});
    out.write("/contact/texture_snr", std::span<const double>(snr), {n});
    out.write("/contact/border_averaged", std::span<const std::int8_t>(averaged), {n});
    out.write("/contact/ridge_label_centre", std::span<const std::int8_t>(labelled), {n});
    out.write("/contact/border_band_centre", std::span<const std::int8_t>(band), {n});
    out.write("/contact/ridge_label_shift_px", std::span<const double>(shift), {n, 2});
    out.write("/contact/ridge_label_shape_px", std::span<const double>(shape), {n, 3});
    out.write("/contact/centre_measured_px", std::span<const double>(measured_centre), {n, 2});
    out.write("/contact/centre_smoothed", std::span<const std::int8_t>(smoothed), {n});
    out.attribute("/contact", "centre_noise_px", centre_noise_px_);
    out.attribute("/contact", "px_per_mm", options_.px_per_mm);
    out.attribute("/contact", "ridge_period_px", period_px());
    out.attribute("/contact", "ridge_period_source", period_source());
    out.attribute("/contact", "ridge_polarity", polarity());
    out.attribute("/contact", "working_downsample", static_cast<double>(segmenter_.downsample()));
    out.attribute("/contact", "block_px", static_cast<double>(options_.block_px));
    out.attribute("/contact", "ellipse_columns", "cx_px,cy_px,semi_major_px,semi_minor_px,angle_rad");
    out.attribute("/contact", "status_bits",
                  "0 ok; 1 no_contact; 2 touches_edge; 4 multiple_blobs; 8 saturated; 16 low_contrast; "
                  "32 no_ellipse; 64 frame_skipped");
  }

  void summarize(nlohmann::json& summary) const override {
    nlohmann::json c;
    std::int64_t with_contact = 0;
    double area_sum = 0.0, area_max = 0.0;
    std::map<std::string, std::int64_t> flags;
    std::int64_t border_averaged = 0, ridge_label_centre = 0, border_band = 0;
    std::vector<double> snr;
    for (const auto& r : records_) {
      if ((r.status & (contact::kNoContact | contact::kFrameSkipped)) == 0) {
        ++with_contact;
        if (r.border_averaged) ++border_averaged;
        if (r.ridge_label_shift_px) ++ridge_label_centre;
        if (r.border_band_used) ++border_band;
        if (r.texture_snr > 0.0) snr.push_back(r.texture_snr);
        area_sum += r.area_mm2;
        area_max = std::max(area_max, r.area_mm2);
      }
      for (std::uint32_t bit = 1; bit <= contact::kFrameSkipped; bit <<= 1)
        if ((r.status & bit) != 0) ++flags[contact::contact_status_text(bit)];
    }
    c["frames_with_contact"] = with_contact;
    c["status_counts"] = flags;
    c["area_mm2_mean"] = with_contact > 0 ? area_sum / static_cast<double>(with_contact) : 0.0;
    c["area_mm2_max"] = area_max;
    c["ridge_period_px"] = period_px();
    c["ridge_period_mm"] = period_px() / options_.px_per_mm;
    c["ridge_period_source"] = period_source();
    c["ridge_polarity"] = polarity();
    c["working_downsample"] = segmenter_.downsample();
    if (!snr.empty()) {
      c["texture_snr_median"] = upper_median_in_place(snr);
    } else {
      c["texture_snr_median"] = nullptr;
    }
    c["frames_border_averaged"] = border_averaged;
    c["frames_ridge_label_centre"] = ridge_label_centre;
    c["frames_border_band_centre"] = border_band;
    c["frames_centre_smoothed"] = centre_smoothed_frames_;
    c["centre_noise_px"] = centre_noise_px_;
    // The switches in effect (the preset's, after the scene's own keys and --segmentation).
    c["settings"] = {{"flat_field", options_.flat_field},
                     {"border_average_snr", options_.border_average_snr},
                     {"ridge_label_centre", options_.ridge_label_centre},
                     {"ridge_label_below_periods", options_.ridge_label_below_periods},
                     {"ridge_label_shape_weight", options_.ridge_label_shape_weight},
                     {"small_contact_ellipse_outline", options_.small_contact_ellipse_outline},
                     {"border_band_centre", options_.border_band_centre},
                     {"downsample", options_.downsample},
                     {"smooth_centre_in_time", smooth_centre_in_time_}};
    c["segment_ms_per_frame"] = segmented_ > 0 ? 1e3 * segment_s_ / static_cast<double>(segmented_) : 0.0;
    summary["contact"] = c;
  }

 private:
  // The ellipse's centre, and the outline with it, moved to the centre smoothed in time; the measured one
  // kept.
  void smooth_centres() {
    std::vector<std::optional<Vec2>> measured(records_.size());
    for (std::size_t i = 0; i < records_.size(); ++i) {
      const ContactRecord& r = records_[i];
      const bool has_ellipse =
          (r.status & (contact::kNoContact | contact::kFrameSkipped | contact::kNoEllipse)) == 0 &&
          r.ellipse[2] > 0.0;
      if (has_ellipse) measured[i] = Vec2{r.ellipse[0], r.ellipse[1]};
    }
    const CentreSmoothing smoothing = smooth_centres_in_time(measured);
    centre_noise_px_ = smoothing.noise_px;
    centre_smoothed_frames_ = smoothing.frames_changed;
    for (std::size_t i = 0; i < records_.size(); ++i) {
      if (!smoothing.changed[i]) continue;
      ContactRecord& r = records_[i];
      const cv::Point2d shift(smoothing.centre_px[i]->x - r.ellipse[0],
                              smoothing.centre_px[i]->y - r.ellipse[1]);
      r.measured_centre_px = cv::Point2d(r.ellipse[0], r.ellipse[1]);
      r.ellipse[0] += shift.x;
      r.ellipse[1] += shift.y;
      for (cv::Point2d& p : r.hull_px) p += shift;
    }
  }

  double period_px() const {
    return segmenter_.ridge_period_px().value_or(options_.default_period_mm * options_.px_per_mm);
  }
  std::string period_source() const {
    if (options_.ridge_period_px) return "scene";
    return segmenter_.period_measured() ? "measured" : "default (no clear ridge ring in any frame)";
  }
  std::string polarity() const {
    if (dark_votes_ == 0 && bright_votes_ == 0) return "unknown";
    return dark_votes_ >= bright_votes_ ? "dark" : "bright";
  }

  contact::SegmenterOptions options_;
  contact::ContactSegmenter segmenter_;
  bool smooth_centre_in_time_ = true;
  std::string period_source_;
  cv::Size blocks_;
  std::vector<ContactRecord> records_;
  bool keep_history_ = true;
  double segment_s_ = 0.0;
  std::int64_t segmented_ = 0;
  std::int64_t dark_votes_ = 0, bright_votes_ = 0;
  double centre_noise_px_ = 0.0;
  std::int64_t centre_smoothed_frames_ = 0;
};

}  // namespace

ContactStageOptions contact_stage_options_for(const Scene& scene) {
  ContactStageOptions stage;
  contact::SegmenterOptions& options = stage.segmenter;
  options.px_per_mm = scene.px_per_mm;
  if (scene.ridge_period_mm) options.ridge_period_px = *scene.ridge_period_mm * scene.px_per_mm;
  if (scene.ridge_polarity == "dark") options.polarity = -1;
  if (scene.ridge_polarity == "bright") options.polarity = 1;
  if (scene.reference_pattern_roi) {
    const RoiPx& r = *scene.reference_pattern_roi;
    const int m = std::max(0, scene.reference_pattern_margin_px);
    options.exclude_px = cv::Rect(r.x - m, r.y - m, r.width + 2 * m, r.height + 2 * m);
  }
  // segmentation: {preset: accurate, downsample: 0, flat_field: true, border_average_snr: 20,
  // ridge_label_centre: true, ridge_label_below_periods: 5, ridge_label_shape_weight: 0.5,
  // border_band_centre: true, small_contact_ellipse_outline: true, smooth_centre_in_time: true} — the preset
  // (accurate, balanced or fast: contact::SegmentationPreset) sets the switches below, and those the scene
  // sets override it one by one; the working-resolution factor (0 automatic from the ridge period, 1 full);
  // the background flat field; the texture SNR below which the edge is searched on the frame averaged along
  // the border (0: never); the centre from where ridges show near the border, on large contacts and on those
  // under so many ridge periods in radius (0: none); on those small ones, the weight of the labels'
  // elongation against the level edge's (0: the level edge's); the border band's intensity fit for the centre
  // of large contacts; the small ones' outline from their ellipse; the centre smoothed in time after the
  // trial. See contact/segmenter.hpp and pipeline/contact_centre_smoothing.hpp.
  YamlSection s(scene.segmentation, scene.file, "segmentation");
  const std::string preset = s.choice("preset", "accurate", {"accurate", "balanced", "fast"});
  options = contact::with_preset(options, preset == "fast"       ? contact::SegmentationPreset::fast
                                          : preset == "balanced" ? contact::SegmentationPreset::balanced
                                                                 : contact::SegmentationPreset::accurate);
  options.downsample = static_cast<int>(s.integer("downsample", options.downsample, 0, 16));
  options.flat_field = s.boolean("flat_field", options.flat_field);
  options.border_average_snr = s.number("border_average_snr", options.border_average_snr, 0.0, 1e9);
  options.ridge_label_centre = s.boolean("ridge_label_centre", options.ridge_label_centre);
  options.ridge_label_below_periods =
      s.number("ridge_label_below_periods", options.ridge_label_below_periods, 0.0, 1e6);
  options.ridge_label_shape_weight =
      s.number("ridge_label_shape_weight", options.ridge_label_shape_weight, 0.0, 1.0);
  options.border_band_centre = s.boolean("border_band_centre", options.border_band_centre);
  options.small_contact_ellipse_outline =
      s.boolean("small_contact_ellipse_outline", options.small_contact_ellipse_outline);
  stage.smooth_centre_in_time = s.boolean("smooth_centre_in_time", stage.smooth_centre_in_time);
  s.finish();
  return stage;
}

contact::SegmenterOptions segmenter_options_for(const Scene& scene) {
  return contact_stage_options_for(scene).segmenter;
}

std::unique_ptr<Stage> make_contact_stage(const Scene& scene) {
  return std::make_unique<ContactStage>(scene);
}

}  // namespace tirstrain::pipeline
