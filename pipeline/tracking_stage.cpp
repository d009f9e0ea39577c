#include "pipeline/tracking_stage.hpp"

#include <Eigen/Core>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>

#include "core/csv.hpp"
#include "core/median.hpp"
#include "flow/model_check.hpp"
#include "flow/settings.hpp"
#include "flow/temporal_smoothing.hpp"
#include "pipeline/tracking_report.hpp"

namespace tirstrain::pipeline {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
// /tracks/status for a track that does not exist in a frame (not born yet, or retired in an earlier frame).
constexpr std::int8_t kAbsent = -1;
constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
// Contacts with semi-minor/semi-major above this are treated as circles by the normalised maps.
constexpr double kCircularAspect = 0.95;

// What is kept per frame: scalars only (for frames.csv, summary.json and replay); the tracks' positions and
// statuses go to result.h5 as the frame is done.
struct TrackFrame {
  double t_s = kNaN;
  int tracker_frame = -1;  // -1: not tracked (before the reference frame, or unusable)
  std::size_t tracks = 0;  // tracks that existed at this frame (the width of its /tracks rows)
  bool rest_tested = false, at_rest = false;
  double rest_chi2_per_dof = kNaN, rest_correlation_z = kNaN;
  bool affine_tested = false, affine_fit = false;
  double affine_chi2_per_dof = kNaN, affine_correlation_z = kNaN, affine_hidden_px = kNaN;
  std::optional<Vec2> plate_px;
  std::int8_t plate_status = kAbsent;  // flow::PlateStatus, kAbsent where not measured
  int alive = 0, born = 0, retired = 0;
};

// One frame's /tracks rows, built from the tracker and written at once: the columns (track ids) of the
// tracks alive or retired in this frame, and their values in that order; every other track's cells hold the
// fill value.
struct TrackRow {
  std::vector<std::size_t> column;
  std::vector<double> position_px;  // per column x 2
  std::vector<std::int8_t> status;
  // What each position is (flow::TrackModel) and the statistic that let a model stand in for the match.
  std::vector<std::uint8_t> model;
  std::vector<float> model_mahalanobis2;
  std::vector<float> model_window_px;  // per column x 2: a local fit's window radius per component, px (NaN)
  std::vector<float> inside_fraction;  // share of the match's subset inside the contact
  std::vector<float> covariance_px2;   // per column x 3: the own match's, xx xy yy
};

// One track through time, read back from result.h5 for smoothing in time.
struct TrackColumn {
  std::vector<double> position_px;     // N x 2
  std::vector<double> covariance_px2;  // N x 3
  std::vector<double> model, model_mahalanobis2;
  std::vector<double> model_window_px;  // N x 2
};

class TrackingStage final : public Stage {
 public:
  explicit TrackingStage(const Scene& scene) : scene_(scene) {
    // Parsed now so that a bad `tracking:` section stops the run before any frame is read; sized again
    // from the measured ridge period when the reference frame arrives.
    settings_ = flow::parse_tracking_options(scene_);
  }

  std::string name() const override { return "tracking"; }

  void start(const TrialInfo& info) override {
    frame_size_ = info.frame_size;
    keep_history_ = info.keep_history;
    out_ = info.out;
  }

  void process(FrameContext& context) override {
    TrackFrame record;
    if (context.frame) record.t_s = context.frame->device_time_s;
    const bool has_contact = context.usable && context.contact &&
                             (context.contact->status & contact::kNoContact) == 0 &&
                             context.contact->outline_px.size() >= 3;
    if (!context.usable || (!tracker_ && !has_contact)) {
      write_row(TrackRow{}, record);
      remember(frames_, std::move(record), keep_history_);
      return;
    }
    contact_mask(context, has_contact);
    const auto t0 = std::chrono::steady_clock::now();
    if (!tracker_) {
      start_tracker(context);
    } else {
      track_frame(context, record);
    }
    track_s_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ++tracked_frames_;

    const int frame = tracker_->frame_index();
    record.tracker_frame = frame;
    tracker_rows_.push_back(static_cast<std::int64_t>(frames_.size()));
    const TrackRow row = record_tracks(record);
    record.plate_px = tracker_->plate_displacement_px();
    record.plate_status = tracker_->plate_status().value_or(kAbsent);
    if (record.plate_status > 0) ++plate_frames_not_matched_[record.plate_status == 1 ? 0 : 1];
    context.tracking = FrameContext::Tracking{&tracker_->tracks(), frame, frame == 0,
                                              &reference_normalization_, reference_has_ellipse_};
    context.plate_displacement_px = record.plate_px;
    write_row(row, record);
    remember(frames_, std::move(record), keep_history_);
  }

