// Contact accuracy on `tirstrain synth` trials against truth.h5: mask IoU, ellipse centre and axes, for the
// default scene and each named hard case that has contact. The scenes are the shipped ones, shortened to
// two frames so the test stays fast.
#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <numbers>
#include <optional>
#include <span>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "contact/ellipse.hpp"
#include "contact/geometry.hpp"
#include "contact/segmenter.hpp"
#include "core/h5_file.hpp"
#include "core/scene.hpp"
#include "pipeline/contact_observability.hpp"
#include "pipeline/contact_stage.hpp"

namespace tirstrain::contact {
namespace {

namespace fs = std::filesystem;

struct Tolerance {
  double min_iou;
  double centre_px;
  double axis_relative;
  bool border_averaged;  // texture SNR below SegmenterOptions::border_average_snr
  // The centre moved from the level edge's (ContactResult::ridge_label_shift_px): by the ridge labels, or on
  // frames averaged along the border by the border band's fit alone.
  bool ridge_labels;
};

// Where the ellipse's centre comes from: the segmenter's defaults (the ridge labels) or the level edge alone.
enum class Centre { scene_defaults, level_edge };

// Renders samples/scenes/<scene>.yaml, changed by `edit`, into test-tmp/contact_synth/<name>.
void render(const std::string& scene, const std::string& name, const std::function<void(YAML::Node&)>& edit,
            fs::path* out) {
  const fs::path dir = fs::path(TIRSTRAIN_TEST_TMP) / "contact_synth" / name;
  fs::remove_all(dir);
  fs::create_directories(dir.parent_path());
  YAML::Node scene_yaml =
      YAML::LoadFile(std::string(TIRSTRAIN_SOURCE_DIR) + "/samples/scenes/" + scene + ".yaml");
  edit(scene_yaml);
  const fs::path scene_path = dir.string() + ".yaml";
  std::ofstream(scene_path) << scene_yaml << "\n";
  const std::string command = std::string(TIRSTRAIN_CLI) + " synth --scene " + scene_path.string() +
                              " --out " + dir.string() + " > " + dir.string() + ".log 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0) << command;
  *out = dir;
}

cv::Mat frame_image(const fs::path& dir, std::size_t frame) {
  char file[32];
  std::snprintf(file, sizeof file, "%06zu.png", frame);
  return cv::imread((dir / "frames" / file).string(), cv::IMREAD_UNCHANGED);
}

// Frame `f` of truth.h5's /contact/mask (255 inside) and the truth's ellipse, as `tirstrain validate` takes
// it (pipeline::truth_contact_ellipse: the direct fit of the mask's outline, semi-axes + 0.5 px to the
// pixels' outer edges). The generator's nominal ellipse (root attributes) is not the mask's ellipse: its
// border irregularity (k = 2..5 harmonics of a few %) changes the axes by up to that much.
struct TruthContact {
  cv::Mat mask;
  std::optional<Ellipse> ellipse;
};

TruthContact truth_contact(const std::vector<std::int64_t>& masks, const H5Shape& shape, std::size_t f) {
  const int height = static_cast<int>(shape[1]), width = static_cast<int>(shape[2]);
  TruthContact truth{cv::Mat(height, width, CV_8UC1), std::nullopt};
  for (int i = 0; i < height * width; ++i)
    truth.mask.data[i] =
        masks[f * static_cast<std::size_t>(height * width) + static_cast<std::size_t>(i)] != 0 ? 255 : 0;
  truth.ellipse = pipeline::truth_contact_ellipse(truth.mask);
  return truth;
}

// One segmenter's errors against the truth over a trial's frames: the centre (px), both semi-axes pooled
// (relative: 0.01 = 1 %), RMS and worst, and the worst mask IoU.
struct FrameErrors {
  double sum_squared_centre_px2 = 0.0, worst_centre_px = 0.0;
  double sum_squared_axis = 0.0, worst_axis = 0.0;
  double worst_iou = 1.0, sum_iou = 0.0;
  int frames = 0;

