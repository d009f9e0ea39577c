// The feasible range of a synthetic contact's truth-ellipse centre given where ridges show
// (pipeline/contact_observability.cpp), on the shipped tiny-contact scene: with the fingerprint as shipped,
// ridge ends all round the border pin the centre to about a tenth of a pixel; with the core at the contact's
// centre, ridges run along the whole border and how far the centre is open depends on how faint a ridge flank
// is still seen (1.6 px at 2 sigma per pixel, 0.2 px at 0.2 sigma). Also the
// truth ellipse itself, on a rasterised ellipse.
#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <string>

#include "core/scene.hpp"
#include "pipeline/contact_observability.hpp"
#include "samples/synth_config.hpp"
#include "samples/trial.hpp"

namespace tirstrain::pipeline {
namespace {

samples::SynthConfig tiny_contact() {
  return samples::parse_synth_config(
      load_scene(std::string(TIRSTRAIN_SOURCE_DIR) + "/samples/scenes/hard_tiny_contact.yaml"));
}

TEST(ContactObservability, ShippedTinyContactCentreIsPinnedByRidgeEnds) {
  const samples::Trial trial(tiny_contact());
  const CentreBound bound = contact_centre_bound(trial, 0);
  // Measured 0.13 px (3885 inside, 6662 outside, 3452 hidden); the segmenter's own error on this frame is
  // 1.37 px (BENCHMARKS.md, contact/), so the gap is the segmenter's, not the image's.
  EXPECT_GT(bound.inside_pixels, 2000);
  EXPECT_GT(bound.outside_pixels, 2000);
  EXPECT_GT(bound.hidden_pixels, 1000);
  EXPECT_GT(bound.half_range_px, 0.02);
  EXPECT_LT(bound.half_range_px, 0.3);
  EXPECT_NEAR(bound.noise_sigma, 0.0118, 0.001);  // sqrt(0.8 / 8000 + 0.006^2 + quantisation)
}

TEST(ContactObservability, CoreUnderTheContactLeavesTheCentreOpen) {
  samples::SynthConfig config = tiny_contact();
  config.fingerprint.core_offset_mm = {0.0, 0.0};
  const samples::Trial trial(config);
  const CentreBound at_2_sigma = contact_centre_bound(trial, 0);
  // Measured 1.59 px: an observer that detects ridges pixel by pixel at 2 sigma cannot promise 1 px here
  // (the segmenter measures 3.66 px; contact_synth_test's TinyContactCentreDependsOnWhereTheFingerprintLies).
  EXPECT_GT(at_2_sigma.half_range_px, 1.2);
  EXPECT_LT(at_2_sigma.half_range_px, 2.0);
  // Seeing fainter ridge flanks narrows the range (measured 0.21 px at 0.2 sigma, what integrating along a
  // ridge over ~100 pixels would see). Seeing only crests widens it (4.82 px at 8 sigma:
  // contact_observability_bench --k-sigma 8).
  ObservabilityOptions options;
  options.k_sigma = 0.2;
  const double faint = contact_centre_bound(trial, 0, options).half_range_px;
  EXPECT_LT(faint, 0.4);
}

TEST(ContactObservability, TruthEllipseOfARasterisedEllipse) {
  cv::Mat mask = cv::Mat::zeros(200, 240, CV_8UC1);
  cv::ellipse(mask, cv::RotatedRect({120.0f, 95.0f}, {140.0f, 90.0f}, 30.0f), cv::Scalar(1), cv::FILLED);
  const auto ellipse = truth_contact_ellipse(mask);
  ASSERT_TRUE(ellipse.has_value());
  EXPECT_NEAR(ellipse->cx_px, 120.0, 0.1);
  EXPECT_NEAR(ellipse->cy_px, 95.0, 0.1);
  EXPECT_NEAR(ellipse->semi_major_px, 70.0, 0.7);  // rasterisation: within a pixel's width on the diameter
  EXPECT_NEAR(ellipse->semi_minor_px, 45.0, 0.7);
  EXPECT_FALSE(truth_contact_ellipse(cv::Mat::zeros(50, 50, CV_8UC1)).has_value());
}

// A contact cut by the frame's bottom edge (a third of it outside): the truth is the contact's own outline,
// so the ellipse is the drawn one, not one pulled up into the frame by the frame's edge.
TEST(ContactObservability, TruthEllipseOfAContactCutByTheFrame) {
  cv::Mat mask = cv::Mat::zeros(256, 320, CV_8UC1);
  cv::circle(mask, {160, 225}, 96, cv::Scalar(1), cv::FILLED);
  const auto ellipse = truth_contact_ellipse(mask);
  ASSERT_TRUE(ellipse.has_value());
  EXPECT_NEAR(ellipse->cx_px, 160.0, 0.3);
  EXPECT_NEAR(ellipse->cy_px, 225.0, 0.5);
  EXPECT_NEAR(ellipse->semi_minor_px, 96.5, 1.0);
  EXPECT_NEAR(ellipse->semi_major_px, 96.5, 1.0);
}

}  // namespace
}  // namespace tirstrain::pipeline
