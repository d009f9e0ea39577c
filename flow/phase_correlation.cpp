#include "flow/phase_correlation.hpp"

#include "core/archive.hpp"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cfloat>
#include <cmath>

namespace tirstrain::flow {

void PhaseCorrelator::archive(Archive& a) {
  a(size_, window_, reference_spectrum_, last_spectrum_, has_last_);
}
namespace {

// The magnitudes of a packed (CCS) spectrum in the layout OpenCV's phase correlation divides by (with
// cv::divSpectrums): each complex pair's magnitude in its real slot (0 in the imaginary one), in float from a
// double square root; the purely real entries (the first column's and, for an even width, the last
// column's first and, for an even height, last rows) their absolute value. The test checks the whole
// correlation against cv::phaseCorrelate to 1e-9.
void packed_magnitudes(const cv::Mat& p, cv::Mat& m) {
  const int rows = p.rows, cols = p.cols;
  m.create(p.size(), CV_32F);
  m.setTo(0);
  const std::size_t ps = p.step1(), ms = m.step1();
  const float* src = p.ptr<float>();
  float* dst = m.ptr<float>();
  const auto magnitude = [](float re, float im) {
    return static_cast<float>(std::sqrt(static_cast<double>(re) * re + static_cast<double>(im) * im));
  };
  for (int k = 0; k < (cols % 2 ? 1 : 2); ++k) {
    const int col = k == 0 ? 0 : cols - 1;
    const float* a = src + col;
    float* o = dst + col;
    o[0] = std::abs(a[0]);
    if (rows % 2 == 0) o[(rows - 1) * ms] = std::abs(a[(rows - 1) * ps]);
    for (int j = 1; j <= rows - 2; j += 2) o[j * ms] = magnitude(a[j * ps], a[(j + 1) * ps]);
  }
  const int last = cols - (cols % 2 == 0 ? 1 : 0);
  for (int y = 0; y < rows; ++y) {
    const float* a = src + y * ps;
    float* o = dst + y * ms;
    for (int j = 1; j < last; j += 2) o[j] = magnitude(a[j], a[j + 1]);
  }
}

// Moves the zero shift to the centre by swapping quadrants, as OpenCV's phase correlation does; for an odd
// side the first quadrant is the larger one.
void shift_to_centre(cv::Mat& c, cv::Mat& tmp) {
  const int xm = c.cols / 2, ym = c.rows / 2, xo = c.cols % 2, yo = c.rows % 2;
  if (!xo && !yo) {
    const auto swap = [&](cv::Rect a, cv::Rect b) {
      c(a).copyTo(tmp);
      c(b).copyTo(c(a));
      tmp.copyTo(c(b));
    };
    swap(cv::Rect(0, 0, xm, ym), cv::Rect(xm, ym, xm, ym));
    swap(cv::Rect(xm, 0, xm, ym), cv::Rect(0, ym, xm, ym));
    return;
  }
  c.copyTo(tmp);
  tmp(cv::Rect(0, 0, xm + xo, ym + yo)).copyTo(c(cv::Rect(xm, ym, xm + xo, ym + yo)));
  tmp(cv::Rect(xm + xo, ym + yo, xm, ym)).copyTo(c(cv::Rect(0, 0, xm, ym)));
  tmp(cv::Rect(xm + xo, 0, xm, ym + yo)).copyTo(c(cv::Rect(0, ym, xm, ym + yo)));
  tmp(cv::Rect(0, ym + yo, xm + xo, ym)).copyTo(c(cv::Rect(xm, 0, xm + xo, ym)));
}

}  // namespace

void PhaseCorrelator::spectrum_of(const cv::Mat& image, cv::Mat& spectrum) {
  CV_Assert(image.type() == CV_32F && image.size() == size_);
  const int m = cv::getOptimalDFTSize(image.rows), n = cv::getOptimalDFTSize(image.cols);
  if (m != image.rows || n != image.cols)
    // Isolated: for a view into a larger image, copyMakeBorder would pad with the pixels around it.
    cv::copyMakeBorder(image, padded_, 0, m - image.rows, 0, n - image.cols,
                       cv::BORDER_CONSTANT | cv::BORDER_ISOLATED, cv::Scalar(0));
  else
    image.copyTo(padded_);
  if (!window_.empty()) cv::multiply(window_, padded_, padded_);
  cv::dft(padded_, spectrum, cv::DFT_REAL_OUTPUT);
}

void PhaseCorrelator::set_reference(const cv::Mat& reference, const cv::Mat& window) {
  CV_Assert(reference.type() == CV_32F);
  CV_Assert(window.empty() || (window.type() == CV_32F && window.size() == reference.size()));
  size_ = reference.size();
  has_last_ = false;
  // A single row or column is left uncorrelated (has_reference() false): the packed spectrum's layout
  // differs there, and no caller's image is that thin.
  if (reference.rows < 2 || reference.cols < 2) {
    reference_spectrum_.release();
    return;
  }
  const int m = cv::getOptimalDFTSize(reference.rows), n = cv::getOptimalDFTSize(reference.cols);
  if (window.empty())
    window_.release();
  else if (m != window.rows || n != window.cols)
    cv::copyMakeBorder(window, window_, 0, m - window.rows, 0, n - window.cols,
                       cv::BORDER_CONSTANT | cv::BORDER_ISOLATED, cv::Scalar(0));
  else
    window.copyTo(window_);
  spectrum_of(reference, reference_spectrum_);
  has_last_ = false;
}

cv::Point2d PhaseCorrelator::correlate(const cv::Mat& image, double* response) {
  CV_Assert(has_reference());
  spectrum_of(image, last_spectrum_);
  has_last_ = true;
  cv::mulSpectrums(reference_spectrum_, last_spectrum_, product_, 0, true);
  packed_magnitudes(product_, magnitudes_);
  cv::divSpectrums(product_, magnitudes_, normalised_, 0, false);
  cv::idft(normalised_, normalised_);
  shift_to_centre(normalised_, quadrant_scratch_);
  cv::Point peak;
  cv::minMaxLoc(normalised_, nullptr, nullptr, nullptr, &peak);
  // The peak's 5×5 neighbourhood's centroid, its sum the response.
  const int r0 = std::max(0, peak.y - 2), r1 = std::min(normalised_.rows - 1, peak.y + 2);
  const int c0 = std::max(0, peak.x - 2), c1 = std::min(normalised_.cols - 1, peak.x + 2);
  double cx = 0.0, cy = 0.0, sum = 0.0;
  for (int y = r0; y <= r1; ++y) {
    const float* row = normalised_.ptr<float>(y);
    for (int x = c0; x <= c1; ++x) {
      cx += static_cast<double>(x) * row[x];
      cy += static_cast<double>(y) * row[x];
      sum += static_cast<double>(row[x]);
    }
  }
  if (response) *response = sum / (static_cast<double>(normalised_.rows) * normalised_.cols);
  sum += DBL_EPSILON;
  cx /= sum;
  cy /= sum;
  return {normalised_.cols / 2.0 - cx, normalised_.rows / 2.0 - cy};
}

bool PhaseCorrelator::adopt_last_as_reference() {
  if (!has_last_) return false;
  std::swap(reference_spectrum_, last_spectrum_);  // the old reference's buffer takes the next spectrum
  has_last_ = false;
  return true;
}

}  // namespace tirstrain::flow
