// The reference-pattern band found along each image edge, and "none" where there is no band, on small
// rendered TIR frames: a fingertip contact (ridges) on a smooth background, with a strip of random dots
// multiplied in along one edge as the glass's printed pattern darkens the light.
#include "contact/pattern_band.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>

#include "contact/geometry.hpp"
#include "contact/segmenter.hpp"
#include "core/error.hpp"
#include "dot_band.hpp"
#include "tir_render.hpp"

namespace tirstrain {
namespace {

using contact::ImageEdge;

constexpr int kWidth = 320, kHeight = 256, kBandPx = 28;

test::TirScene small_scene() {
  test::TirScene s;
  s.size = {kWidth, kHeight};
  s.contacts = {{160.0, 128.0, 70.0, 55.0, 0.3}};
  s.core_x = 150.0;
  s.core_y = 120.0;
  s.period_px = 12.0;
  return s;
}

using test::add_dots;

cv::Rect band_at(ImageEdge edge) {
  switch (edge) {
    case ImageEdge::kTop:
      return {0, 0, kWidth, kBandPx};
    case ImageEdge::kBottom:
      return {0, kHeight - kBandPx, kWidth, kBandPx};
    case ImageEdge::kLeft:
      return {0, 0, kBandPx, kHeight};
    case ImageEdge::kRight:
      return {kWidth - kBandPx, 0, kBandPx, kHeight};
    case ImageEdge::kNone:
      break;
  }
  return {};
}

class PatternBandEdge : public ::testing::TestWithParam<ImageEdge> {};

// Edge right, boundary within 2 px of the truth (the band's edge cuts through dots 8 px apart, and where the
// last ones fall moves the boundary found by about a quarter of that), rectangle inside the band and short of
// it by the inset (1 px) plus at most 3 px, confidence high.
TEST_P(PatternBandEdge, FoundWithItsRectangle) {
  const ImageEdge edge = GetParam();
  cv::Mat image = test::render_tir(small_scene());
  const cv::Rect truth = band_at(edge);
  add_dots(image, truth);
  const contact::PatternBand band = contact::detect_pattern_band(image);
  ASSERT_EQ(band.edge, edge) << contact::to_string(band.edge) << " contrast " << band.contrast;
  EXPECT_NEAR(band.width_px, kBandPx, 2.0);
  EXPECT_EQ(band.roi_px & truth, band.roi_px);  // inside the band
  const int across =
      edge == ImageEdge::kTop || edge == ImageEdge::kBottom ? band.roi_px.height : band.roi_px.width;
  EXPECT_GE(across, kBandPx - 4);
  EXPECT_GE(band.confidence, 0.8);
}

INSTANTIATE_TEST_SUITE_P(EveryEdge, PatternBandEdge,
                         ::testing::Values(ImageEdge::kTop, ImageEdge::kBottom, ImageEdge::kLeft,
                                           ImageEdge::kRight),
                         [](const auto& info) { return contact::to_string(info.param); });

// The contact pressed against the band still leaves the band's boundary where it is.
TEST(PatternBand, ContactTouchingTheBand) {
  test::TirScene s = small_scene();
  s.contacts = {{160.0, 200.0, 80.0, 60.0, 0.0}};  // runs into the bottom band
  cv::Mat image = test::render_tir(s);
  const cv::Rect truth = band_at(ImageEdge::kBottom);
  add_dots(image, truth);
  const contact::PatternBand band = contact::detect_pattern_band(image);
  ASSERT_EQ(band.edge, ImageEdge::kBottom);
  EXPECT_NEAR(band.width_px, kBandPx, 2.0);
  EXPECT_EQ(band.roi_px & truth, band.roi_px);
}

TEST(PatternBand, NoneWithoutBand) {
  const contact::PatternBand band = contact::detect_pattern_band(test::render_tir(small_scene()));
  EXPECT_EQ(band.edge, ImageEdge::kNone);
  EXPECT_TRUE(band.roi_px.empty());
  EXPECT_LT(band.confidence, 0.5);
}

// Textures and layouts that are not a band: a contact running off an edge, ridges filling the whole frame,
// an edge strip brighter (and so noisier) than the rest, a frame of noise only.
TEST(PatternBand, NoneOnLookAlikes) {
  test::TirScene edge_contact = small_scene();
  edge_contact.contacts = {{40.0, 128.0, 90.0, 70.0, 0.0}};
  test::TirScene full_ridges = small_scene();
  full_ridges.contacts = {{160.0, 128.0, 400.0, 400.0, 0.0}};
  full_ridges.whorl = false;
  full_ridges.ridge_angle_rad = 0.0;  // parallel to the top edge
  test::TirScene noise_only = small_scene();
  noise_only.contacts = {{-1000.0, -1000.0, 1.0, 1.0, 0.0}};
  for (const test::TirScene& s : {edge_contact, full_ridges, noise_only}) {
    const contact::PatternBand band = contact::detect_pattern_band(test::render_tir(s));
    EXPECT_EQ(band.edge, ImageEdge::kNone) << contact::to_string(band.edge) << " " << band.contrast;
  }
  cv::Mat bright = test::render_tir(noise_only);
  cv::Mat strip = bright(band_at(ImageEdge::kTop));
  cv::Mat noisy, extra(strip.size(), CV_32F);
  strip.convertTo(noisy, CV_32F);
  cv::randn(extra, 0.0, 20.0);  // four times the frame's noise (0.02 of full scale)
  noisy += extra;
  noisy.convertTo(strip, CV_8U);
  EXPECT_EQ(contact::detect_pattern_band(bright).edge, ImageEdge::kNone);
}

// Without the band excluded, the segmenter still returns the fingertip alone: the dotted strip is a separate
// textured region, further than merge_gap_periods from the contact, and is flagged but not joined. The same
// for a second textured object at the image's edge. The outline is then the one the fingertip alone gives
// (IoU >= 0.99 with it, centre within 0.3 px), and within this small renderer's accuracy of the truth.
TEST(PatternBand, SegmenterKeepsTheFingertipOnly) {
  const test::TirScene s = small_scene();
  const cv::Mat plain = test::render_tir(s);
  contact::ContactSegmenter alone_segmenter;
  const contact::ContactResult alone = alone_segmenter.segment(plain);
  ASSERT_TRUE(alone.ellipse.has_value());
  const cv::Mat alone_mask = contact::rasterize_polygon(alone.hull_px, s.size);
  const cv::Mat truth = test::render_truth_mask(s);
  cv::Mat banded = plain.clone();
  add_dots(banded, band_at(ImageEdge::kBottom));
  test::TirScene with_object = s;
  with_object.contacts.push_back({-10.0, 128.0, 40.0, 60.0, 0.0});  // a textured object at the left edge
  for (const cv::Mat& image : {banded, test::render_tir(with_object)}) {
    contact::ContactSegmenter segmenter;
    const contact::ContactResult r = segmenter.segment(image);
    ASSERT_TRUE(r.ellipse.has_value());
    EXPECT_NE(r.status & contact::kMultipleBlobs, 0u) << contact::contact_status_text(r.status);
    EXPECT_EQ(r.status & contact::kTouchesEdge, 0u) << contact::contact_status_text(r.status);
    const cv::Mat mask = contact::rasterize_polygon(r.hull_px, s.size);
    std::cout << "  IoU with the fingertip alone " << contact::mask_iou(mask, alone_mask)
              << ", with the truth " << contact::mask_iou(mask, truth)
              << " (alone: " << contact::mask_iou(alone_mask, truth) << ")\n";
    EXPECT_GE(contact::mask_iou(mask, alone_mask), 0.99);
    EXPECT_GE(contact::mask_iou(mask, truth), 0.94);
    EXPECT_NEAR(r.ellipse->cx_px, alone.ellipse->cx_px, 0.3);
    EXPECT_NEAR(r.ellipse->cy_px, alone.ellipse->cy_px, 0.3);
  }
}

TEST(PatternBand, WrongImageTypeIsAnError) {
  EXPECT_THROW(contact::detect_pattern_band(cv::Mat(64, 64, CV_8UC3)), Error);
}

}  // namespace
}  // namespace tirstrain
