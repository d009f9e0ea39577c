// Contact segmentation on rendered TIR images with exact truth: mask IoU, ellipse centre and axes, ridge
// period and orientation, and every named hard case giving a defined result.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <numbers>

#include "contact/geometry.hpp"
#include "contact/segmenter.hpp"
#include "contact/texture_regions.hpp"
#include "tests/contact/tir_render.hpp"

namespace tirstrain::contact {
namespace {

using test::TirScene;

double angle_difference_mod_pi(double a, double b) {
  double d = std::fmod(std::abs(a - b), std::numbers::pi);
  return std::min(d, std::numbers::pi - d);
}

struct Measured {
  ContactResult result;
  double iou = 0.0;
};

Measured run(const TirScene& scene, SegmenterOptions options = {}) {
  ContactSegmenter segmenter(options);
  Measured m;
  m.result = segmenter.segment(test::render_tir(scene));
  if (!m.result.hull_px.empty())
    m.iou = mask_iou(rasterize_polygon(m.result.hull_px, scene.size), test::render_truth_mask(scene));
  return m;
}

void expect_finite(const ContactResult& r) {
  EXPECT_TRUE(std::isfinite(r.area_mm2));
  for (const auto& p : r.hull_px) EXPECT_TRUE(std::isfinite(p.x) && std::isfinite(p.y));
  EXPECT_TRUE(cv::checkRange(r.orientation_rad));
  EXPECT_TRUE(cv::checkRange(r.coherence));
}

void expect_ellipse_close(const ContactResult& r, const Ellipse& truth, double centre_tol_px,
                          double axis_tol) {
  ASSERT_TRUE(r.ellipse.has_value());
  const Ellipse& e = *r.ellipse;
  std::cout << "  ellipse centre error " << std::hypot(e.cx_px - truth.cx_px, e.cy_px - truth.cy_px)
            << " px, axes " << e.semi_major_px / truth.semi_major_px - 1.0 << ", "
            << e.semi_minor_px / truth.semi_minor_px - 1.0 << " relative\n";
  EXPECT_LE(std::hypot(e.cx_px - truth.cx_px, e.cy_px - truth.cy_px), centre_tol_px);
  EXPECT_NEAR(e.semi_major_px / truth.semi_major_px, 1.0, axis_tol);
  EXPECT_NEAR(e.semi_minor_px / truth.semi_minor_px, 1.0, axis_tol);
}

TEST(ContactSegmenter, DefaultSceneMeetsAccuracy) {
  const TirScene scene;
  const Measured m = run(scene);
  std::cout << "  status " << contact_status_text(m.result.status) << " IoU " << m.iou << " period "
            << m.result.ridge_period_px << " px\n";
  EXPECT_EQ(m.result.status, kContactOk);
  EXPECT_GE(m.iou, 0.97);
  expect_ellipse_close(m.result, scene.contacts[0], 1.0, 0.02);
  ASSERT_EQ(m.result.hull_px.size(), 50u);
  const double truth_area_mm2 = std::numbers::pi * 150.0 * 110.0 / (52.0 * 52.0);
  EXPECT_NEAR(m.result.area_mm2 / truth_area_mm2, 1.0, 0.04);
  EXPECT_EQ(m.result.polarity, -1);
  expect_finite(m.result);
}

TEST(ContactSegmenter, LargeFrameAndBrightRidges16Bit) {
  TirScene scene;
  scene.size = {1280, 1024};
  scene.contacts = {{655.0, 498.0, 270.0, 190.0, -0.3}};
  scene.core_x = 640.0;
  scene.core_y = 470.0;
  scene.dark_ridges = false;
  scene.background = 0.15;
  scene.depth = CV_16U;
  const Measured m = run(scene);
  std::cout << "  status " << contact_status_text(m.result.status) << " IoU " << m.iou << "\n";
  EXPECT_EQ(m.result.status, kContactOk);
  EXPECT_GE(m.iou, 0.97);
  expect_ellipse_close(m.result, scene.contacts[0], 1.0, 0.02);
  EXPECT_EQ(m.result.polarity, 1);
}

TEST(ContactSegmenter, FullResolutionAgreesWithReduced) {
  const TirScene scene;
  SegmenterOptions full;
  full.downsample = 1;
  const Measured m = run(scene, full);
  std::cout << "  full resolution IoU " << m.iou << "\n";
  EXPECT_GE(m.iou, 0.97);
  expect_ellipse_close(m.result, scene.contacts[0], 1.0, 0.02);
}

TEST(ContactSegmenter, MeasuresRidgePeriodFromSpectrum) {
  for (double period_px : {16.0, 23.4, 35.0}) {
    TirScene scene;
    scene.period_px = period_px;
    ContactSegmenter segmenter;
    const ContactResult r = segmenter.segment(test::render_tir(scene));
    ASSERT_TRUE(segmenter.period_measured());
    std::cout << "  period truth " << period_px << " measured " << *segmenter.ridge_period_px() << " px\n";
    EXPECT_NEAR(*segmenter.ridge_period_px() / period_px, 1.0, 0.05);
    EXPECT_EQ(r.status, kContactOk);
  }
}

TEST(ContactSegmenter, OrientationFieldMatchesRidges) {
  for (bool whorl : {false, true}) {
    TirScene scene;
    scene.whorl = whorl;
    scene.ridge_angle_rad = 0.52;
    const Measured m = run(scene);
    double sum = 0.0;
    int count = 0;
    for (int by = 0; by < m.result.coherence.rows; ++by)
      for (int bx = 0; bx < m.result.coherence.cols; ++bx) {
        if (m.result.coherence.at<float>(by, bx) < 0.5) continue;
        // Blocks near the whorl's core have curved ridges; the truth is taken at the block centre.
        const double truth = test::ridge_orientation(scene, bx * 32 + 15.5, by * 32 + 15.5);
        sum += angle_difference_mod_pi(m.result.orientation_rad.at<float>(by, bx), truth);
        ++count;
      }
    ASSERT_GT(count, 40);
    const double mean_deg = sum / count * 180.0 / std::numbers::pi;
    std::cout << "  " << (whorl ? "whorl" : "straight") << " ridges: mean |orientation error| " << mean_deg
              << " deg over " << count << " blocks\n";
    EXPECT_LE(mean_deg, whorl ? 5.0 : 2.0);
  }
}

TEST(ContactSegmenter, UniformImageIsNoContact) {
  for (double noise : {0.0, 0.02}) {
    TirScene scene;
    scene.contacts.clear();
    scene.noise = noise;
    const Measured m = run(scene);
    EXPECT_EQ(m.result.status & kNoContact, kNoContact);
    EXPECT_EQ(m.result.area_mm2, 0.0);
    EXPECT_TRUE(m.result.hull_px.empty());
    EXPECT_FALSE(m.result.ellipse.has_value());
    EXPECT_EQ(m.result.orientation_rad.size(), cv::Size(20, 16));
    EXPECT_EQ(cv::countNonZero(m.result.coherence), 0);
    expect_finite(m.result);
  }
  const cv::Mat black = cv::Mat::zeros(512, 640, CV_8UC1), white(512, 640, CV_8UC1, cv::Scalar(255));
  ContactSegmenter segmenter;
  EXPECT_EQ(segmenter.segment(black).status, kNoContact);
  EXPECT_EQ(segmenter.segment(white).status, kNoContact | kSaturated);
  EXPECT_EQ(segmenter.segment(cv::Mat(3, 3, CV_8UC1, cv::Scalar(9))).status, kNoContact);
}

// Frames narrower or shorter than one working block (a row or column of the block-averaged image is empty),
// at every pixel type and working resolution: a defined "no contact", never a crash. Meant to be run under
// -DTIRSTRAIN_SANITIZE=ON as well (a null-pointer store was once reported in the block averaging).
TEST(ContactSegmenter, DegenerateFrameSizesAreNoContact) {
  cv::RNG rng(7);
  for (const cv::Size size :
       {cv::Size(1, 1), cv::Size(3, 5), cv::Size(5, 3), cv::Size(40, 1), cv::Size(1, 40), cv::Size(33, 4),
        cv::Size(4, 33), cv::Size(64, 9), cv::Size(9, 64)}) {
    for (const int depth : {CV_8U, CV_16U, CV_32F}) {
      cv::Mat image(size, CV_MAKETYPE(depth, 1));
      rng.fill(image, cv::RNG::UNIFORM, 0.0, depth == CV_32F ? 1.0 : (depth == CV_8U ? 255.0 : 4095.0));
      for (const int downsample : {0, 1, 3, 8}) {
        SegmenterOptions options;
        options.downsample = downsample;
        ContactSegmenter segmenter(options);
        const ContactResult r = segmenter.segment(image);
        EXPECT_EQ(r.status & kNoContact, kNoContact) << size << " depth " << depth << " f " << downsample;
        EXPECT_EQ(r.area_mm2, 0.0);
        EXPECT_TRUE(r.hull_px.empty());
        expect_finite(r);
      }
    }
  }
}

TEST(ContactSegmenter, ContactTouchingFrameEdge) {
  TirScene scene;
  scene.contacts = {{90.0, 300.0, 150.0, 110.0, 0.2}};  // a third of it outside the frame
  scene.core_x = 100.0;
  const Measured m = run(scene);
  std::cout << "  status " << contact_status_text(m.result.status) << " IoU " << m.iou << "\n";
  EXPECT_EQ(m.result.status, kTouchesEdge);
  EXPECT_GE(m.iou, 0.93);
  expect_ellipse_close(m.result, scene.contacts[0], 2.0, 0.03);
  expect_finite(m.result);
}

TEST(ContactSegmenter, TwoBlobsAreFlaggedAndJoined) {
  TirScene scene;
  scene.contacts = {{230.0, 256.0, 100.0, 90.0, 0.0}, {440.0, 256.0, 80.0, 70.0, 0.0}};
  const Measured m = run(scene);
  std::cout << "  status " << contact_status_text(m.result.status) << "\n";
  EXPECT_EQ(m.result.status & kMultipleBlobs, kMultipleBlobs);
  // The joined hull spans both regions.
  ASSERT_FALSE(m.result.hull_px.empty());
  EXPECT_LT(m.result.bounding_box_px.x, 135);
  EXPECT_GT(m.result.bounding_box_px.br().x, 515);
  expect_finite(m.result);
}

// The centre from the ridge labels, by default on every contact: the logistic fit on small contacts (under
// ridge_label_below_periods ridge periods in radius), the per-sector brackets on larger ones; off with
// ridge_label_centre false and ridge_label_below_periods 0. Within 1 px on this renderer's small contacts
// and its default-sized ones (measured: small, straight ridges 0.30 px against the level edge's 0.19, whorl
// 0.55 against 0.95; default size, whorl 0.55 against 0.45, straight 0.14 against 0.34). On this one whorl
// the brackets' midway borders do worse than the level edge; over random scenes of this renderer they do
// better (CentreOverRandomScenes).
TEST(ContactSegmenter, RidgeLabelCentreOnSmallAndLargeContacts) {
  SegmenterOptions level_edge_only;
  level_edge_only.ridge_label_below_periods = 0.0;
  level_edge_only.ridge_label_centre = false;
  for (const int size : {0, 1, 2, 3}) {
    TirScene scene;
    scene.whorl = size == 1 || size == 2;
    if (size < 2) {
      scene.contacts = {{320.0, 256.0, 50.0, 42.0, 0.4}};
      scene.core_x = 310.0;
      scene.core_y = 250.0;
    }
    const Measured labelled = run(scene);
    const Measured level_edge = run(scene, level_edge_only);
    ASSERT_TRUE(labelled.result.ellipse && level_edge.result.ellipse);
    EXPECT_TRUE(labelled.result.ridge_label_shift_px.has_value());
    EXPECT_FALSE(level_edge.result.ridge_label_shift_px.has_value());
    const Ellipse& truth = scene.contacts[0];
    const auto centre_px = [&](const Measured& m) {
      return std::hypot(m.result.ellipse->cx_px - truth.cx_px, m.result.ellipse->cy_px - truth.cy_px);
    };
    const char* names[] = {"small, straight", "small, whorl", "default, whorl", "default, straight"};
    std::cout << "  " << names[size] << ": centre error " << centre_px(labelled)
              << " px from the ridge labels, " << centre_px(level_edge) << " px from the level edge\n";
    EXPECT_LE(centre_px(labelled), 1.0);
    // Small contacts (the logistic fit): the outline is moved and its elongation blended with the fit's
    // (SegmenterOptions::ridge_label_shape_weight), its mean semi-axis kept, so the area moves by the square
    // of the elongation's change only (measured: 0.16 % and 0.17 %). Large ones (the brackets): also resized
    // and reshaped, and the area comes nearer the truth's (measured: whorl 0.4 %, straight 0.3 %, against
    // the level edge's 2.6 % and 2.4 %).
    const double truth_mm2 = std::numbers::pi * truth.semi_major_px * truth.semi_minor_px / (52.0 * 52.0);
    std::cout << "    area " << labelled.result.area_mm2 / truth_mm2 << " of the truth's, level edge "
              << level_edge.result.area_mm2 / truth_mm2 << "\n";
    if (size < 2) {
      ASSERT_TRUE(labelled.result.ridge_label_shape_px.has_value());
      EXPECT_EQ((*labelled.result.ridge_label_shape_px)[0], 0.0);  // no size change
      EXPECT_NEAR(labelled.result.area_mm2 / level_edge.result.area_mm2, 1.0, 0.005);
      EXPECT_NEAR(labelled.result.ellipse->semi_major_px + labelled.result.ellipse->semi_minor_px,
                  level_edge.result.ellipse->semi_major_px + level_edge.result.ellipse->semi_minor_px, 1e-9);
    } else {
      EXPECT_TRUE(labelled.result.ridge_label_shape_px.has_value());
      EXPECT_NEAR(labelled.result.area_mm2 / truth_mm2, 1.0, 0.01);
      EXPECT_LT(std::abs(labelled.result.area_mm2 / truth_mm2 - 1.0),
                std::abs(level_edge.result.area_mm2 / truth_mm2 - 1.0));
    }
  }
}

// The centre over 60 random scenes of this renderer: contact size, shape, orientation and place; whorl or
// straight ridges, the whorl's core anywhere near the middle; period 20-26 px; noise 0.5-2 % of full scale,
// below the border averaging's threshold, so that every scene gets the brackets. Measured RMS 0.205 px, worst
// 0.60 px; with each sector's border just beyond its inside labels and no gap weights (contact/
// ridge_labels.cpp, fit_brackets) 0.337 / 1.00 px. Asserted at 0.27 and 0.8 px so that the two are told
// apart.
TEST(ContactSegmenter, CentreOverRandomScenes) {
  cv::RNG rng(23);
  constexpr int kScenes = 60;
  double sum_squared_px2 = 0.0, worst_px = 0.0;
  for (int i = 0; i < kScenes; ++i) {
    TirScene scene;
    scene.contacts = {{rng.uniform(300.0, 340.0), rng.uniform(236.0, 276.0), rng.uniform(130.0, 170.0),
                       rng.uniform(95.0, 125.0), rng.uniform(0.0, std::numbers::pi)}};
    scene.whorl = i % 3 != 2;
    scene.core_x = rng.uniform(260.0, 380.0);
    scene.core_y = rng.uniform(200.0, 310.0);
    scene.ridge_angle_rad = rng.uniform(0.0, std::numbers::pi);
    scene.period_px = rng.uniform(20.0, 26.0);
    scene.noise = rng.uniform(0.005, 0.02);
    scene.seed = static_cast<std::uint64_t>(i + 1);
    const Measured m = run(scene);
    ASSERT_TRUE(m.result.ellipse.has_value()) << "scene " << i;
    EXPECT_TRUE(m.result.ridge_label_shift_px.has_value()) << "scene " << i;
    const Ellipse& truth = scene.contacts[0];
    const double centre_px =
        std::hypot(m.result.ellipse->cx_px - truth.cx_px, m.result.ellipse->cy_px - truth.cy_px);
    sum_squared_px2 += centre_px * centre_px;
    worst_px = std::max(worst_px, centre_px);
  }
  const double rms_px = std::sqrt(sum_squared_px2 / kScenes);
  std::cout << "  " << kScenes << " random scenes: centre error RMS " << rms_px << " px, worst " << worst_px
            << " px\n";
  EXPECT_LE(rms_px, 0.27);
  EXPECT_LE(worst_px, 0.8);
}

TEST(ContactSegmenter, SweatPatchesInsideContact) {
  TirScene scene;
  scene.sweat = {{300.0, 240.0, 45.0}, {400.0, 300.0, 30.0}};
  const Measured m = run(scene);
  std::cout << "  status " << contact_status_text(m.result.status) << " IoU " << m.iou << "\n";
  EXPECT_EQ(m.result.status, kContactOk);
  EXPECT_GE(m.iou, 0.93);
  expect_ellipse_close(m.result, scene.contacts[0], 1.0, 0.02);
}

TEST(ContactSegmenter, SaturatedFrame) {
  TirScene scene;
  scene.gain = 1.5;  // background and valleys clip at full scale
  const Measured m = run(scene);
  std::cout << "  status " << contact_status_text(m.result.status) << " IoU " << m.iou << "\n";
  EXPECT_EQ(m.result.status, kSaturated);
  EXPECT_GE(m.iou, 0.93);
  expect_ellipse_close(m.result, scene.contacts[0], 1.0, 0.02);
}

TEST(ContactSegmenter, VeryLowContrast) {
  TirScene scene;
  scene.ridge_depth = 0.025;  // ~6 grey levels against noise of 2.5 levels
  scene.noise = 0.01;
  const Measured m = run(scene);
  std::cout << "  status " << contact_status_text(m.result.status) << " IoU " << m.iou << " energy "
            << m.result.texture_energy << "\n";
  EXPECT_EQ(m.result.status, kLowContrast);
  EXPECT_GE(m.iou, 0.93);
  // Hard case: only IoU is specified; the ellipse is checked loosely (measured 2.0 px, 3.1 %).
  expect_ellipse_close(m.result, scene.contacts[0], 3.0, 0.04);
}

TEST(ContactSegmenter, PureNoiseIsNoContact) {
  TirScene scene;
  scene.contacts.clear();
  scene.noise = 0.08;
  const Measured m = run(scene);
  EXPECT_EQ(m.result.status, kNoContact);
}

TEST(ContactSegmenter, RidgesFillingTheFrameAreAContactOverTheWholeFrame) {
  // A contact larger than the view (magnified optics, a pressed pad): no background for Otsu's split, so
  // its two classes are both ridges, far above what the frame's own noise gives. Measured: hull IoU with
  // the whole frame 0.999 at both noise levels (Otsu's ratio 1.09: "no contact" by the ratio alone).
  TirScene scene;
  scene.contacts = {{320.0, 256.0, 2000.0, 2000.0, 0.0}};
  for (const double noise : {0.02, 0.06}) {
    scene.noise = noise;
    const Measured m = run(scene);
    std::cout << "  noise " << noise << ": status " << contact_status_text(m.result.status) << " IoU "
              << m.iou << " energy ratio " << m.result.energy_ratio << "\n";
    EXPECT_EQ(m.result.status & kNoContact, 0u) << noise;
    EXPECT_NE(m.result.status & kTouchesEdge, 0u) << noise;
    EXPECT_GE(m.iou, 0.97) << noise;
    expect_finite(m.result);
  }
}

TEST(ContactSegmenter, TheNoiseEnergyIsWhatANoiseFrameGives) {
  // noise_energy_per_sigma's fixed-seed noise against another, larger noise image of σ = 0.03: the mean
  // texture energy agrees within 5 % at three ridge periods (working pixels).
  for (const double period_w : {4.0, 5.85, 8.0}) {
    cv::Mat noise(400, 400, CV_32F);
    cv::RNG rng(99);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, 0.03);
    TextureImages images;
    ridge_texture_energy(noise, period_w, cv::Rect(), images);
    const double measured = cv::mean(images.energy)[0];
    EXPECT_NEAR(measured / (0.03 * noise_energy_per_sigma(period_w)), 1.0, 0.05) << period_w;
  }
}

TEST(ContactSegmenter, ExcludedBandIsNeverContact) {
  TirScene scene;
  scene.contacts = {{320.0, 200.0, 150.0, 110.0, 0.0}};
  // A textured band at the bottom (the reference pattern on the glass), touching the contact.
  cv::Mat image = test::render_tir(scene);
  for (int y = 440; y < 512; ++y)
    for (int x = 0; x < 640; ++x) image.at<std::uint8_t>(y, x) = ((x / 6 + y / 6) % 2) != 0 ? 40 : 200;
  SegmenterOptions options;
  options.exclude_px = cv::Rect(0, 440, 640, 72);
  ContactSegmenter segmenter(options);
  const ContactResult r = segmenter.segment(image);
  EXPECT_EQ(r.status, kContactOk);
  ASSERT_TRUE(r.ellipse.has_value());
  EXPECT_NEAR(r.ellipse->cy_px, 200.0, 1.0);
  EXPECT_LT(r.bounding_box_px.br().y, 330);
}

// Region tracking (the frames after one with a contact are segmented around it): on a 1280x1024 frame whose
// contact is a fifth of it, the tracked frames give the same outline as whole frames (IoU of the two hulls
// >= 0.997, ellipse centres within 0.25 px: Otsu's threshold of the region differs a little from the
// frame's, which moves where the rays start; same orientation blocks to 0.01 rad where both have a value)
// and the same accuracy against the truth (IoU >= 0.97).
TEST(ContactSegmenter, TrackedRegionAgreesWithWholeFrame) {
  TirScene scene;
  scene.size = {1280, 1024};
  scene.contacts = {{645.0, 509.0, 300.0, 220.0, 0.4}};
  scene.core_x = 600.0;
  scene.core_y = 460.0;
  const cv::Mat image = test::render_tir(scene);
  const cv::Mat truth = test::render_truth_mask(scene);
  SegmenterOptions whole_options;
  whole_options.track_region = false;
  ContactSegmenter tracking, whole(whole_options);
  const ContactResult reference = whole.segment(image);
  ASSERT_TRUE(reference.ellipse.has_value());
  for (int frame = 0; frame < 3; ++frame) {
    const ContactResult r = tracking.segment(image);
    ASSERT_TRUE(r.ellipse.has_value()) << frame;
    const double agreement =
        mask_iou(rasterize_polygon(r.hull_px, scene.size), rasterize_polygon(reference.hull_px, scene.size));
    const double iou = mask_iou(rasterize_polygon(r.hull_px, scene.size), truth);
    std::cout << "  frame " << frame << ": IoU against whole frame " << agreement << ", against truth " << iou
              << "\n";
    EXPECT_GE(agreement, 0.997);
    EXPECT_GE(iou, 0.97);
    EXPECT_LE(
        std::hypot(r.ellipse->cx_px - reference.ellipse->cx_px, r.ellipse->cy_px - reference.ellipse->cy_px),
        0.25);
    EXPECT_EQ(r.status, reference.status);
    ASSERT_EQ(r.orientation_rad.size(), reference.orientation_rad.size());
    int compared = 0;
    for (int y = 0; y < r.orientation_rad.rows; ++y)
      for (int x = 0; x < r.orientation_rad.cols; ++x) {
        if (r.coherence.at<float>(y, x) <= 0.0f || reference.coherence.at<float>(y, x) <= 0.0f) continue;
        ++compared;
        EXPECT_LE(angle_difference_mod_pi(r.orientation_rad.at<float>(y, x),
                                          reference.orientation_rad.at<float>(y, x)),
                  0.01);
      }
    EXPECT_GT(compared, 50);
  }
}

// A tracked region never hides a change: a contact that moves out of it is found again in the same frame
// (the outline reaches the region's side, so the whole frame is segmented), and a second contact appearing
// elsewhere is flagged at the latest at the next whole frame (full_frame_every).
TEST(ContactSegmenter, TrackedRegionFollowsChanges) {
  TirScene scene;
  scene.size = {1280, 1024};
  scene.contacts = {{400.0, 400.0, 150.0, 120.0, 0.2}};
  scene.core_x = 390.0;
  scene.core_y = 380.0;
  SegmenterOptions options;
  options.full_frame_every = 4;
  ContactSegmenter segmenter(options);
  ASSERT_TRUE(segmenter.segment(test::render_tir(scene)).ellipse.has_value());
  // Moved by 250 px: outside the region around the first one.
  TirScene moved = scene;
  moved.contacts = {{650.0, 600.0, 150.0, 120.0, 0.2}};
  moved.core_x = 640.0;
  moved.core_y = 580.0;
  const ContactResult r = segmenter.segment(test::render_tir(moved));
  ASSERT_TRUE(r.ellipse.has_value());
  EXPECT_LE(std::hypot(r.ellipse->cx_px - 650.0, r.ellipse->cy_px - 600.0), 1.5);
  EXPECT_GE(mask_iou(rasterize_polygon(r.hull_px, moved.size), test::render_truth_mask(moved)), 0.97);
  // A second contact far away: flagged within full_frame_every frames.
  TirScene two = moved;
  two.contacts.push_back({1100.0, 200.0, 90.0, 80.0, 0.0});
  bool flagged = false;
  for (int frame = 0; frame < options.full_frame_every && !flagged; ++frame)
    flagged = (segmenter.segment(test::render_tir(two)).status & kMultipleBlobs) != 0;
  EXPECT_TRUE(flagged);
}

TEST(ContactSegmenter, RejectsColourImages) {
  ContactSegmenter segmenter;
  EXPECT_THROW(segmenter.segment(cv::Mat(10, 10, CV_8UC3)), std::exception);
}

}  // namespace
}  // namespace tirstrain::contact

