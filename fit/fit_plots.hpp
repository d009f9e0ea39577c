#pragma once
// Pictures of a fit for people to look at: residual maps at three moments of the loading and c/a and Q
// against time beside Cattaneo–Mindlin's c/a = (1 − Q/μP)^(1/3).
#include <string>
#include <vector>

#include "fit/cm_fit.hpp"
#include "fit/fit_result.hpp"

namespace tirstrain::fit {

// The frames the residual maps show, chosen from the fit itself: onset (the first loaded frame after a
// rest frame, else the first loaded one), t90 (the first with Q ≥ 0.9 of the largest Q) and full slip (the
// first full_slip frame). −1 where there is none.
struct KeyFrames {
  long onset = -1, t90 = -1, full_slip = -1;
};
KeyFrames key_frames(const std::vector<FrameFit>& fits);

// Writes DIR/residual_onset.png, residual_t90.png, residual_full_slip.png (|measured − model| per 8 px cell
// of the reference, px; grey without tracks) for the key frames that exist, and DIR/c_q_vs_time.png.
void write_fit_plots(const std::string& dir, const ResultForFit& result, const std::vector<FrameFit>& fits);

}  // namespace tirstrain::fit