  // The tracker's state inside the stage's: the tracker is made again with the settings sized on its
  // reference frame and given back its state.
  void archive(Archive& a) override {
    bool started = tracker_ != nullptr;
    a(started, settings_);
    if (a.reading())
      tracker_ =
          started ? std::make_unique<flow::FeatureTracker>(settings_, scene_.reference_pattern_roi) : nullptr;
    if (started) tracker_->archive(a);
    a.layout(sizeof(TrackFrame), "tracking record");
    a(reference_normalization_, reference_has_ellipse_, reference_row_, reference_frame_index_, frames_,
      tracker_rows_, track_s_, tracked_frames_, plate_frames_not_matched_, rest_frames_averaged_,
      rest_frames_on_fit_, affine_fit_frames_, model_track_frames_, local_fit_by_component_, fusion_declined_,
      smoothing_declined_, unmeasured_direction_);
  }

  // Positions with a direction no match measured are said, with how many and where to see them.
  std::vector<std::string> warnings() const override {
    std::vector<std::string> out;
    std::int64_t track_frames = 0;
    for (const std::int64_t n : model_track_frames_) track_frames += n;
    if (unmeasured_direction_ > 0 && track_frames > 0) {
      char share[32];
      std::snprintf(share, sizeof share, "%.1f",
                    100.0 * static_cast<double>(unmeasured_direction_) / static_cast<double>(track_frames));
      out.push_back(
          std::to_string(unmeasured_direction_) + " track-frames (" + share +
          " %) have a direction the texture does not determine (straight ridges, or no texture): "
          "their position is not measured along it (variance 100 px2 there in /tracks/covariance_px2, "
          "and the strain's /strain/total_sd)");
    }
    if (const std::string plate = plate_warning(); !plate.empty()) out.push_back(plate);
    return out;
  }

  // A band whose frames are mostly predicted or followed by LK alone was not matched into its own pattern:
  // the plate's motion (and the stick ratio measured against it) is then a guess, which is said.
  std::string plate_warning() const {
    if (!scene_.reference_pattern_roi || tracked_frames_ < 4) return {};
    const std::int64_t not_matched = plate_frames_not_matched_[0] + plate_frames_not_matched_[1];
    if (2 * not_matched <= tracked_frames_) return {};
    return "the plate was matched into its dot pattern in only " +
           std::to_string(tracked_frames_ - not_matched) + " of " + std::to_string(tracked_frames_) +
           " frames (" + std::to_string(plate_frames_not_matched_[0]) + " predicted from its last motion, " +
           std::to_string(plate_frames_not_matched_[1]) +
           " followed by LK alone; /plate/status): its displacement, and the stick ratio measured against "
           "it, "
           "are unreliable; check that reference_pattern.roi_px holds the printed dots";
  }

  // Smoothing in time (flow/temporal_smoothing.hpp) once the trial is complete, where the settings in effect
  // ask for it: "auto" on noisy texture only (the tracker's low-SNR subsets).
  bool finish() override {
    smoothed_ = will_smooth();
    if (!smoothed_) return false;
    smooth_tracks({.gamma = tracker_->settings().smoothing.gamma});
    return true;
  }

  // Known from frame 0 on (the texture is judged there), so the overlay can say it.
  bool will_smooth() const {
    if (!keep_history_ || !tracker_ || !out_) return false;
    const std::string& mode = tracker_->settings().smoothing.mode;
    return mode == "on" || (mode == "auto" && tracker_->low_snr_texture());
  }

  void replay(FrameContext& context, std::size_t row) override {
    const TrackFrame& f = frames_.at(row);
    if (f.tracker_frame < 0) return;
    // The tracks as they were in that frame: status and (revised) position from result.h5's row, the rest
    // as now.
    const std::vector<double> status = out_->read_block("/tracks/status", {row, 0}, {1, f.tracks});
    const std::vector<double> position =
        out_->read_block("/tracks/position_px", {row, 0, 0}, {1, f.tracks, 2});
    replay_tracks_ = tracker_->tracks();
    for (std::size_t k = 0; k < replay_tracks_.size(); ++k) {
      flow::Track& t = replay_tracks_[k];
      const bool existed = k < f.tracks && status[k] != kAbsent;
      t.status = existed ? static_cast<flow::TrackStatus>(status[k]) : flow::TrackStatus::kLeftContact;
      if (existed && flow::is_alive(t.status)) t.position_px = {position[2 * k], position[2 * k + 1]};
    }
    context.tracking = FrameContext::Tracking{&replay_tracks_, f.tracker_frame, f.tracker_frame == 0,
                                              &reference_normalization_, reference_has_ellipse_};
    context.plate_displacement_px = f.plate_px;
  }

