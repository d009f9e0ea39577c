#include "contact/ridge_period.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "core/median.hpp"

namespace tirstrain::contact {
namespace {

// The ring's radial centre: the centroid of the power summed per ring over ±25 % of the peak's frequency (at
// least 10 bins), less the straight baseline between the window's ends. A ring's sum is what its ridges
// carry whatever its radius (the mean per sample falls as 1/f across a ring). The centroid, not the
// strongest bin: a whorl's ring is asymmetric, its strongest bin a few per cent above its period (the Hankel
// transform's phase), and split into lobes, while its centroid sits on the period.
double ring_centre(const std::vector<double>& total, int best, int lo, int hi, double bin_width) {
  const auto at = [&](int b) { return total[static_cast<std::size_t>(b)]; };
  const int reach = std::max(10, static_cast<int>(std::lround(0.25 * best)));
  const int left = std::max(lo, best - reach), right = std::min(hi, best + reach);
  const double base_left = at(left), base_right = at(right);
  double sum_w = 0.0, sum_wb = 0.0;
  for (int b = left; b <= right; ++b) {
    const double baseline =
        right > left ? base_left + (base_right - base_left) * (b - left) / (right - left) : 0.0;
    const double w = std::max(0.0, at(b) - baseline);
    sum_w += w;
    sum_wb += w * b;
  }
  return (sum_w > 0.0 ? sum_wb / sum_w : best) * bin_width;
}

}  // namespace

std::optional<PeriodEstimate> estimate_ridge_period(const cv::Mat& image, double min_period_px,
                                                    double max_period_px) {
  CV_Assert(image.type() == CV_32FC1);
  if (image.rows < 16 || image.cols < 16 || !(min_period_px >= 2.0) || !(max_period_px > min_period_px))
    return std::nullopt;
  // A Hann window stops the frame border from painting a cross of leakage through the spectrum. Padded to
  // twice the size, the spectrum samples the ridge ring's radial profile finely enough to locate its centre
  // between bins.
  cv::Mat window;
  cv::createHanningWindow(window, image.size(), CV_32F);
  cv::Mat centred = image - cv::mean(image)[0];
  cv::Mat windowed = centred.mul(window);
  const int rows = cv::getOptimalDFTSize(2 * image.rows), cols = cv::getOptimalDFTSize(2 * image.cols);
  cv::Mat padded;
  cv::copyMakeBorder(windowed, padded, 0, rows - image.rows, 0, cols - image.cols, cv::BORDER_CONSTANT, 0.0);
  cv::Mat spectrum;
  cv::dft(padded, spectrum, cv::DFT_COMPLEX_OUTPUT);

  const double bin_width = 1.0 / std::max(rows, cols);  // cycles per pixel
  const double f_lo = 1.0 / max_period_px, f_hi = std::min(0.5, 1.0 / min_period_px);
  const int bins = static_cast<int>(std::ceil(f_hi / bin_width)) + 2;
  // Per radial bin: the power summed over the bin's ring, and how many samples it holds.
  std::vector<double> total(static_cast<std::size_t>(bins), 0.0);
  std::vector<double> count(static_cast<std::size_t>(bins), 0.0);
  // Only half the plane is needed (the spectrum of a real image is symmetric).
  for (int v = 0; v < rows; ++v) {
    const double fy = (v <= rows / 2 ? v : v - rows) / static_cast<double>(rows);
    const auto* row = spectrum.ptr<cv::Vec2f>(v);
    for (int u = 0; u <= cols / 2; ++u) {
      const double fx = u / static_cast<double>(cols);
      const int bin = static_cast<int>(std::lround(std::hypot(fx, fy) / bin_width));
      if (bin >= bins) continue;
      total[static_cast<std::size_t>(bin)] +=
          static_cast<double>(row[u][0]) * row[u][0] + static_cast<double>(row[u][1]) * row[u][1];
      count[static_cast<std::size_t>(bin)] += 1.0;
    }
  }
  const int lo = std::max(1, static_cast<int>(std::ceil(f_lo / bin_width)));
  const int hi = std::min(bins - 2, static_cast<int>(std::floor(f_hi / bin_width)));
  if (hi - lo < 3) return std::nullopt;
  // Detection: the mean power per sample whitened by f², which flattens the 1/f² spectrum of the contact's
  // outline and of the illumination that would otherwise out-shout the ridge ring at long periods.
  std::vector<double> whitened(static_cast<std::size_t>(bins), 0.0);
  std::vector<double> band;
  int best = lo;
  for (int b = lo; b <= hi; ++b) {
    const auto i = static_cast<std::size_t>(b);
    const double f = b * bin_width;
    whitened[i] = count[i] > 0.0 ? total[i] / count[i] * f * f : 0.0;
    band.push_back(whitened[i]);
    if (whitened[i] > whitened[static_cast<std::size_t>(best)]) best = b;
  }
  const double median = upper_median_in_place(band);
  const double f_peak = ring_centre(total, best, lo, hi, bin_width);
  if (!(f_peak > 0.0)) return std::nullopt;
  PeriodEstimate estimate;
  estimate.period_px = std::clamp(1.0 / f_peak, min_period_px, max_period_px);
  estimate.confidence = median > 0.0 ? whitened[static_cast<std::size_t>(best)] / median : 0.0;
  return estimate;
}

}  // namespace tirstrain::contact
