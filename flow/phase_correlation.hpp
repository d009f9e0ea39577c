#pragma once
// Phase correlation of a sequence of images against the previous one, each spectrum computed once.
// cv::phaseCorrelate transforms both of its images at every call; correlating frame t with frame t − 1 and
// then t + 1 with t transformed every frame twice. The plate's band and the tracker's high-passed contact
// are correlated this way every frame (each forward transform about a third of a correlation, which were
// 9 % of the tracker's instructions on the 640×512 goal trial).
#include <opencv2/core.hpp>

namespace tirstrain {
class Archive;
}

namespace tirstrain::flow {

class PhaseCorrelator {
 public:
  // The reference image (CV_32F, at least 2×2; a thinner one leaves no reference) and the window both
  // images are multiplied by (CV_32F, the same size; empty: none). Its spectrum is computed here.
  void set_reference(const cv::Mat& reference, const cv::Mat& window = cv::Mat());
  bool has_reference() const { return !reference_spectrum_.empty(); }
  cv::Size reference_size() const { return size_; }
  // cv::phaseCorrelate(reference, image, window, response), with the same arithmetic step for step (the same
  // shift and response): the shift of `image` relative to the reference, response the peak's strength.
  // `image` must have the reference's size and type.
  cv::Point2d correlate(const cv::Mat& image, double* response);
  // The image last passed to correlate() becomes the reference, its spectrum reused. False (and nothing
  // changes) when nothing was correlated since the reference was set.
  bool adopt_last_as_reference();
  // Its state in a checkpoint (core/archive.hpp).
  void archive(Archive& a);

 private:
  // The windowed image zero-padded to the transform's size, and its spectrum (packed CCS, real output).
  void spectrum_of(const cv::Mat& image, cv::Mat& spectrum);

  cv::Size size_;
  cv::Mat window_, padded_, reference_spectrum_, last_spectrum_, product_, magnitudes_, normalised_;
  cv::Mat quadrant_scratch_;
  bool has_last_ = false;
};

}  // namespace tirstrain::flow