  void draw(cv::Mat& bgr, const FrameContext& context, const OverlayText& overlay) const override {
    if (!context.tracking) return;
    const double scale = std::max(1.0, bgr.cols / 640.0);
    const int thick = static_cast<int>(std::lround(scale));
    constexpr int kShift = 4;
    const auto fixed = [](const Vec2& p) {
      return cv::Point(static_cast<int>(std::lround(p.x * (1 << kShift))),
                       static_cast<int>(std::lround(p.y * (1 << kShift))));
    };
    // Flow vectors: reference position → current position (the displacement since the reference frame),
    // and the current position as a dot coloured by status (green tracked, cyan newborn, orange recovered).
    for (const flow::Track& t : *context.tracking->tracks) {
      if (!flow::is_alive(t.status)) continue;
      cv::line(bgr, fixed(t.reference_px), fixed(t.position_px), cv::Scalar(0, 160, 0), 1, cv::LINE_AA,
               kShift);
      const cv::Scalar colour = t.status == flow::TrackStatus::kBorn        ? cv::Scalar(255, 255, 0)
                                : t.status == flow::TrackStatus::kRecovered ? cv::Scalar(0, 140, 255)
                                                                            : cv::Scalar(0, 255, 0);
      cv::circle(bgr, fixed(t.position_px), thick * (1 << kShift), colour, cv::FILLED, cv::LINE_AA, kShift);
    }
    // The pattern band's rectangle is drawn by process (pipeline/process.cpp), with where it came from.
    const TrackFrame& f = frames_.back();
    char text[200];
    // A plate displacement that was not matched into the pattern mosaic says how it was obtained.
    const char* plate_how = f.plate_status == 1 ? " predicted" : f.plate_status == 2 ? " LK only" : "";
    if (f.plate_px)
      std::snprintf(text, sizeof text, "tracks: %d alive (+%d, -%d)  plate (%.2f, %.2f) px%s", f.alive,
                    f.born, f.retired, f.plate_px->x, f.plate_px->y, plate_how);
    else
      std::snprintf(text, sizeof text, "tracks: %d alive (+%d, -%d)", f.alive, f.born, f.retired);
    overlay.status_line(bgr, 2, text);
    // The video shows each frame as tracked; the result files hold the tracks smoothed afterwards.
    if (will_smooth()) overlay.status_line(bgr, 5, "as tracked; result.h5 smoothed in time");
  }

  std::vector<std::string> csv_header() const override {
    return {"tracks_alive", "tracks_born", "tracks_retired", "plate_dx_px", "plate_dy_px", "plate_status"};
  }

  void csv_row(std::size_t row, std::vector<std::string>& cells) const override {
    const TrackFrame& f = frames_.at(row);
    cells.push_back(std::to_string(f.alive));
    cells.push_back(std::to_string(f.born));
    cells.push_back(std::to_string(f.retired));
    cells.push_back(format_double(f.plate_px ? f.plate_px->x : kNaN));
    cells.push_back(format_double(f.plate_px ? f.plate_px->y : kNaN));
    cells.push_back(std::to_string(f.plate_status));
  }

  // Per-track datasets and the attributes; the per-frame rows are written as frames are done.
  void write(H5Stream& out) const override {
    const std::size_t k = tracker_ ? tracker_->tracks().size() : 0;
    std::vector<double> reference(k * 2);
    std::vector<std::int32_t> born(k), retired(k);
    std::vector<std::int8_t> extrapolated(k, 0);
    for (std::size_t j = 0; j < k; ++j) {
      const flow::Track& t = tracker_->tracks()[j];
      extrapolated[j] = t.reference_extrapolated ? 1 : 0;
      reference[2 * j] = t.reference_px.x;
      reference[2 * j + 1] = t.reference_px.y;
      // Tracker frames count from the reference frame; stored as result.h5 frame rows (−1: never retired).
      born[j] = row_of_tracker_frame(t.born_frame);
      retired[j] = row_of_tracker_frame(t.retired_frame);
    }
    out.write("/tracks/reference_px", std::span<const double>(reference), {k, 2});
    out.write("/tracks/born_frame", std::span<const std::int32_t>(born), {k});
    out.write("/tracks/retired_frame", std::span<const std::int32_t>(retired), {k});
    out.write("/tracks/reference_extrapolated", std::span<const std::int8_t>(extrapolated), {k});
    write_attributes(out);
  }

