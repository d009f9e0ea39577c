#pragma once
// `tirstrain fit`'s library side: read what the fit needs from a `tirstrain process` result, fit every
// frame (fit/cm_fit.hpp), and write fit.csv and fit.h5 into an output folder that appears complete or not at
// all. Layout: docs/formats.md "Model fit".
#include <cstdint>
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
};

// Fits every frame; frames are independent and fitted in parallel.
std::vector<FrameFit> fit_result(const ResultForFit& result, const RunOptions& options);

// Writes OUT/fit.csv and OUT/fit.h5, staged in OUT.partial and swapped in. Refuses an OUT that holds the
// result (the input is never touched).
void write_fit_outputs(const std::string& out_dir, const ResultForFit& result,
                       const std::vector<FrameFit>& fits, const FitOptions& options);

}  // namespace tirstrain::fit
