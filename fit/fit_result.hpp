#pragma once
// `tirstrain fit`'s library side: read what the fit needs from a `tirstrain process` result, fit every
// frame (fit/cm_fit.hpp), and write fit.csv and fit.h5 into an output folder that appears complete or not at
// all. Layout: docs/formats.md "Model fit".
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "core/tensor2.hpp"
#include "fit/cm_fit.hpp"

namespace tirstrain::fit {

// A result's tracks, contacts, calibration and tissue, and its force channel where one was processed.
struct ResultForFit {
  std::string result_path;                // the result.h5 read
  std::vector<double> t_s;                // [N]
  std::vector<ContactEllipse> ellipse;    // [N]
  std::vector<std::uint8_t> has_contact;  // [N] 1 where the frame has an ellipse
  std::vector<Vec2> reference_px;         // [K]
  std::vector<double> position_px;        // [N, K, 2], NaN where a track is absent
  double px_per_mm = 0.0;
  double young_Pa = 0.0;
  double poisson = 0.0;
  std::vector<double> tangential_channel_N;  // [N] (NaN outside the channel's span); empty: no channel
  std::vector<double> normal_channel_N;      // [N] likewise: the normal load P, whence μ = fitted μP / P

  std::size_t frames() const { return t_s.size(); }
  std::size_t tracks() const { return reference_px.size(); }
  FrameObservations frame(std::size_t i) const;
};

// Reads RESULT_DIR/result.h5 (or a result.h5 path). Throws Error naming the file and dataset when the result
// lacks what the fit needs (the tracking stage's /tracks).
ResultForFit read_result_for_fit(const std::string& result);

struct RunOptions {
  FitOptions fit;         // per-frame fit settings
  int frame_threads = 2;  // frames fitted in parallel (default 2)
  bool trial_limit =
      true;  // μP measured on the trial and held in its stick and partial-slip frames (default on)
};

// A trial's fits: one per frame, and the trial's μP when it was measured and used.
struct FitRun {
  std::vector<FrameFit> frames;
  std::optional<TrialLimit> trial_limit;
};

// Fits every frame in two passes: each frame on its own (fit_each_frame), then, when the trial's μP can be
// measured (trial_limit) and options.trial_limit is on, the frames in stick or partial slip again with it
// (refit_at_trial_limit).
FitRun fit_result(const ResultForFit& result, const RunOptions& options);

// Each frame on its own; frames are independent and fitted in parallel.
std::vector<FrameFit> fit_each_frame(const ResultForFit& result, const RunOptions& options);

// The trial's friction limit μP from the frames fitted on their own in partial slip whose annulus and stick
// zone the tracks both resolve: kResolvedStick ≤ c/a ≤ tracked_radius − kResolvedAnnulus. A frame nearer
// gross slip (a stick zone too small to hold tracks) measures the sliding friction rather than the static
// limit that sets the annulus. The median of their μP; its SD the larger of the frames' median SD and their
// scatter (1.4826 MAD), over √frames. None without such a frame.
std::optional<TrialLimit> trial_limit(const std::vector<FrameFit>& fits);
inline constexpr double kResolvedAnnulus = 0.25;
inline constexpr double kResolvedStick = 0.2;

// Whether a frame fitted on its own is fitted again at the trial's limit: stick or partial slip (below the
// limit; frames in full slip are at it).
bool refits_at_trial_limit(const FrameFit& fit);

// The frames of `fits` (one per frame of `result`) that refits_at_trial_limit takes, fitted again with
// `limit`, in parallel, in place. Returns their indices.
std::vector<std::size_t> refit_at_trial_limit(const ResultForFit& result, const RunOptions& options,
                                              const TrialLimit& limit, std::vector<FrameFit>& fits);

// Writes OUT/fit.csv and OUT/fit.h5, staged in OUT.partial and swapped in. Refuses an OUT that holds the
// result (the input is never touched).
void write_fit_outputs(const std::string& out_dir, const ResultForFit& result, const FitRun& fits,
                       const FitOptions& options);

}  // namespace tirstrain::fit
