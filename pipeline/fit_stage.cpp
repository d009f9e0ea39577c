#include "pipeline/fit_stage.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <limits>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "core/csv.hpp"
#include "core/error.hpp"
#include "fit/fit_result.hpp"

namespace tirstrain::pipeline {
namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr float kNaNf = std::numeric_limits<float>::quiet_NaN();
// Frames read back and fitted together: bounds the memory (frames × tracks × 2 doubles) and gives the
// worker threads enough frames to share.
constexpr std::size_t kBlockFrames = 32;
constexpr int kNotFitted = -1;

bool fitted(const fit::FrameFit& f) {
  return f.status == fit::FitStatus::ok || f.status == fit::FitStatus::no_covariance;
}

// What frames.csv and summary.json keep of each frame's fit.
struct FitRow {
  std::int32_t status = static_cast<std::int32_t>(fit::FitStatus::no_contact);
  std::int32_t model = kNotFitted;
  double c_mm = kNaN;
  double tangential_N = kNaN;
  bool limit_from_trial = false;
};

class FitStage final : public Stage {
 public:
  explicit FitStage(const Scene& scene)
      : px_per_mm_(scene.px_per_mm), young_Pa_(scene.tissue.young_Pa), poisson_(scene.tissue.poisson) {}

  std::string name() const override { return "fit"; }

  // The tracks themselves are the tracking stage's (the next frame points at them again).
  void archive(Archive& a) override {
    a.layout(sizeof(fit::ContactEllipse), "contact ellipse");
    a(ellipses_, has_contact_, t_s_);
  }

  void start(const TrialInfo& info) override { out_ = info.keep_history ? info.out : nullptr; }

  void process(FrameContext& context) override {
    fit::ContactEllipse e;
    bool has = false;
    if (context.usable && context.contact && context.contact->ellipse) {
      const contact::Ellipse& c = *context.contact->ellipse;
      e = {c.cx_px, c.cy_px, c.semi_major_px, c.semi_minor_px, c.angle_rad};
      has = c.semi_major_px > 0.0 && c.semi_minor_px > 0.0;
    }
    ellipses_.push_back(e);
    has_contact_.push_back(has ? 1 : 0);
    t_s_.push_back(context.frame ? context.frame->device_time_s : kNaN);
    if (context.tracking) tracks_ = context.tracking->tracks;
  }

  // The tracks are final once the tracking stage has finished: every frame is fitted now, in the two passes
  // of fit::fit_result (each frame on its own; then, with the trial's μP, its stick and partial-slip frames).
  bool finish() override {
    rows_.assign(ellipses_.size(), FitRow{});
    if (!out_) return false;
    const auto start = std::chrono::steady_clock::now();
    const fit::ResultForFit whole = trial_without_positions();
    std::vector<fit::FrameFit> first_pass(rows_.size());
    for (std::size_t first = 0; first < rows_.size(); first += kBlockFrames)
      fit_block(whole, first, std::min(rows_.size(), first + kBlockFrames), first_pass);
    if (options_.trial_limit) trial_limit_ = fit::trial_limit(first_pass);
    if (trial_limit_)
      for (std::size_t first = 0; first < rows_.size(); first += kBlockFrames)
        refit_block(whole, first, std::min(rows_.size(), first + kBlockFrames), first_pass);
    fit_s_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return false;
  }

  std::vector<std::string> csv_header() const override {
    return {"fit_model", "fit_c_mm", "fit_tangential_N"};
  }

  void csv_row(std::size_t row, std::vector<std::string>& cells) const override {
    const FitRow& r = rows_.at(row);
    cells.push_back(r.model == kNotFitted ? std::string()
                                          : fit::field_model_name(static_cast<fit::FieldModel>(r.model)));
    cells.push_back(std::isfinite(r.c_mm) ? format_double(r.c_mm) : std::string());
    cells.push_back(std::isfinite(r.tangential_N) ? format_double(r.tangential_N) : std::string());
  }

  void write(H5Stream& out) const override {
    out.attribute("/fit", "model_codes", "-1 not fitted, 0 rest, 1 full_stick, 2 partial_slip, 3 full_slip");
    out.attribute("/fit", "status_codes", "0 ok, 1 no_contact, 2 too_few_tracks, 3 no_covariance");
    out.attribute("/fit", "criteria_columns", "rest, full_stick, partial_slip, full_slip");
    out.attribute("/fit", "px_per_mm", px_per_mm_);
    out.attribute("/fit", "young_Pa", young_Pa_);
    out.attribute("/fit", "poisson", poisson_);
    out.attribute("/fit", "loss_scale_px", options_.fit.loss_scale_px);
    out.attribute("/fit", "rest_tolerance_px", options_.fit.rest_tolerance_px);
    out.attribute("/fit", "min_tracks", static_cast<double>(options_.fit.min_tracks));
    out.attribute("/fit", "contact_margin", options_.fit.contact_margin);
    out.attribute("/fit", "trial_limit_N", trial_limit_ ? trial_limit_->limit_N : kNaN);
    out.attribute("/fit", "trial_limit_sd_N", trial_limit_ ? trial_limit_->sd_N : kNaN);
    out.attribute("/fit", "trial_limit_frames",
                  trial_limit_ ? static_cast<double>(trial_limit_->frames) : 0.0);
  }

