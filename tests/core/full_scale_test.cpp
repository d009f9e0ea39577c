#include <gtest/gtest.h>

#include <cstdint>

#include "core/full_scale.hpp"

namespace tirstrain {
namespace {

// A 16-bit frame whose largest value is `max_value` (the rest lower).
cv::Mat frame_u16(int max_value) {
  cv::Mat frame(4, 5, CV_16UC1, cv::Scalar(max_value / 2));
  frame.at<std::uint16_t>(2, 3) = static_cast<std::uint16_t>(max_value);
  return frame;
}

TEST(FullScale, EightBitIs255WhateverTheContent) {
  EXPECT_EQ(full_scale_of(cv::Mat(3, 3, CV_8UC1, cv::Scalar(0))), 255.0);
  EXPECT_EQ(full_scale_of(cv::Mat(3, 3, CV_8UC1, cv::Scalar(17))), 255.0);
}

TEST(FullScale, SixteenBitIsTheSmallestCameraDepthHoldingTheMaximum) {
  EXPECT_EQ(full_scale_of(frame_u16(0)), 1023.0);  // a black frame: the smallest depth
  EXPECT_EQ(full_scale_of(frame_u16(1000)), 1023.0);
  EXPECT_EQ(full_scale_of(frame_u16(1023)), 1023.0);  // 10-bit full scale itself
  EXPECT_EQ(full_scale_of(frame_u16(1024)), 4095.0);  // one code above: 12-bit
  EXPECT_EQ(full_scale_of(frame_u16(4095)), 4095.0);
  EXPECT_EQ(full_scale_of(frame_u16(4096)), 16383.0);  // 14-bit
  EXPECT_EQ(full_scale_of(frame_u16(16383)), 16383.0);
  EXPECT_EQ(full_scale_of(frame_u16(16384)), 65535.0);  // 16-bit
  EXPECT_EQ(full_scale_of(frame_u16(65535)), 65535.0);
}

TEST(FullScale, FloatIsOne) {
  EXPECT_EQ(full_scale_of(cv::Mat(3, 3, CV_32FC1, cv::Scalar(0.25))), 1.0);
  EXPECT_EQ(full_scale_of(cv::Mat(3, 3, CV_32FC1, cv::Scalar(7.0))), 1.0);  // not read from the content
}

}  // namespace
}  // namespace tirstrain
