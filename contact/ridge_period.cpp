#include "contact/ridge_period.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/median.hpp"

namespace tirstrain::contact {

std::optional<PeriodEstimate> estimate_ridge_period(const cv::Mat& image, double min_period_px,
                                                    double max_period_px) {
  CV_Assert(image.type() == CV_32FC1);
  if (image.rows < 16 || image.cols < 16 || !(min_period_px >= 2.0) || !(max_period_px > min_period_px))
    return std::nullopt;
  // A Hann window stops the frame border from painting a cross of leakage through the spectrum.
  cv::Mat window;
  cv::createHanningWindow(window, image.size(), CV_32F);
  cv::Mat centred = image - cv::mean(image)[0];
  cv::Mat windowed = centred.mul(window);
  const int rows = cv::getOptimalDFTSize(image.rows), cols = cv::getOptimalDFTSize(image.cols);
  cv::Mat padded;
  cv::copyMakeBorder(windowed, padded, 0, rows - image.rows, 0, cols - image.cols, cv::BORDER_CONSTANT, 0.0);
  cv::Mat spectrum;
  cv::dft(padded, spectrum, cv::DFT_COMPLEX_OUTPUT);

  const double bin_width = 1.0 / std::max(rows, cols);  // cycles per pixel
  const double f_lo = 1.0 / max_period_px, f_hi = std::min(0.5, 1.0 / min_period_px);
  const int bins = static_cast<int>(std::ceil(f_hi / bin_width)) + 2;
  std::vector<double> power(static_cast<std::size_t>(bins), 0.0);
  std::vector<double> count(static_cast<std::size_t>(bins), 0.0);
  // Only half the plane is needed (the spectrum of a real image is symmetric).
  for (int v = 0; v < rows; ++v) {
    const double fy = (v <= rows / 2 ? v : v - rows) / static_cast<double>(rows);
    const auto* row = spectrum.ptr<cv::Vec2f>(v);
    for (int u = 0; u <= cols / 2; ++u) {
      const double fx = u / static_cast<double>(cols);
      const double f = std::hypot(fx, fy);
      const int bin = static_cast<int>(std::lround(f / bin_width));
      if (bin >= bins) continue;
      // Whitening by f^2 flattens the 1/f^2 spectrum of the contact's outline and of illumination, which
      // would otherwise out-shout the ridge ring at long periods.
      const double p =
          (static_cast<double>(row[u][0]) * row[u][0] + static_cast<double>(row[u][1]) * row[u][1]) * f * f;
      power[static_cast<std::size_t>(bin)] += p;
      count[static_cast<std::size_t>(bin)] += 1.0;
    }
  }
  const int lo = std::max(1, static_cast<int>(std::ceil(f_lo / bin_width)));
  const int hi = std::min(bins - 2, static_cast<int>(std::floor(f_hi / bin_width)));
  if (hi - lo < 3) return std::nullopt;
  std::vector<double> band;
  int best = lo;
  for (int b = lo; b <= hi; ++b) {
    const auto i = static_cast<std::size_t>(b);
    power[i] = count[i] > 0.0 ? power[i] / count[i] : 0.0;
  }
  for (int b = lo; b <= hi; ++b) {
    band.push_back(power[static_cast<std::size_t>(b)]);
    if (power[static_cast<std::size_t>(b)] > power[static_cast<std::size_t>(best)]) best = b;
  }
  const double median = upper_median_in_place(band);
  // Power-weighted centre of the peak and its neighbours gives a sub-bin frequency.
  double sum_w = 0.0, sum_wf = 0.0;
  for (int b = std::max(1, best - 1); b <= best + 1; ++b) {
    const double w = b == best - 1 || b == best + 1 ? 0.5 * power[static_cast<std::size_t>(b)]
                                                    : power[static_cast<std::size_t>(b)];
    if (b < lo - 1 || b > hi + 1) continue;
    sum_w += w;
    sum_wf += w * b * bin_width;
  }
  const double f_peak = sum_w > 0.0 ? sum_wf / sum_w : best * bin_width;
  if (!(f_peak > 0.0)) return std::nullopt;
  PeriodEstimate estimate;
  estimate.period_px = std::clamp(1.0 / f_peak, min_period_px, max_period_px);
  estimate.confidence = median > 0.0 ? power[static_cast<std::size_t>(best)] / median : 0.0;
  return estimate;
}

}  // namespace tirstrain::contact
