#include "flow/mask_erosion.hpp"

#include <gtest/gtest.h>
#include <opencv2/imgproc.hpp>

#include <random>

#include "flow/subset.hpp"

namespace tirstrain::flow {
namespace {

cv::Mat reference_erosion(const cv::Mat& mask, int r) {
  cv::Mat out;
  cv::erode(mask, out, cv::getStructuringElement(cv::MORPH_ELLIPSE, cv::Size(2 * r + 1, 2 * r + 1)),
            cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::Scalar(0));
  return out;
}

// Blobs of every shape, some cut by the frame's edge, with holes and thin necks.
cv::Mat random_mask(std::mt19937& rng, cv::Size size, std::uint8_t value) {
  cv::Mat mask = cv::Mat::zeros(size, CV_8U);
  std::uniform_int_distribution<int> x(-20, size.width + 20), y(-20, size.height + 20), radius(2, 60);
  for (int k = 0; k < 6; ++k)
    cv::ellipse(mask, cv::Point(x(rng), y(rng)), cv::Size(radius(rng), radius(rng)), 30.0 * k, 0, 360,
                cv::Scalar(value), cv::FILLED);
  for (int k = 0; k < 4; ++k)
    cv::circle(mask, cv::Point(x(rng), y(rng)), radius(rng) / 4, cv::Scalar(0), cv::FILLED);
  for (int k = 0; k < 3; ++k)
    cv::line(mask, cv::Point(x(rng), y(rng)), cv::Point(x(rng), y(rng)), cv::Scalar(value), 1 + k);
  return mask;
}

TEST(MaskErosion, EqualsOpenCVsEllipticErosionPixelForPixel) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 12; ++trial) {
    const cv::Size size(97 + 31 * trial, 80 + 17 * trial);
    const cv::Mat mask = random_mask(rng, size, trial % 2 ? 255 : 1);
    for (int r : {0, 1, 2, 3, 5, 8, 13, 14, 21, 40}) {
      cv::Mat fast;
      erode_ellipse(mask, r, fast);
      const cv::Mat expected = reference_erosion(mask, r);
      EXPECT_EQ(cv::countNonZero(fast != expected), 0) << "trial " << trial << ", radius " << r;
    }
  }
}

TEST(MaskErosion, FullAndEmptyMasksAndAView) {
  const cv::Mat full(60, 50, CV_8U, cv::Scalar(255));
  cv::Mat out;
  erode_ellipse(full, 6, out);
  // The frame's edge is background: only pixels at least 7 px inside survive.
  EXPECT_EQ(cv::countNonZero(out), (60 - 12) * (50 - 12));
  EXPECT_EQ(cv::countNonZero(out != reference_erosion(full, 6)), 0);
  erode_ellipse(cv::Mat::zeros(30, 30, CV_8U), 4, out);
  EXPECT_EQ(cv::countNonZero(out), 0);
  // Into a view of a larger mask, leaving the rest of it alone.
  cv::Mat big(100, 100, CV_8U, cv::Scalar(9));
  cv::Mat view = big(cv::Rect(20, 30, 50, 60));
  erode_ellipse(full, 6, view);
  EXPECT_EQ(big.at<std::uint8_t>(0, 0), 9);
  EXPECT_EQ(cv::countNonZero(view != reference_erosion(full, 6)), 0);
  EXPECT_EQ(view.data, big.ptr<std::uint8_t>(30) + 20);
}

// The composition the match mask is built from, with the image's edge counted as a border.
cv::Mat eroded_with_the_edge_as_border(const cv::Mat& mask, int r) {
  cv::Mat rect;
  erode_for_matching(mask, rect);
  return reference_erosion(rect, r);
}

cv::Mat match_mask_of(const cv::Mat& mask, cv::Rect box, int r) {
  cv::Mat out(mask.size(), CV_8U, cv::Scalar(0));
  cv::Mat view = out(box);
  MatchMaskScratch scratch;
  erode_contact_for_matching(mask, box, r, scratch, view);
  return out;
}

TEST(MatchMask, AContactInsideTheFrameIsErodedByTheExclusionAndTheKernel) {
  cv::Mat mask = cv::Mat::zeros(120, 160, CV_8U);
  cv::ellipse(mask, cv::Point(80, 60), cv::Size(45, 35), 20.0, 0, 360, cv::Scalar(1), cv::FILLED);
  const cv::Rect box = cv::Rect(20, 10, 120, 100);  // past the contact by more than 14 + 3 px
  const cv::Mat out = match_mask_of(mask, box, 14);
  EXPECT_EQ(cv::countNonZero(out != eroded_with_the_edge_as_border(mask, 14)), 0);
  EXPECT_GT(cv::countNonZero(out), 0);
}

TEST(MatchMask, TheImagesEdgeKeepsOnlyTheKernelsReach) {
  // The whole frame in contact: everything but the 2 px the interpolation kernel needs inside the edge.
  const cv::Mat full(90, 130, CV_8U, cv::Scalar(1));
  const cv::Mat out = match_mask_of(full, cv::Rect(0, 0, 130, 90), 14);
  EXPECT_EQ(cv::countNonZero(out), (90 - 4) * (130 - 4));
  EXPECT_EQ(out.at<std::uint8_t>(2, 2), 1);
  EXPECT_EQ(out.at<std::uint8_t>(1, 60), 0);
  // A contact running off the left edge: eroded by 14 px from its own border, by 2 px from the edge.
  cv::Mat mask = cv::Mat::zeros(90, 130, CV_8U);
  cv::rectangle(mask, cv::Rect(0, 20, 80, 50), cv::Scalar(1), cv::FILLED);
  const cv::Mat cut = match_mask_of(mask, cv::Rect(0, 0, 110, 90), 14);
  const int row = 45;  // the middle of the band: its first and last kept pixels
  int first = -1, last = -1;
  for (int x = 0; x < 130; ++x)
    if (cut.at<std::uint8_t>(row, x)) {
      if (first < 0) first = x;
      last = x;
    }
  EXPECT_EQ(first, 2);
  EXPECT_EQ(last, 79 - 2 - 14);  // the 5 x 5 kernel's 2 px, then the 14 px ellipse
  // Off the edge, the same as counting the edge as a border.
  const cv::Mat reference = eroded_with_the_edge_as_border(mask, 14);
  EXPECT_EQ(cv::countNonZero(cut(cv::Rect(40, 0, 90, 90)) != reference(cv::Rect(40, 0, 90, 90))), 0);
}

}  // namespace
}  // namespace tirstrain::flow