  void summarize(nlohmann::json& summary) const override {
    std::array<int, fit::kFieldModels> by_model{};
    int not_fitted = 0, from_trial = 0;
    for (const FitRow& r : rows_) {
      from_trial += r.limit_from_trial ? 1 : 0;
      if (r.model == kNotFitted)
        ++not_fitted;
      else
        ++by_model[static_cast<std::size_t>(r.model)];
    }
    nlohmann::json by_name;
    for (int m = 0; m < fit::kFieldModels; ++m)
      by_name[fit::field_model_name(static_cast<fit::FieldModel>(m))] = by_model[static_cast<std::size_t>(m)];
    summary["fit"] = {
        {"frames_by_model", by_name},
        {"frames_not_fitted", not_fitted},
        {"trial_limit_N", trial_limit_ ? nlohmann::json(trial_limit_->limit_N) : nlohmann::json()},
        {"trial_limit_sd_N", trial_limit_ ? nlohmann::json(trial_limit_->sd_N) : nlohmann::json()},
        {"trial_limit_frames", trial_limit_ ? trial_limit_->frames : 0},
        {"frames_limit_from_trial", from_trial},
        {"fit_ms_per_frame", rows_.empty() ? 0.0 : 1e3 * fit_s_ / static_cast<double>(rows_.size())}};
  }

 private:
  // Calibration, tissue, contacts and reference positions; the positions are read a block at a time.
  fit::ResultForFit trial_without_positions() const {
    fit::ResultForFit r;
    r.result_path = out_->path();
    r.px_per_mm = px_per_mm_;
    r.young_Pa = young_Pa_;
    r.poisson = poisson_;
    // No tracking output (nothing was ever tracked: a recording with no contact): nothing to fit.
    if (!tracks_ || !out_->has("/tracks/position_px")) return r;
    const std::size_t k =
        std::min(tracks_->size(), static_cast<std::size_t>(out_->shape("/tracks/position_px")[1]));
    for (std::size_t j = 0; j < k; ++j) r.reference_px.push_back((*tracks_)[j].reference_px);
    return r;
  }

  // Frames [first, last) of the trial with their tracks read back from result.h5.
  fit::ResultForFit read_block(const fit::ResultForFit& whole, std::size_t first, std::size_t last) const {
    fit::ResultForFit block = whole;
    const std::size_t n = last - first, k = whole.tracks();
    block.t_s.assign(t_s_.begin() + static_cast<std::ptrdiff_t>(first),
                     t_s_.begin() + static_cast<std::ptrdiff_t>(last));
    block.ellipse.assign(ellipses_.begin() + static_cast<std::ptrdiff_t>(first),
                         ellipses_.begin() + static_cast<std::ptrdiff_t>(last));
    block.has_contact.assign(has_contact_.begin() + static_cast<std::ptrdiff_t>(first),
                             has_contact_.begin() + static_cast<std::ptrdiff_t>(last));
    block.position_px =
        k == 0 ? std::vector<double>() : out_->read_block("/tracks/position_px", {first, 0, 0}, {n, k, 2});
    return block;
  }

  // Frames [first, last) fitted each on its own, in parallel, written as rows and kept (without their
  // residuals) in `first_pass`.
  void fit_block(const fit::ResultForFit& whole, std::size_t first, std::size_t last,
                 std::vector<fit::FrameFit>& first_pass) {
    const fit::ResultForFit block = read_block(whole, first, last);
    const std::size_t n = last - first, k = whole.tracks();
    std::vector<fit::FrameFit> fits;
    if (k > 0) {
      fits = fit::fit_each_frame(block, options_);
    } else {  // no track to fit (the tracker never started)
      fits.resize(n);
      for (std::size_t i = 0; i < n; ++i)
        fits[i].status = block.has_contact[i] ? fit::FitStatus::too_few_tracks : fit::FitStatus::no_contact;
    }
    for (std::size_t i = 0; i < n; ++i) {
      write_frame(first + i, fits[i], k);
      first_pass[first + i] = std::move(fits[i]);
      first_pass[first + i].residual_px = {};
    }
  }

  // The frames of [first, last) in stick or partial slip fitted again at the trial's μP; their rows
  // rewritten.
  void refit_block(const fit::ResultForFit& whole, std::size_t first, std::size_t last,
                   const std::vector<fit::FrameFit>& first_pass) {
    if (std::none_of(first_pass.begin() + static_cast<std::ptrdiff_t>(first),
                     first_pass.begin() + static_cast<std::ptrdiff_t>(last), fit::refits_at_trial_limit))
      return;
    const fit::ResultForFit block = read_block(whole, first, last);
    std::vector<fit::FrameFit> fits(first_pass.begin() + static_cast<std::ptrdiff_t>(first),
                                    first_pass.begin() + static_cast<std::ptrdiff_t>(last));
    for (const std::size_t i : fit::refit_at_trial_limit(block, options_, *trial_limit_, fits))
      write_frame(first + i, fits[i], whole.tracks());
  }