  void summarize(nlohmann::json& summary) const override {
    nlohmann::json s;
    s["settings"] = settings_summary();
    s["started"] = tracker_ != nullptr;
    s["reference_frame_index"] = reference_frame_index_;
    // Frames at rest averaged into the reference frame's anchor, besides the reference frame itself.
    s["rest_frames_averaged"] = rest_frames_averaged_;
    // Frames at rest whose frame-0 tracks report the affine fit of their motion (docs/flow.md, step 5).
    s["rest_frames_on_fit"] = rest_frames_on_fit_;
    // Moving frames whose frame-0 tracks report the frame's affine fit (docs/flow.md, step 5).
    s["affine_fit_frames"] = affine_fit_frames_;
    // Track-frames by what their position is (docs/flow.md, what a position is): no model stands in for a
    // match unless a test on that frame accepted it.
    s["track_frames_by_model"] = {
        {"own_match", model_track_frames_[0]}, {"fused", model_track_frames_[1]},
        {"rest_fit", model_track_frames_[2]},  {"smoothed_in_time", model_track_frames_[3]},
        {"local_fit", model_track_frames_[4]}, {"affine_fit", model_track_frames_[5]}};
    // Of the local-fit track-frames, those whose x and y come from different windows (flow/local_fit.hpp).
    s["local_fit_by_component_track_frames"] = local_fit_by_component_;
    s["fusion_declined_track_frames"] = fusion_declined_;
    // Alive track-frames whose own match has a direction the texture does not determine (docs/flow.md).
    s["unmeasured_direction_track_frames"] = unmeasured_direction_;
    s["smoothing_declined_track_frames"] = smoothing_declined_;
    s["tracks_total"] = tracker_ ? tracker_->tracks().size() : 0;
    double alive_sum = 0.0;
    int alive_last = 0;
    for (const TrackFrame& f : frames_) {
      alive_sum += f.alive;
      if (f.tracker_frame >= 0 && f.tracks > 0) alive_last = f.alive;
    }
    s["tracks_alive_mean"] = tracked_frames_ > 0 ? alive_sum / static_cast<double>(tracked_frames_) : 0.0;
    s["tracks_alive_last"] = alive_last;
    s["track_ms_per_frame"] =
        tracked_frames_ > 0 ? 1e3 * track_s_ / static_cast<double>(tracked_frames_) : 0.0;
    s["smoothed_in_time"] = smoothed_;
    if (smoothed_) {
      s["smoothed_track_frames"] = smoothed_track_frames_;
      s["smoothing_noise_px_median"] = smoothing_noise_px_median_;
    }
    s["plate_measured"] = scene_.reference_pattern_roi.has_value() && plate_warning().empty();
    s["plate_frames_predicted"] = plate_frames_not_matched_[0];
    s["plate_frames_flow_only"] = plate_frames_not_matched_[1];
    if (!frames_.empty() && frames_.back().plate_px)
      s["plate_displacement_last_px"] = {frames_.back().plate_px->x, frames_.back().plate_px->y};
    summary["tracking"] = s;
  }

 private:
  // Result rows of tracker frames (unusable frames in between have rows but are not tracked).
  std::int32_t row_of_tracker_frame(int frame) const {
    if (frame < 0 || static_cast<std::size_t>(frame) >= tracker_rows_.size()) return -1;
    return static_cast<std::int32_t>(tracker_rows_[static_cast<std::size_t>(frame)]);
  }