namespace tirstrain::contact {
namespace {

// A small contact's outline from its ellipse (SegmenterOptions::small_contact_ellipse_outline) on this
// renderer's ridges (a linear soft border, no contrast fade, sinusoidal ridges), not the synthetic trials'
// it was measured on: straight and whorled ridges, three placements of the ridges each, a 45 × 35 px
// contact. Measured: IoU 0.935-0.974 (mean 0.954) from the ellipse against 0.938-0.955 (mean 0.948) traced,
// where this renderer's 3 px linear border and the ridges' placement decide most of the error. Asserted:
// at least as good as the traced outline on average, never more than 0.005 worse on one frame, and
// IoU >= 0.93 everywhere.
TEST(ContactSegmenter, SmallContactOutlineFromItsEllipseOnOtherRidges) {
  double sum_ellipse = 0.0, sum_traced = 0.0;
  int count = 0;
  for (bool whorl : {false, true})
    for (double shift : {0.0, 7.0, 13.0}) {
      TirScene scene;
      scene.contacts = {{320.0, 256.0, 45.0, 35.0, 0.3}};
      scene.whorl = whorl;
      scene.core_x = 300.0 + shift;
      scene.core_y = 240.0 - shift;
      scene.ridge_angle_rad = 0.4 + 0.1 * shift;
      SegmenterOptions traced;
      traced.small_contact_ellipse_outline = false;
      const Measured e = run(scene), t = run(scene, traced);
      ASSERT_TRUE(e.result.ellipse.has_value());
      std::cout << "  " << (whorl ? "whorl" : "straight") << ", ridges shifted " << shift << " px: IoU "
                << e.iou << " from the ellipse, " << t.iou << " traced\n";
      EXPECT_GE(e.iou, 0.93);
      EXPECT_GE(e.iou, t.iou - 0.005);
      sum_ellipse += e.iou;
      sum_traced += t.iou;
      ++count;
    }
  std::cout << "  mean IoU " << sum_ellipse / count << " from the ellipse, " << sum_traced / count
            << " traced\n";
  EXPECT_GE(sum_ellipse, sum_traced);
}

}  // namespace
}  // namespace tirstrain::contact