  void write_frame(std::size_t r, const fit::FrameFit& f, std::size_t k) {
    write_row(r, f, k);
    rows_[r] = {static_cast<std::int32_t>(f.status),
                fitted(f) ? static_cast<std::int32_t>(f.model) : kNotFitted, fitted(f) ? f.c_mm.value : kNaN,
                fitted(f) ? f.tangential_N.value : kNaN, fitted(f) && f.limit_from_trial};
  }

  void write_row(std::size_t r, const fit::FrameFit& f, std::size_t k) const {
    H5Stream& out = *out_;
    const bool ok = fitted(f);
    const int m = static_cast<int>(f.model);
    const std::int32_t ints[3] = {static_cast<std::int32_t>(f.status), ok ? m : kNotFitted, f.tracks_used};
    out.write_row("/fit/status", r, std::span<const std::int32_t>(ints, 1), {}, std::int32_t{0});
    out.write_row("/fit/model", r, std::span<const std::int32_t>(ints + 1, 1), {}, std::int32_t{kNotFitted});
    out.write_row("/fit/tracks", r, std::span<const std::int32_t>(ints + 2, 1), {}, std::int32_t{0});
    const double scalars[3] = {ok ? f.residual_rms_px : kNaN, ok ? f.aic[static_cast<std::size_t>(m)] : kNaN,
                               ok ? f.bic[static_cast<std::size_t>(m)] : kNaN};
    out.write_row("/fit/residual_rms_px", r, std::span<const double>(scalars, 1), {}, kNaN);
    const double shared = ok ? f.shared_residuals : kNaN;
    out.write_row("/fit/shared_residuals", r, std::span<const double>(&shared, 1), {}, kNaN);
    out.write_row("/fit/aic", r, std::span<const double>(scalars + 1, 1), {}, kNaN);
    out.write_row("/fit/bic", r, std::span<const double>(scalars + 2, 1), {}, kNaN);
    std::array<double, fit::kFieldModels> aic{}, bic{};
    for (std::size_t j = 0; j < aic.size(); ++j) {
      aic[j] = ok ? f.aic[j] : kNaN;
      bic[j] = ok ? f.bic[j] : kNaN;
    }
    out.write_row("/fit/aic_by_model", r, std::span<const double>(aic), {fit::kFieldModels}, kNaN);
    out.write_row("/fit/bic_by_model", r, std::span<const double>(bic), {fit::kFieldModels}, kNaN);
    const double reach = ok ? f.tracked_radius : kNaN;
    out.write_row("/fit/tracked_radius", r, std::span<const double>(&reach, 1), {}, kNaN);
    const std::int32_t from_trial = ok && f.limit_from_trial ? 1 : 0;
    out.write_row("/fit/limit_from_trial", r, std::span<const std::int32_t>(&from_trial, 1), {},
                  std::int32_t{0});
    write_estimates(r, f, ok);
    std::vector<float> residual(2 * k, kNaNf);
    for (std::size_t j = 0; j < k && j < f.residual_px.size(); ++j) {
      residual[2 * j] = static_cast<float>(f.residual_px[j].x);
      residual[2 * j + 1] = static_cast<float>(f.residual_px[j].y);
    }
    out.write_row("/fit/residual_px", r, std::span<const float>(residual), {k, 2}, kNaNf);
  }

  void write_estimates(std::size_t r, const fit::FrameFit& f, bool ok) const {
    const std::pair<const char*, const fit::Estimate*> estimates[] = {{"centre_x_px", &f.centre_x_px},
                                                                      {"centre_y_px", &f.centre_y_px},
                                                                      {"direction_deg", &f.direction_deg},
                                                                      {"a_mm", &f.a_mm},
                                                                      {"c_mm", &f.c_mm},
                                                                      {"tangential_N", &f.tangential_N},
                                                                      {"limit_N", &f.limit_N}};
    for (const auto& [name, e] : estimates) {
      const double v[2] = {ok ? e->value : kNaN, ok ? e->sd : kNaN};
      out_->write_row(std::string("/fit/") + name, r, std::span<const double>(v, 1), {}, kNaN);
      out_->write_row(std::string("/fit/") + name + "_sd", r, std::span<const double>(v + 1, 1), {}, kNaN);
    }
  }

  double px_per_mm_, young_Pa_, poisson_;
  fit::RunOptions options_;
  H5Stream* out_ = nullptr;
  const std::vector<flow::Track>* tracks_ = nullptr;
  std::vector<fit::ContactEllipse> ellipses_;
  std::vector<std::uint8_t> has_contact_;
  std::vector<double> t_s_;
  std::vector<FitRow> rows_;
  std::optional<fit::TrialLimit> trial_limit_;
  double fit_s_ = 0.0;
};

}  // namespace

std::unique_ptr<Stage> make_fit_stage(const Scene& scene) {
  return std::make_unique<FitStage>(scene);
}

}  // namespace tirstrain::pipeline