  void contact_mask(const FrameContext& context, bool has_contact) {
    if (mask_.size() != context.frame->image.size()) mask_.create(context.frame->image.size(), CV_8UC1);
    mask_.setTo(0);
    if (!has_contact) return;
    std::vector<cv::Point> outline;
    outline.reserve(context.contact->outline_px.size());
    for (const auto& p : context.contact->outline_px)
      outline.emplace_back(static_cast<int>(std::lround(p.x)), static_cast<int>(std::lround(p.y)));
    cv::fillPoly(mask_, std::vector<std::vector<cv::Point>>{outline}, cv::Scalar(255));
    // Kept clear of the measured outline (flow/settings.hpp, contact_inset_px).
    const int inset = static_cast<int>(std::lround(settings_.border.contact_inset_px));
    if (inset > 0)
      cv::erode(mask_, mask_,
                cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * inset + 1, 2 * inset + 1)));
  }

  // The reference frame: the tracker sized for this contact, and the normalisation the maps use.
  void start_tracker(const FrameContext& context) {
    Scene sized = scene_;
    // Model only what the scene needs: without a fixed ridge period, size the preset from the period the
    // contact stage measured on this frame.
    if (!scene_.ridge_period_mm && context.contact->ridge_period_px > 0.0)
      sized.ridge_period_mm = context.contact->ridge_period_px / scene_.px_per_mm;
    settings_ = flow::parse_tracking_options(sized);
    tracker_ = std::make_unique<flow::FeatureTracker>(settings_, scene_.reference_pattern_roi);
    tracker_->start(context.frame->image, mask_, context.frame->device_time_s);
    reference_has_ellipse_ = context.contact->ellipse.has_value();
    if (reference_has_ellipse_) {
      // A nearly circular contact has no meaningful major axis: its fitted angle is noise, and maps rotated
      // by it could not be compared or averaged across trials. Below this aspect the maps keep the image
      // axes (translation and scale only). Otherwise the map's +x runs along the major axis towards the
      // image's bottom (angle in [0, pi)): a fingertip's contact is elongated along the finger, which the rig
      // images along y, so the sign of the axis never flips between trials of nearly the same contact (with
      // angles in (-pi/2, pi/2] it would, at exactly that orientation).
      contact::Ellipse e = *context.contact->ellipse;
      if (e.semi_minor_px > kCircularAspect * e.semi_major_px)
        e.angle_rad = 0.0;
      else if (e.angle_rad < 0.0)
        e.angle_rad += std::numbers::pi;
      reference_normalization_ = contact::EllipseNormalization(e);
    } else {
      reference_normalization_ = {};
    }
    reference_row_ = static_cast<std::int64_t>(frames_.size());
    reference_frame_index_ = context.frame->index;
  }

  void track_frame(const FrameContext& context, TrackFrame& record) {
    const flow::FrameStats& stats =
        tracker_->track(context.frame->image, mask_, context.frame->device_time_s);
    rest_frames_averaged_ += stats.rest_frames_averaged;
    rest_frames_on_fit_ += stats.at_rest ? 1 : 0;
    record.rest_tested = stats.rest_tested;
    record.at_rest = stats.at_rest;
    record.rest_chi2_per_dof = stats.rest_chi2_per_dof;
    record.rest_correlation_z = stats.rest_correlation_z;
    affine_fit_frames_ += stats.affine_fit ? 1 : 0;
    record.affine_tested = stats.affine_tested;
    record.affine_fit = stats.affine_fit;
    record.affine_chi2_per_dof = stats.affine_chi2_per_dof;
    record.affine_correlation_z = stats.affine_correlation_z;
    record.affine_hidden_px = stats.affine_hidden_px;
    fusion_declined_ += stats.fusion_declined;
    unmeasured_direction_ += stats.unmeasured_direction;
  }

  // The tracks as they are after this frame: alive ones with position and what it is, retired ones with
  // why; the counts go to the record.
  TrackRow record_tracks(TrackFrame& record) {
    const int frame = tracker_->frame_index();
    const auto& tracks = tracker_->tracks();
    const std::size_t k_count = tracks.size();
    record.tracks = k_count;
    TrackRow row;
    for (std::size_t k = 0; k < k_count; ++k) {
      const flow::Track& t = tracks[k];
      const bool alive = flow::is_alive(t.status);
      if (!alive && t.retired_frame != frame) continue;
      row.column.push_back(k);
      row.status.push_back(static_cast<std::int8_t>(t.status));
      if (alive) {
        row.position_px.insert(row.position_px.end(), {t.position_px.x, t.position_px.y});
        row.model.push_back(static_cast<std::uint8_t>(t.model));
        row.model_mahalanobis2.push_back(static_cast<float>(t.model_mahalanobis2));
        for (std::size_t c = 0; c < 2; ++c)
          row.model_window_px.push_back(static_cast<float>(t.model_window_px[c]));
        row.inside_fraction.push_back(static_cast<float>(t.subset_inside_fraction));
        for (std::size_t c = 0; c < 3; ++c)
          row.covariance_px2.push_back(static_cast<float>(t.covariance_px2[c]));
        ++model_track_frames_[static_cast<std::size_t>(t.model)];
        if (t.model == flow::TrackModel::kLocalFit && t.model_window_px[0] != t.model_window_px[1])
          ++local_fit_by_component_;
        ++record.alive;
        if (t.status == flow::TrackStatus::kBorn && frame > 0) ++record.born;
      } else {
        // Retired in this frame: its status says why, its values are the fill.
        row.position_px.insert(row.position_px.end(), {kNaN, kNaN});
        row.model.push_back(0);
        row.model_mahalanobis2.push_back(kNaNf);
        row.model_window_px.insert(row.model_window_px.end(), {kNaNf, kNaNf});
        row.inside_fraction.push_back(kNaNf);
        row.covariance_px2.insert(row.covariance_px2.end(), {kNaNf, kNaNf, kNaNf});
        ++record.retired;
      }
    }
    return row;
  }

  // This frame's rows of /tracks and /plate (row = its row in /frames).
  void write_row(const TrackRow& row, const TrackFrame& f) const {
    if (!out_) return;
    H5Stream& out = *out_;
    const std::size_t r = frames_.size();
    const std::size_t k = f.tracks;
    const std::span<const std::size_t> columns(row.column);
    out.write_columns("/tracks/position_px", r, columns, std::span<const double>(row.position_px), {k, 2},
                      kNaN);
    out.write_columns("/tracks/status", r, columns, std::span<const std::int8_t>(row.status), {k}, kAbsent);
    out.write_columns("/tracks/model", r, columns, std::span<const std::uint8_t>(row.model), {k},
                      std::uint8_t{0});
    out.write_columns("/tracks/model_mahalanobis2", r, columns,
                      std::span<const float>(row.model_mahalanobis2), {k}, kNaNf);
    out.write_columns("/tracks/model_window_px", r, columns, std::span<const float>(row.model_window_px),
                      {k, 2}, kNaNf);
    out.write_columns("/tracks/covariance_px2", r, columns, std::span<const float>(row.covariance_px2),
                      {k, 3}, kNaNf);
    out.write_columns("/tracks/subset_inside_fraction", r, columns,
                      std::span<const float>(row.inside_fraction), {k}, kNaNf);
    const std::int8_t rest[2] = {static_cast<std::int8_t>(f.rest_tested),
                                 static_cast<std::int8_t>(f.at_rest)};
    out.write_row("/tracks/rest_tested", r, std::span<const std::int8_t>(rest, 1), {}, std::int8_t{0});
    out.write_row("/tracks/at_rest", r, std::span<const std::int8_t>(rest + 1, 1), {}, std::int8_t{0});
    out.write_row("/tracks/rest_chi2_per_dof", r, std::span<const double>(&f.rest_chi2_per_dof, 1), {}, kNaN);
    out.write_row("/tracks/rest_correlation_z", r, std::span<const double>(&f.rest_correlation_z, 1), {},
                  kNaN);
    const std::int8_t affine[2] = {static_cast<std::int8_t>(f.affine_tested),
                                   static_cast<std::int8_t>(f.affine_fit)};
    out.write_row("/tracks/affine_tested", r, std::span<const std::int8_t>(affine, 1), {}, std::int8_t{0});
    out.write_row("/tracks/affine_fit", r, std::span<const std::int8_t>(affine + 1, 1), {}, std::int8_t{0});
    out.write_row("/tracks/affine_chi2_per_dof", r, std::span<const double>(&f.affine_chi2_per_dof, 1), {},
                  kNaN);
    out.write_row("/tracks/affine_correlation_z", r, std::span<const double>(&f.affine_correlation_z, 1), {},
                  kNaN);
    out.write_row("/tracks/affine_hidden_px", r, std::span<const double>(&f.affine_hidden_px, 1), {}, kNaN);
    const double plate[2] = {f.plate_px ? f.plate_px->x : kNaN, f.plate_px ? f.plate_px->y : kNaN};
    out.write_row("/plate/displacement_px", r, std::span<const double>(plate), {2}, kNaN);
    out.write_row("/plate/status", r, std::span<const std::int8_t>(&f.plate_status, 1), {}, kAbsent);
  }

  void write_attributes(H5Stream& out) const {
    out.attribute(
        "/tracks", "model_codes",
        "0 own match; 1 neighbour fusion within the match's noise; 2 affine fit of a frame at rest; "
        "3 smoothed in time within the match's noise; 4 local fit of the neighbours' matches; 5 affine fit "
        "of a moving frame (docs/flow.md, what a position is)");
    out.attribute(
        "/tracks", "subset_inside_fraction",
        "share of each match's subset pixels inside the contact (and the image); the others are not "
        "used: below 1 where a subset crosses the contact's border");
    out.attribute("/tracks", "reference_extrapolated",
                  "1: the track's reference position was not matched in the reference frame but extrapolated "
                  "from its neighbours' map (skin the reference frame did not see); its displacement is "
                  "partly a model");
    out.attribute("/tracks", "preset", settings_.preset);
    out.attribute("/tracks", "reference_frame_row", static_cast<double>(reference_row_));
    out.attribute("/tracks", "status_codes",
                  "-1 absent (not born yet or retired earlier); 0 tracked; 1 born; 2 recovered; 3 unchecked; "
                  "10 left contact; 11 forward-backward; 12 poor match; 13 inconsistent; 14 left image");
    out.attribute("/tracks", "settings", settings_summary().dump());
    out.attribute("/tracks", "smoothed_in_time", smoothed_ ? 1.0 : 0.0);
    out.attribute("/plate", "measured", scene_.reference_pattern_roi ? 1.0 : 0.0);
    out.attribute("/plate", "status_codes",
                  "-1 not measured; 0 matched into the pattern mosaic; 1 predicted from the last motion (the "
                  "subsets disagree or none matched: a motion-blurred band); 2 LK only (the band left the "
                  "mosaic)");
  }

  // The smoothed position stands in for the frame's own where it lies within that match's predicted
  // noise; further away the series has a motion the smoothing would erase (a slip, a jump), and the
  // track keeps what it measured.
  bool adopt_smoothed(TrackColumn& column, std::size_t row, Vec2 smoothed) {
    double* p = &column.position_px[2 * row];
    const double* c = &column.covariance_px2[3 * row];
    Eigen::Matrix2d covariance;
    covariance << c[0], c[1], c[1], c[2];
    const double d2 = covariance.allFinite()
                          ? flow::mahalanobis2({smoothed.x - p[0], smoothed.y - p[1]}, covariance)
                          : std::numeric_limits<double>::infinity();
    if (!(d2 <= flow::kModelShiftChi2)) return false;
    p[0] = smoothed.x;
    p[1] = smoothed.y;
    --model_track_frames_[static_cast<std::size_t>(column.model[row])];
    if (column.model[row] == static_cast<double>(flow::TrackModel::kLocalFit) &&
        column.model_window_px[2 * row] != column.model_window_px[2 * row + 1])
      --local_fit_by_component_;
    ++model_track_frames_[static_cast<std::size_t>(flow::TrackModel::kSmoothedInTime)];
    column.model[row] = static_cast<double>(flow::TrackModel::kSmoothedInTime);
    // Stored as float, as the tracker's own statistic is.
    column.model_mahalanobis2[row] = static_cast<double>(static_cast<float>(d2));
    column.model_window_px[2 * row] = column.model_window_px[2 * row + 1] =
        std::numeric_limits<double>::quiet_NaN();
    return true;
  }

  // One track's rows through the whole trial, read back from result.h5 (chunks hold one track's rows of
  // many frames, so this reads a few chunks, not the file).
  TrackColumn read_column(std::size_t k) const {
    const std::size_t n = frames_.size();
    TrackColumn c;
    c.position_px = out_->read_block("/tracks/position_px", {0, k, 0}, {n, 1, 2});
    c.covariance_px2 = out_->read_block("/tracks/covariance_px2", {0, k, 0}, {n, 1, 3});
    c.model = out_->read_block("/tracks/model", {0, k}, {n, 1});
    c.model_mahalanobis2 = out_->read_block("/tracks/model_mahalanobis2", {0, k}, {n, 1});
    c.model_window_px = out_->read_block("/tracks/model_window_px", {0, k, 0}, {n, 1, 2});
    return c;
  }

  void write_column(std::size_t k, const TrackColumn& c) const {
    const std::size_t n = frames_.size();
    out_->write_block("/tracks/position_px", {0, k, 0}, {n, 1, 2}, c.position_px);
    out_->write_block("/tracks/model", {0, k}, {n, 1}, c.model);
    out_->write_block("/tracks/model_mahalanobis2", {0, k}, {n, 1}, c.model_mahalanobis2);
    out_->write_block("/tracks/model_window_px", {0, k, 0}, {n, 1, 2}, c.model_window_px);
  }

  // Each track's runs of consecutive alive rows, x and y apart, smoothed with their own noise level; the
  // reference frame keeps its exact position (the displacement is zero there by definition). One track is
  // in memory at a time: the window in time is the track's whole life, at 16 bytes per frame.
  void smooth_tracks(const flow::TemporalSmoothing& options) {
    const std::size_t k_total = tracker_->tracks().size();
    std::vector<double> noise;
    std::vector<std::size_t> run;
    std::vector<double> t, x;
    std::array<std::vector<double>, 2> smoothed;
    TrackColumn column;
    bool changed = false;
    const auto smooth_run = [&]() {
      if (static_cast<int>(run.size()) < options.min_samples) return;
      t.clear();
      for (std::size_t row : run) t.push_back(frames_[row].t_s);
      for (std::size_t c = 0; c < 2; ++c) {
        x.clear();
        for (std::size_t row : run) x.push_back(column.position_px[2 * row + c]);
        const double sigma = flow::series_noise(x);
        noise.push_back(sigma);
        smoothed[c] = flow::smooth_in_time(t, x, sigma, options);
      }
      for (std::size_t i = 0; i < run.size(); ++i) {
        if (static_cast<std::int64_t>(run[i]) == reference_row_) continue;
        if (adopt_smoothed(column, run[i], {smoothed[0][i], smoothed[1][i]})) {
          ++smoothed_track_frames_;
          changed = true;
        } else {
          ++smoothing_declined_;
        }
      }
    };
    for (std::size_t k = 0; k < k_total; ++k) {
      column = read_column(k);
      changed = false;
      run.clear();
      for (std::size_t row = 0; row < frames_.size(); ++row) {
        const bool alive = k < frames_[row].tracks && std::isfinite(column.position_px[2 * row]) &&
                           std::isfinite(column.position_px[2 * row + 1]) && std::isfinite(frames_[row].t_s);
        if (alive) {
          run.push_back(row);
        } else {
          smooth_run();
          run.clear();
        }
      }
      smooth_run();
      if (changed) write_column(k, column);
    }
    if (!noise.empty()) {
      smoothing_noise_px_median_ = upper_median_in_place(noise);
    }
  }

  // The settings in effect: the tracker may have adapted them to frame 0's texture.
  nlohmann::json settings_summary() const {
    nlohmann::json j = tracking_settings_json(tracker_ ? tracker_->settings() : settings_);
    if (tracker_ && tracker_->settings().refine) j["texture"] = texture_json(*tracker_);
    return j;
  }

  Scene scene_;
  flow::TrackerOptions settings_;
  std::unique_ptr<flow::FeatureTracker> tracker_;
  cv::Size frame_size_;
  cv::Mat mask_;
  contact::EllipseNormalization reference_normalization_;
  bool reference_has_ellipse_ = false;
  std::int64_t reference_row_ = 0;
  std::int64_t reference_frame_index_ = -1;
  std::vector<TrackFrame> frames_;
  bool keep_history_ = true;
  H5Stream* out_ = nullptr;  // result.h5, where rows go as frames are done (null in the live view)
  std::vector<std::int64_t> tracker_rows_;
  double track_s_ = 0.0;
  std::int64_t tracked_frames_ = 0;
  std::array<std::int64_t, 2> plate_frames_not_matched_{};  // predicted, LK only (/plate/status 1, 2)
  std::int64_t rest_frames_averaged_ = 0;
  std::int64_t rest_frames_on_fit_ = 0;
  std::int64_t affine_fit_frames_ = 0;
  std::array<std::int64_t, 6> model_track_frames_{};
  std::int64_t local_fit_by_component_ = 0;  // local-fit track-frames whose components' windows differ
  std::int64_t fusion_declined_ = 0, smoothing_declined_ = 0;
  std::int64_t unmeasured_direction_ = 0;  // alive track-frames with a direction no match measured
  bool smoothed_ = false;
  std::int64_t smoothed_track_frames_ = 0;
  double smoothing_noise_px_median_ = 0.0;
  std::vector<flow::Track> replay_tracks_;
};

}  // namespace

std::unique_ptr<Stage> make_tracking_stage(const Scene& scene) {
  return std::make_unique<TrackingStage>(scene);
}

}  // namespace tirstrain::pipeline