  void add(const ContactResult& r, const TruthContact& truth, cv::Size size) {
    const Ellipse& m = *r.ellipse;
    const Ellipse& t = *truth.ellipse;
    const double centre_px = std::hypot(m.cx_px - t.cx_px, m.cy_px - t.cy_px);
    sum_squared_centre_px2 += centre_px * centre_px;
    worst_centre_px = std::max(worst_centre_px, centre_px);
    for (const double axis :
         {m.semi_major_px / t.semi_major_px - 1.0, m.semi_minor_px / t.semi_minor_px - 1.0}) {
      sum_squared_axis += 0.5 * axis * axis;
      worst_axis = std::max(worst_axis, std::abs(axis));
    }
    const double iou = mask_iou(rasterize_polygon(r.hull_px, size), truth.mask);
    worst_iou = std::min(worst_iou, iou);
    sum_iou += iou;
    ++frames;
  }
  double mean_iou() const { return sum_iou / std::max(1, frames); }
  double centre_rms_px() const { return std::sqrt(sum_squared_centre_px2 / std::max(1, frames)); }
  double axis_rms() const { return std::sqrt(sum_squared_axis / std::max(1, frames)); }
};

// Segments the first `frames` frames of the trial rendered in `dir` (all of them when 0) with each of
// `segmenters` in turn, in frame order, adding each one's errors to the matching `errors`. `check`
// (optional) is called with each result, e.g. to assert which centre was applied.
void measure_frames(
    const fs::path& dir, std::size_t frames, std::span<ContactSegmenter> segmenters,
    std::span<FrameErrors> errors,
    const std::function<void(std::size_t f, std::size_t k, const ContactResult&)>& check = {}) {
  ASSERT_EQ(segmenters.size(), errors.size());
  H5Reader truth((dir / "truth.h5").string());
  H5Shape shape;
  const auto masks = truth.read_integers("/contact/mask", &shape);
  const std::size_t count = frames == 0 ? shape[0] : std::min<std::size_t>(frames, shape[0]);
  for (std::size_t f = 0; f < count; ++f) {
    const cv::Mat image = frame_image(dir, f);
    ASSERT_FALSE(image.empty()) << dir << " frame " << f;
    const TruthContact truth_now = truth_contact(masks, shape, f);
    ASSERT_TRUE(truth_now.ellipse.has_value()) << dir << " frame " << f;
    for (std::size_t k = 0; k < segmenters.size(); ++k) {
      const ContactResult r = segmenters[k].segment(image);
      ASSERT_TRUE(r.ellipse.has_value()) << dir << " frame " << f << " segmenter " << k;
      if (check) check(f, k, r);
      errors[k].add(r, truth_now, image.size());
    }
  }
}

// Renders samples/scenes/<name>.yaml with two frames and segments both.
void check_scene(const std::string& name, const Tolerance& tolerance,
                 Centre centre = Centre::scene_defaults) {
  fs::path dir;
  render(
      name, name + (centre == Centre::level_edge ? "_level_edge" : ""),
      [](YAML::Node& yaml) { yaml["synthesis"]["timing"]["frames"] = 2; }, &dir);
  if (dir.empty()) return;

  const Scene scene = load_scene((dir / "scene.yaml").string());
  SegmenterOptions options = pipeline::segmenter_options_for(scene);
  if (centre == Centre::level_edge) {
    options.ridge_label_below_periods = 0.0;
    options.ridge_label_centre = false;
  }
  ContactSegmenter segmenter(options);
  H5Reader truth((dir / "truth.h5").string());
  H5Shape shape;
  const auto masks = truth.read_integers("/contact/mask", &shape);
  const double cx = truth.attribute_number("/", "contact_centre_x_px");
  const double cy = truth.attribute_number("/", "contact_centre_y_px");
  const double a1 = truth.attribute_number("/", "contact_semi_axis_1_px");
  const double a2 = truth.attribute_number("/", "contact_semi_axis_2_px");
  const double major_nominal = std::max(a1, a2), minor_nominal = std::min(a1, a2);
  const int height = static_cast<int>(shape[1]), width = static_cast<int>(shape[2]);
  for (std::size_t f = 0; f < shape[0]; ++f) {
    const cv::Mat image = frame_image(dir, f);
    ASSERT_FALSE(image.empty());
    const ContactResult r = segmenter.segment(image);
    const TruthContact truth_now = truth_contact(masks, shape, f);
    const cv::Mat& truth_mask = truth_now.mask;
    const std::optional<Ellipse>& truth_ellipse = truth_now.ellipse;
    ASSERT_TRUE(truth_ellipse.has_value());
    // Both the mask's ellipse and the generator's nominal one are printed.
    const double major = truth_ellipse->semi_major_px, minor = truth_ellipse->semi_minor_px;
    std::cout << "  truth mask ellipse " << truth_ellipse->cx_px << ", " << truth_ellipse->cy_px << ", "
              << major << ", " << minor << " (nominal " << cx << ", " << cy << ", " << major_nominal << ", "
              << minor_nominal << ")\n";
    ASSERT_FALSE(r.hull_px.empty()) << name << " frame " << f;
    ASSERT_TRUE(r.ellipse.has_value());
    const double iou = mask_iou(rasterize_polygon(r.hull_px, {width, height}), truth_mask);
    const double centre_error =
        std::hypot(r.ellipse->cx_px - truth_ellipse->cx_px, r.ellipse->cy_px - truth_ellipse->cy_px);
    const double major_error = r.ellipse->semi_major_px / major - 1.0;
    const double minor_error = r.ellipse->semi_minor_px / minor - 1.0;
    std::cout << "  " << name << " frame " << f << ": status " << contact_status_text(r.status) << ", IoU "
              << iou << ", centre error " << centre_error << " px, axes " << major_error << ", "
              << minor_error << ", texture SNR " << r.texture_snr
              << (r.border_averaged ? " (averaged along the border)" : "")
              << (r.ridge_label_shift_px ? " (centre from the ridge labels)" : "") << "\n";
    EXPECT_EQ(r.border_averaged, tolerance.border_averaged) << name << " texture SNR " << r.texture_snr;
    EXPECT_EQ(r.ridge_label_shift_px.has_value(), tolerance.ridge_labels) << name;
    EXPECT_GE(iou, tolerance.min_iou) << name;
    EXPECT_LE(centre_error, tolerance.centre_px) << name;
    EXPECT_LE(std::abs(major_error), tolerance.axis_relative) << name;
    EXPECT_LE(std::abs(minor_error), tolerance.axis_relative) << name;
    EXPECT_EQ(r.status & (kNoContact | kNoEllipse), 0u);
  }
}

// Issue targets: IoU >= 0.97 on the default scene and >= 0.93 on hard cases with contact; centre <= 1 px and
// axes <= 2 % of the truth's ellipse, asserted at those tolerances on these two frames at rest with the
// segmenter's defaults: the centre from the ridge labels (brackets and the border band's fit on the large
// contacts, the logistic fit on the tiny one), the border band's fit alone on the frames averaged along the
// border. Measured centre errors: default 0.49 / 0.28 px, sweat 0.11 / 0.18, low contrast 0.29 / 0.43, heavy
// noise 0.40 / 0.59, tiny 0.33 / 0.11. Over whole trials, while the skin slides under the contact, some
// sliding frames of other fingerprints exceed 1 px (`tirstrain validate` reports every frame; BENCHMARKS.md,
// contact/).
TEST(SynthAccuracy, DefaultScene) {
  check_scene("default", {0.97, 1.0, 0.02, false, true});
}
TEST(SynthAccuracy, SweatBlobs) {
  check_scene("hard_sweat_blobs", {0.93, 1.0, 0.02, false, true});
}
TEST(SynthAccuracy, LowContrast) {
  check_scene("hard_low_contrast", {0.93, 1.0, 0.02, true, true});
}
TEST(SynthAccuracy, HeavyNoise) {
  check_scene("hard_heavy_noise", {0.93, 1.0, 0.02, true, true});
}
TEST(SynthAccuracy, TinyContact) {
  check_scene("hard_tiny_contact", {0.93, 1.0, 0.02, false, true});
}

// The level edge's centre alone (`segmentation: {ridge_label_centre: false, ridge_label_below_periods: 0}`).
// Where a ridge valley runs along the border the edge is invisible (a valley reflects like the background)
// and the level edge, which works from the crests, stops at the last crest; on a contact two ridge periods
// in radius, which valleys happen to lie along which side moves the centre by about a pixel (measured 1.37
// px on both frames; the default scene 0.35 / 0.12 px). Asserted at those values plus a small margin, so
// that the comparison shows if either changes.
TEST(SynthAccuracy, LevelEdgeCentreAlone) {
  check_scene("default", {0.97, 1.0, 0.02, false, false}, Centre::level_edge);
  check_scene("hard_tiny_contact", {0.93, 1.5, 0.02, false, false}, Centre::level_edge);
}

// While the skin slides: the whole affine_stretch_50 trial (60 frames; the skin under the contact stretched
// by up to 50 % along x), the shipped trial whose sliding frames are the hardest for the centre. Each sector
// of the brackets places the border midway between its inside and outside ridge labels, and counts less
// where they are far apart (contact/ridge_labels.cpp): measured 0.51 px RMS over the frames, 0.98 px at the
// worst; with the border just beyond the inside labels instead, 0.66 / 1.39 px. Asserted at 0.6 and 1.1 px
// so that the two rules are told apart (BENCHMARKS.md, contact/).
TEST(SynthAccuracy, SlidingTrialCentre) {
  fs::path dir;
  render(
      "affine_stretch_50", "affine_stretch_50_all_frames", [](YAML::Node&) {}, &dir);
  if (dir.empty()) return;
  ContactSegmenter segmenter[1] = {
      ContactSegmenter(pipeline::segmenter_options_for(load_scene((dir / "scene.yaml").string())))};
  FrameErrors errors[1];
  measure_frames(dir, 0, segmenter, errors, [](std::size_t f, std::size_t, const ContactResult& r) {
    EXPECT_TRUE(r.ridge_label_shift_px.has_value()) << "frame " << f;
  });
  ASSERT_EQ(errors[0].frames, 60);
  std::cout << "  affine_stretch_50, 60 frames: centre error RMS " << errors[0].centre_rms_px()
            << " px, worst " << errors[0].worst_centre_px << " px\n";
  EXPECT_LE(errors[0].centre_rms_px(), 0.6);
  EXPECT_LE(errors[0].worst_centre_px, 1.1);
}

// Other fingerprints: the default scene with seeds 2, 4 and 6 (ridge flow, minutiae, border irregularity and
// noise differ), 20 frames over the same 0.6 s of loading and slide. The shipped trials all use seed 1, a
// concentric whorl whose valleys run along most of the border; with other seeds ridges end against more of
// it, and the level edge's outline is off by a few px: too large where ridges end (the edge sits on the
// step's foot), too small where valleys run along it, in a pattern of two lobes. The brackets' size (from
// the sectors where ridges end) and shape terms take that out, and their centre is nearer too. Measured over
// the 60 frames, worst semi-axis error: 1.08 % (level edge alone 3.31 %, the brackets' centre alone 3.25 %,
// with the shape terms but the level edge's size 2.75 %); worst IoU 0.972 (level edge 0.951); centre RMS
// 0.67 px (level edge 1.41 px). Asserted at 1.5 %, 0.97 and 0.9 px, which the level edge alone fails on all
// three and the partial rules on the axes (BENCHMARKS.md, contact/).
TEST(SynthAccuracy, ShapeAndCentreOnOtherFingerprints) {
  FrameErrors errors[2];  // the segmenter's defaults, the level edge alone
  for (const int seed : {2, 4, 6}) {
    fs::path dir;
    render(
        "default", "default_seed_" + std::to_string(seed),
        [seed](YAML::Node& scene) {
          scene["synthesis"]["seed"] = seed;
          scene["synthesis"]["timing"]["frames"] = 20;
          scene["synthesis"]["timing"]["frame_rate_hz"] = 100.0 / 3.0;
        },
        &dir);
    if (dir.empty()) return;
    const SegmenterOptions options =
        pipeline::segmenter_options_for(load_scene((dir / "scene.yaml").string()));
    SegmenterOptions level_edge_only = options;
    level_edge_only.ridge_label_centre = false;
    level_edge_only.ridge_label_below_periods = 0.0;
    ContactSegmenter segmenters[2] = {ContactSegmenter(options), ContactSegmenter(level_edge_only)};
    measure_frames(dir, 0, segmenters, errors, [seed](std::size_t f, std::size_t k, const ContactResult& r) {
      EXPECT_EQ(r.ridge_label_shape_px.has_value(), k == 0) << "seed " << seed << " frame " << f;
    });
  }
  std::cout << "  seeds 2, 4, 6, " << errors[0].frames << " frames: semi-axis error RMS "
            << 100.0 * errors[0].axis_rms() << " %, worst " << 100.0 * errors[0].worst_axis
            << " %, worst IoU " << errors[0].worst_iou << ", centre RMS " << errors[0].centre_rms_px()
            << " px; level edge alone " << 100.0 * errors[1].axis_rms() << " / "
            << 100.0 * errors[1].worst_axis << " %, IoU " << errors[1].worst_iou << ", "
            << errors[1].centre_rms_px() << " px\n";
  EXPECT_EQ(errors[0].frames, 60);
  EXPECT_LE(errors[0].worst_axis, 0.015);
  EXPECT_GE(errors[0].worst_iou, 0.97);
  EXPECT_LE(errors[0].centre_rms_px(), 0.9);
  EXPECT_GT(errors[1].worst_axis, 0.015);
  EXPECT_LT(errors[1].worst_iou, 0.97);
  EXPECT_GT(errors[1].centre_rms_px(), 0.9);
}

// The border band's intensity fit (`segmentation: {border_band_centre: true}`, contact/border_band.hpp; on
// by default) on two of the four shipped trials where the balanced preset's centre (the
// band off) has a frame above 1 px, one for each way the fit is used: the elliptical contact (the centre the
// mean of the brackets' and the band fit's) and the heavy-noise one (too noisy for labels: the band fit's
// alone). Over all 60 frames: elliptical_contact without the band 0.78 px RMS, worst 1.10 (frame 1); with
// the band 0.23 / 0.52; hard_heavy_noise without it 0.67 / 1.09 (frame 11), with the band 0.67 / 0.93 (frame
// 23). The trials are rendered whole, as shipped, and their first 30 frames segmented (every worst frame lies
// there). Asserted: with the band every frame within the 1 px; without it some frame above (the
// comparison shows if either changes).
TEST(SynthAccuracy, BorderBandCentre) {
  for (const std::string name : {"elliptical_contact", "hard_heavy_noise"}) {
    fs::path dir;
    render(
        name, name + "_all_frames", [](YAML::Node&) {}, &dir);
    if (dir.empty()) return;
    SegmenterOptions options = pipeline::segmenter_options_for(load_scene((dir / "scene.yaml").string()));
    ASSERT_TRUE(options.border_band_centre);  // the default
    const SegmenterOptions balanced = with_preset(options, SegmentationPreset::balanced);
    ASSERT_FALSE(balanced.border_band_centre);
    ContactSegmenter segmenters[2] = {ContactSegmenter(balanced), ContactSegmenter(options)};
    FrameErrors errors[2];  // without the band, with it
    constexpr std::size_t kFrames = 30;
    measure_frames(dir, kFrames, segmenters, errors,
                   [&](std::size_t f, std::size_t k, const ContactResult& r) {
                     // On the noisy trial the balanced preset leaves the level edge's centre; the band fit
                     // moves it.
                     if (name == "hard_heavy_noise") {
                       EXPECT_EQ(r.ridge_label_shift_px.has_value(), k == 1) << "frame " << f;
                     }
                     EXPECT_EQ(r.border_band_used, k == 1) << name << " frame " << f;
                   });
    std::cout << "  " << name << ", " << kFrames << " frames: centre error RMS / worst "
              << errors[0].centre_rms_px() << " / " << errors[0].worst_centre_px << " px without the band, "
              << errors[1].centre_rms_px() << " / " << errors[1].worst_centre_px
              << " px with the border band\n";
    EXPECT_EQ(errors[1].frames, static_cast<int>(kFrames));
    EXPECT_LE(errors[1].worst_centre_px, 1.0) << name;
    EXPECT_LE(errors[1].centre_rms_px(), 0.8) << name;
    EXPECT_GT(errors[0].worst_centre_px, 1.0) << name;
  }
}

// The tiny contact's shape (SegmenterOptions::ridge_label_shape_weight): the elongation and direction half
// the level edge's, half the logistic fit's. The shipped trial, all 60 frames: the level edge's
// shape alone, worst semi-axis error 2.08 % (frame 43; the minor axis 1.2 % short on average), RMS over
// frames and both axes 0.96 %; the blend 1.70 % and 0.55 %. Asserted: every frame within the 2 % and
// IoU >= 0.93 with the blend, some frame above 2 % without it, and the RMS below 0.7 %.
//
// Its outline (SegmenterOptions::small_contact_ellipse_outline) is the ellipse, as a polygon of the
// ellipse's area: worst IoU 0.970 and mean 0.980 against the traced outline's 0.956 and 0.968, whose lobes
// of a few ridge periods are larger than the contact's departure from its ellipse. Asserted: the ellipse's
// worst IoU at least 0.965 and 0.01 above the traced outline's, its mean at least 0.975, and its area
// exactly the ellipse's.
TEST(SynthAccuracy, TinyContactShapeFromLabelsAndLevelEdge) {
  fs::path dir;
  render(
      "hard_tiny_contact", "hard_tiny_contact_all_frames", [](YAML::Node&) {}, &dir);
  if (dir.empty()) return;
  SegmenterOptions options = pipeline::segmenter_options_for(load_scene((dir / "scene.yaml").string()));
  ASSERT_GT(options.ridge_label_shape_weight, 0.0);
  ASSERT_TRUE(options.small_contact_ellipse_outline);
  const SegmenterOptions blended = options;
  SegmenterOptions traced = options;
  traced.small_contact_ellipse_outline = false;
  options.ridge_label_shape_weight = 0.0;
  ContactSegmenter segmenters[3] = {ContactSegmenter(options), ContactSegmenter(blended),
                                    ContactSegmenter(traced)};
  FrameErrors errors[3];  // the level edge's shape, blended, blended with the traced outline
  measure_frames(dir, 0, segmenters, errors, [](std::size_t f, std::size_t k, const ContactResult& r) {
    EXPECT_TRUE(r.ridge_label_shift_px.has_value()) << "frame " << f;
    if (k == 1) {
      const Ellipse& e = *r.ellipse;
      EXPECT_NEAR(polygon_area_px2(r.hull_px) / (std::numbers::pi * e.semi_major_px * e.semi_minor_px), 1.0,
                  1e-9)
          << "frame " << f;
    }
  });
  std::cout << "  tiny contact, " << errors[1].frames << " frames: semi-axis error RMS / worst "
            << 100.0 * errors[0].axis_rms() << " / " << 100.0 * errors[0].worst_axis
            << " % with the level edge's shape, " << 100.0 * errors[1].axis_rms() << " / "
            << 100.0 * errors[1].worst_axis << " % blended; worst IoU " << errors[0].worst_iou << ", "
            << errors[1].worst_iou << "; outline from the ellipse: worst / mean IoU " << errors[1].worst_iou
            << " / " << errors[1].mean_iou() << ", traced " << errors[2].worst_iou << " / "
            << errors[2].mean_iou() << "\n";
  EXPECT_EQ(errors[1].frames, 60);
  EXPECT_LE(errors[1].worst_axis, 0.02);
  EXPECT_LE(errors[1].axis_rms(), 0.007);
  EXPECT_GE(errors[1].worst_iou, 0.93);
  EXPECT_GT(errors[0].worst_axis, 0.02);
  EXPECT_GE(errors[1].worst_iou, 0.965);
  EXPECT_GE(errors[1].worst_iou, errors[2].worst_iou + 0.01);
  EXPECT_GE(errors[1].mean_iou(), 0.975);
}

// The same tiny contact (same truth mask) with the fingerprint's core at the contact's centre and well
// outside it: the ridge phase along the border decides the outline where a valley lies along it, so the
// centre is good when ridges cross the border and several pixels off when they run around it (BENCHMARKS.md,
// contact/; measured 3.66 / 3.54 px and 0.39 / 0.37 px, IoU 0.88 and 0.96). Known limit, asserted
// at the measured values so that a change either way shows.
//
// With the centre from the ridge labels (the default on a contact this small), the placement with the core
// outside comes within the 1 px and the one with the core at the centre within 1.6 px: ridge ends
// pin the centre where the crests do not. 1.6 px is what that frame itself allows: its centre can move by
// 1.59 px without changing which pixels show a ridge at 2 noise sigmas (ContactObservability.
// CoreUnderTheContactLeavesTheCentreOpen; measured 1.29 / 1.06 px, and 0.35 / 0.23 px with the core outside).
TEST(SynthAccuracy, TinyContactCentreDependsOnWhereTheFingerprintLies) {
  for (const auto& [core, low_px, high_px, labelled_max_px] :
       {std::tuple{std::vector<double>{0.0, 0.0}, 3.0, 4.2, 1.6},
        std::tuple{std::vector<double>{1.5, 1.0}, 0.0, 0.6, 1.0}}) {
    fs::path dir;
    render(
        "hard_tiny_contact", "tiny_core_" + std::to_string(core[0]),
        [&](YAML::Node& yaml) {
          yaml["synthesis"]["timing"]["frames"] = 2;
          yaml["synthesis"]["fingerprint"]["core_offset_mm"] = core;
        },
        &dir);
    if (dir.empty()) return;
    SegmenterOptions options = pipeline::segmenter_options_for(load_scene((dir / "scene.yaml").string()));
    ContactSegmenter with_ridge_labels(options);
    options.ridge_label_below_periods = 0.0;
    options.ridge_label_centre = false;
    ContactSegmenter segmenter(options);
    H5Reader truth((dir / "truth.h5").string());
    H5Shape shape;
    const auto masks = truth.read_integers("/contact/mask", &shape);
    const std::optional<Ellipse> truth_ellipse = truth_contact(masks, shape, 0).ellipse;
    ASSERT_TRUE(truth_ellipse.has_value());
    const auto centre_error = [&](const ContactResult& r) {
      return std::hypot(r.ellipse->cx_px - truth_ellipse->cx_px, r.ellipse->cy_px - truth_ellipse->cy_px);
    };
    for (std::size_t f = 0; f < 2; ++f) {
      const cv::Mat image = frame_image(dir, f);
      const ContactResult r = segmenter.segment(image);
      const ContactResult labelled = with_ridge_labels.segment(image);
      ASSERT_TRUE(r.ellipse.has_value());
      ASSERT_TRUE(labelled.ellipse.has_value());
      const double centre_px = centre_error(r), labelled_px = centre_error(labelled);
      std::cout << "  core at (" << core[0] << ", " << core[1] << ") mm, frame " << f << ": centre error "
                << centre_px << " px, " << labelled_px << " px from the ridge labels\n";
      EXPECT_GE(centre_px, low_px);
      EXPECT_LE(centre_px, high_px);
      EXPECT_LE(labelled_px, labelled_max_px);
      // The labels move the outline and blend its elongation; its mean semi-axis stays the level edge's.
      EXPECT_NEAR(labelled.ellipse->semi_major_px + labelled.ellipse->semi_minor_px,
                  r.ellipse->semi_major_px + r.ellipse->semi_minor_px, 1e-9);
      EXPECT_NEAR(labelled.area_mm2 / r.area_mm2, 1.0, 0.005);
    }
  }
}

// The border averaging on a contact two ridge periods in radius, where its band reaches most of the way to
// the centre (forced here: the tiny scene's SNR of 35 does not call for it). Every sample finite, the ellipse
// within 1.5 px and 4 % of the nominal contact (measured: centre 1.10 / 1.24 px, axes +0.4 to +2.4 %).
TEST(SynthAccuracy, BorderAveragingOnATinyContact) {
  fs::path dir;
  render(
      "hard_tiny_contact", "tiny_averaged",
      [](YAML::Node& yaml) { yaml["synthesis"]["timing"]["frames"] = 2; }, &dir);
  if (dir.empty()) return;
  SegmenterOptions options = pipeline::segmenter_options_for(load_scene((dir / "scene.yaml").string()));
  options.border_average_snr = 1e12;
  ContactSegmenter segmenter(options);
  H5Reader truth((dir / "truth.h5").string());
  const double cx = truth.attribute_number("/", "contact_centre_x_px");
  const double cy = truth.attribute_number("/", "contact_centre_y_px");
  const double radius = truth.attribute_number("/", "contact_semi_axis_1_px");
  for (std::size_t f = 0; f < 2; ++f) {
    const cv::Mat image = frame_image(dir, f);
    ASSERT_FALSE(image.empty());
    const ContactResult r = segmenter.segment(image);
    EXPECT_TRUE(r.border_averaged);
    ASSERT_TRUE(r.ellipse.has_value());
    for (const auto& p : r.hull_px) ASSERT_TRUE(std::isfinite(p.x) && std::isfinite(p.y));
    const double centre_px = std::hypot(r.ellipse->cx_px - cx, r.ellipse->cy_px - cy);
    std::cout << "  tiny contact, averaged: centre " << centre_px << " px from the nominal, axes "
              << r.ellipse->semi_major_px / radius - 1.0 << ", " << r.ellipse->semi_minor_px / radius - 1.0
              << "\n";
    EXPECT_LE(centre_px, 1.5);
    EXPECT_NEAR(r.ellipse->semi_major_px / radius, 1.0, 0.04);
    EXPECT_NEAR(r.ellipse->semi_minor_px / radius, 1.0, 0.04);
  }
}

// The outline must not depend on the light's shape. The low-contrast scene, noise-free and in 16 bits so
// that only the illumination differs, rendered with flat light and with strong vignetting (30 % at the
// corners): with the flat field the two ellipses agree; without it the vignetted one is measured smaller
// (grey closing flattens the background that rises outward beside the contact, so the edge level is
// reached too early). On the balanced preset: the border band's fit (on by default) moves its centre by up to
// 0.4 px between any two renders that differ a little, not steadily with the light (band fit alone, flat
// light to 30 % vignetting in steps of 5 %: x 319.41, 319.57, 319.17, 319.43, 319.31, 319.29, 319.06 px);
// that is its scatter, not a dependence on the light. With it, both centres are asserted against
// the truth's instead.
TEST(SynthAccuracy, OutlineDoesNotDependOnVignetting) {
  const auto edit = [](double vignetting) {
    return [vignetting](YAML::Node& yaml) {
      yaml["synthesis"]["timing"]["frames"] = 1;
      yaml["synthesis"]["image"]["bit_depth"] = 16;
      yaml["synthesis"]["sensor"]["full_well_electrons"] = 1e9;
      yaml["synthesis"]["sensor"]["read_noise"] = 0.0;
      yaml["synthesis"]["sensor"]["drift"] = 0.0;
      yaml["synthesis"]["fingerprint"]["vignetting"] = vignetting;
    };
  };
  fs::path flat_dir, vignetted_dir;
  render("hard_low_contrast", "vignetting_0", edit(0.0), &flat_dir);
  render("hard_low_contrast", "vignetting_30", edit(0.3), &vignetted_dir);
  if (flat_dir.empty() || vignetted_dir.empty()) return;
  const cv::Mat flat_image = frame_image(flat_dir, 0), vignetted_image = frame_image(vignetted_dir, 0);
  ASSERT_FALSE(flat_image.empty());
  ASSERT_FALSE(vignetted_image.empty());
  const Scene scene = load_scene((flat_dir / "scene.yaml").string());
  for (const bool flat_field : {true, false}) {
    SegmenterOptions options =
        with_preset(pipeline::segmenter_options_for(scene), SegmentationPreset::balanced);
    options.flat_field = flat_field;
    const ContactResult flat = ContactSegmenter(options).segment(flat_image);
    const ContactResult vignetted = ContactSegmenter(options).segment(vignetted_image);
    ASSERT_TRUE(flat.ellipse.has_value());
    ASSERT_TRUE(vignetted.ellipse.has_value());
    const double centre_px = std::hypot(vignetted.ellipse->cx_px - flat.ellipse->cx_px,
                                        vignetted.ellipse->cy_px - flat.ellipse->cy_px);
    const double major = vignetted.ellipse->semi_major_px / flat.ellipse->semi_major_px - 1.0;
    const double minor = vignetted.ellipse->semi_minor_px / flat.ellipse->semi_minor_px - 1.0;
    std::cout << "  flat field " << (flat_field ? "on" : "off") << ": vignetted - flat light: centre "
              << centre_px << " px, axes " << major << ", " << minor << "\n";
    if (flat_field) {
      EXPECT_LE(centre_px, 0.2);
      EXPECT_LE(std::abs(major), 0.002);
      EXPECT_LE(std::abs(minor), 0.002);
    } else {
      // The effect the flat field removes is there to be removed (the test can fail).
      EXPECT_GT(std::max(std::abs(major), std::abs(minor)), 0.01);
    }
  }
  H5Reader truth((flat_dir / "truth.h5").string());
  H5Shape shape;
  const std::optional<Ellipse> truth_ellipse =
      truth_contact(truth.read_integers("/contact/mask", &shape), shape, 0).ellipse;
  ASSERT_TRUE(truth_ellipse.has_value());
  const SegmenterOptions accurate = pipeline::segmenter_options_for(scene);
  ASSERT_TRUE(accurate.border_band_centre);
  for (const cv::Mat& image : {flat_image, vignetted_image}) {
    const ContactResult r = ContactSegmenter(accurate).segment(image);
    ASSERT_TRUE(r.ellipse.has_value());
    EXPECT_TRUE(r.border_band_used);
    const double centre_px =
        std::hypot(r.ellipse->cx_px - truth_ellipse->cx_px, r.ellipse->cy_px - truth_ellipse->cy_px);
    std::cout << "  border band on: centre " << centre_px << " px from the truth's\n";
    EXPECT_LE(centre_px, 0.3);
  }
}

// The scene's `segmentation:` keys reach the segmenter; a value out of range names the key.
TEST(SynthAccuracy, SegmentationSceneKeys) {
  const fs::path dir = fs::path(TIRSTRAIN_TEST_TMP) / "contact_synth";
  fs::create_directories(dir);
  const fs::path path = dir / "segmentation_keys.yaml";
  std::ofstream(path)
      << "calibration: {px_per_mm: 52}\n"
         "segmentation: {downsample: 2, flat_field: false, border_average_snr: 0, "
         "ridge_label_centre: false, ridge_label_below_periods: 0, ridge_label_shape_weight: 0.25, "
         "border_band_centre: true}\n";
  const SegmenterOptions options = pipeline::segmenter_options_for(load_scene(path.string()));
  EXPECT_EQ(options.downsample, 2);
  EXPECT_FALSE(options.flat_field);
  EXPECT_EQ(options.border_average_snr, 0.0);
  EXPECT_FALSE(options.ridge_label_centre);
  EXPECT_EQ(options.ridge_label_below_periods, 0.0);
  EXPECT_EQ(options.ridge_label_shape_weight, 0.25);
  EXPECT_TRUE(options.border_band_centre);
  const SegmenterOptions defaults = pipeline::segmenter_options_for(
      load_scene((fs::path(TIRSTRAIN_SOURCE_DIR) / "samples/scenes/default.yaml").string()));
  EXPECT_TRUE(defaults.flat_field);
  EXPECT_EQ(defaults.border_average_snr, 20.0);
  EXPECT_TRUE(defaults.ridge_label_centre);
  EXPECT_EQ(defaults.ridge_label_below_periods, 5.0);
  EXPECT_EQ(defaults.ridge_label_shape_weight, 0.5);
  EXPECT_TRUE(defaults.border_band_centre);
  // A preset sets the switches; keys set beside it override them one by one.
  std::ofstream(path) << "calibration: {px_per_mm: 52}\nsegmentation: {preset: fast}\n";
  const SegmenterOptions fast = pipeline::segmenter_options_for(load_scene(path.string()));
  EXPECT_FALSE(fast.flat_field);
  EXPECT_EQ(fast.border_average_snr, 0.0);
  EXPECT_FALSE(fast.ridge_label_centre);
  EXPECT_EQ(fast.ridge_label_below_periods, 0.0);
  EXPECT_FALSE(fast.border_band_centre);
  std::ofstream(path)
      << "calibration: {px_per_mm: 52}\nsegmentation: {preset: balanced, flat_field: false}\n";
  const SegmenterOptions balanced = pipeline::segmenter_options_for(load_scene(path.string()));
  EXPECT_FALSE(balanced.border_band_centre);
  EXPECT_TRUE(balanced.ridge_label_centre);
  EXPECT_EQ(balanced.ridge_label_below_periods, 5.0);
  EXPECT_FALSE(balanced.flat_field);
  // An out-of-range value is refused, and the message names the key.
  for (const auto& [key, value] :
       {std::pair{"border_average_snr", "-1"}, std::pair{"ridge_label_shape_weight", "1.5"},
        std::pair{"preset", "quick"}}) {
    std::ofstream(path) << "calibration: {px_per_mm: 52}\nsegmentation: {" << key << ": " << value << "}\n";
    try {
      pipeline::segmenter_options_for(load_scene(path.string()));
      ADD_FAILURE() << key << ": " << value << " was accepted";
    } catch (const std::exception& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace tirstrain::contact
