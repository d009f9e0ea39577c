// The tracking and strain stages of `tirstrain process` on synthesised trials with exact truth, through
// `tirstrain validate`'s comparison: datasets and shapes, strain against an affine field, the compressed
// side of a Cattaneo–Mindlin contact facing the plate's motion for the four stimulus directions.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <nlohmann/json.hpp>

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <numbers>
#include <optional>
#include <string>

#include <opencv2/imgproc.hpp>

#include "contact/ellipse.hpp"
#include "contact/geometry.hpp"
#include "core/error.hpp"
#include "core/h5_file.hpp"
#include "core/scene.hpp"
#include "core/tensor2.hpp"
#include "pipeline/process.hpp"
#include "pipeline/validate.hpp"
#include "samples/synth.hpp"
#include "samples/synth_config.hpp"
#include "samples/trial.hpp"
#include "strain/deformation.hpp"
#include "tests/support/scratch.hpp"

namespace tirstrain {
namespace {

namespace fs = std::filesystem;

fs::path scratch(const std::string& name) {
  return testing::scratch_dir("strain_pipeline", name);
}

// A small noise-free trial: by default a Hertz contact with R = 5 mm (a = 1.83 mm, 95 px) in a 288x256
// image.
std::string scene_yaml(const std::string& loading, int frames, int size_px = 288, double radius_m = 0.005) {
  return "calibration: {px_per_mm: 52, ridge_period_mm: 0.45, ridge_polarity: dark}\n"
         "compute: [contact, tracking, strain]\n"
         "synthesis:\n"
         "  seed: 3\n"
         "  image: {width_px: " +
         std::to_string(size_px) + ", height_px: " + std::to_string(size_px - 32) +
         ", bit_depth: 8}\n"
         "  timing: {frames: " +
         std::to_string(frames) +
         ", frame_rate_hz: 100, jitter_s: 0}\n"
         "  contact: {shape: hertz, normal_N: 2.0, radius_m: " +
         std::to_string(radius_m) +
         "}\n"
         "  loading: " +
         loading +
         "\n"
         "  sensor: {full_well_electrons: 0, read_noise: 0, blur_sigma_px: 0, drift: 0}\n";
}

// Writes the scene, synthesises the trial and processes it; returns the validation.
pipeline::ValidationReport synthesise_and_validate(const std::string& name, const std::string& yaml) {
  const fs::path dir = scratch(name);
  fs::create_directories(dir);
  const fs::path scene = dir / "scene_in.yaml";
  {
    std::ofstream out(scene);
    out << yaml;
  }
  pipeline::ValidateOptions o;
  o.scene_path = scene.string();
  o.out_dir = (dir / "validation").string();
  o.quiet = true;
  return pipeline::run_validate(o);
}

TEST(StrainPipeline, AffineFieldDatasetsAndAccuracy) {
  // 10 % stretch along x, 4 % compression along y and shear, ramped over 6 frames.
  const pipeline::ValidationReport report = synthesise_and_validate(
      "affine", scene_yaml("{field: affine, gradient: [0.10, 0.03, -0.02, -0.04]}", 6));
  const H5Reader h5((fs::path(report.result_dir) / "result.h5").string());
  const std::size_t n = 6;
  const H5Shape positions = h5.shape("/tracks/position_px");
  ASSERT_EQ(positions.size(), 3u);
  EXPECT_EQ(positions[0], n);
  EXPECT_EQ(positions[2], 2u);
  const std::size_t k = positions[1];
  EXPECT_GT(k, 100u);
  EXPECT_EQ(h5.shape("/tracks/reference_px"), (H5Shape{k, 2}));
  EXPECT_EQ(h5.shape("/tracks/status"), (H5Shape{n, k}));
  EXPECT_EQ(h5.shape("/plate/displacement_px"), (H5Shape{n, 2}));
  const H5Shape triangles = h5.shape("/mesh/triangles");
  const std::size_t t = triangles[0];
  EXPECT_GT(t, 150u);
  for (const char* name : {"/strain/total", "/strain/total_incremental", "/strain/rate", "/strain/principal"})
    EXPECT_EQ(h5.shape(name), (H5Shape{n, t, 3})) << name;
  EXPECT_EQ(h5.shape("/strain/rotation_rad"), (H5Shape{n, t}));
  EXPECT_EQ(h5.shape("/energy/density_J_m3"), (H5Shape{n, t}));
  EXPECT_EQ(h5.shape("/energy/total_J"), (H5Shape{n}));
  EXPECT_EQ(h5.shape("/stick/ratio"), (H5Shape{n}));
  EXPECT_EQ(h5.shape("/maps/strain_total"), (H5Shape{n, 65, 65, 3}));
  EXPECT_EQ(h5.attribute_text("/strain", "mode"), "exact");

  // Every triangle index points at a track; the reference frame has zero strain.
  const std::vector<std::int64_t> mesh = h5.read_integers("/mesh/triangles");
  for (const std::int64_t v : mesh) ASSERT_TRUE(v >= 0 && static_cast<std::size_t>(v) < k);
  const std::vector<double> total = h5.read_doubles("/strain/total");
  for (std::size_t i = 0; i < t * 3; ++i) {
    if (std::isfinite(total[i])) {
      ASSERT_NEAR(total[i], 0.0, 1e-12);
    }
  }

  // Against the exact field (interior, triangle reference: tracking error only), printed below. Measured on
  // this noise-free trial: E_xx 0.0040, E_yy 0.0023, E_xy 0.0015 RMS, interior displacement 0.033 px RMS,
  // U within 2.4 %. Asserted at the 0.005 per component with a margin for E_xx; the displacement and
  // U bounds are the measured values with a margin.
  for (const auto& row : report.rows) {
    if (row.reference != "triangle" && row.reference != "tracks" && row.reference != "same triangles")
      continue;
    std::printf("  %-22s %-15s %-12s rms %.4g max %.4g (n = %ld)\n", row.quantity.c_str(),
                row.reference.c_str(), row.mode.c_str(), row.rms, row.max_abs, row.samples);
  }
  for (const char* component : {"E_xx", "E_yy", "E_xy"}) {
    const pipeline::ErrorStats* exact = report.find(component, "triangle", "exact");
    ASSERT_NE(exact, nullptr);
    EXPECT_GT(exact->samples, 500);
    EXPECT_LT(exact->rms, 0.0055) << component;
  }
  EXPECT_LT(report.find("displacement_interior", "tracks")->rms, 0.05);
  // The displacement by depth inside the border: every live track-frame in exactly one band.
  long by_depth = 0;
  for (const char* band :
       {"displacement_border_0-0.5mm", "displacement_border_0.5-1mm", "displacement_beyond_1mm"}) {
    const pipeline::ErrorStats* row = report.find(band, "tracks");
    ASSERT_NE(row, nullptr) << band;
    by_depth += row->samples;
  }
  EXPECT_EQ(by_depth, report.find("displacement", "tracks")->samples);
  EXPECT_LT(std::abs(report.find("U", "same triangles", "exact")->mean), 3.0);  // %
  // U of the other mode, side by side: the incremental sum is the smaller strain here (its E_xx lags the
  // exact one by the definition, below), so its U is lower.
  const pipeline::ErrorStats* u_incremental = report.find("U", "same triangles", "incremental");
  ASSERT_NE(u_incremental, nullptr);
  EXPECT_GE(u_incremental->samples, 4);
  EXPECT_LT(u_incremental->mean, report.find("U", "same triangles", "exact")->mean);
  // Against the energy of the same running sum on the exact positions, the incremental mode's U is as close
  // as the exact mode's is to its truth.
  const pipeline::ErrorStats* u_increments = report.find("U", "truth increments", "incremental");
  ASSERT_NE(u_increments, nullptr);
  EXPECT_GE(u_increments->samples, 4);
  EXPECT_LT(std::abs(u_increments->mean), 3.0);  // %

  // The paper's incremental mode. Its measurement error, against the same running sum of increments taken
  // on the exact vertex positions, is the exact mode's (measured 0.0037, 0.0023, 0.0015). That sum itself
  // differs from the exact Green–Lagrange strain by the definition alone; for this homogeneous linear ramp
  // F_i = I + (i/5) H the difference is the same on every triangle and computed here in closed form.
  const Gradient2 h_last{0.10, 0.03, -0.02, -0.04};
  const auto ramp = [&](double r) {
    return Gradient2{r * h_last.xx, r * h_last.xy, r * h_last.yx, r * h_last.yy};
  };
  double difference_sq[3] = {0, 0, 0};
  Strain2 sum;
  for (int i = 1; i < 6; ++i) {
    const Strain2 inc = green_lagrange(strain::incremental_gradient(ramp(i / 5.0), ramp((i - 1) / 5.0)));
    sum = {sum.xx + inc.xx, sum.yy + inc.yy, sum.xy + inc.xy};
    const Strain2 exact = green_lagrange(ramp(i / 5.0));
    difference_sq[0] += (sum.xx - exact.xx) * (sum.xx - exact.xx) / 6.0;
    difference_sq[1] += (sum.yy - exact.yy) * (sum.yy - exact.yy) / 6.0;
    difference_sq[2] += (sum.xy - exact.xy) * (sum.xy - exact.xy) / 6.0;
  }
  int c = 0;
  for (const char* component : {"E_xx", "E_yy", "E_xy"}) {
    const pipeline::ErrorStats* measured = report.find(component, "truth increments", "incremental");
    const pipeline::ErrorStats* definition = report.find(component, "point", "incremental of truth");
    ASSERT_NE(measured, nullptr);
    ASSERT_NE(definition, nullptr);
    EXPECT_GT(measured->samples, 500);
    EXPECT_LT(measured->rms, 0.0055) << component;
    // A triangle that joins the mesh after frame 0 starts its sum at its exact total, so it carries less of
    // the difference: the closed form (every triangle from frame 0) is an upper bound. Measured 9-10 % below.
    const double expected = std::sqrt(difference_sq[c++]);
    std::printf(
        "  %s: incremental sum of the exact positions minus exact strain %.5f RMS (closed form %.5f)\n",
        component, definition->rms, expected);
    EXPECT_LT(definition->rms, 1.02 * expected) << component;
    EXPECT_GT(definition->rms, 0.8 * expected) << component;
  }

  // The contact rows, recomputed here from result.h5 and truth.h5: per frame the hull filled against the
  // truth mask, and the ellipse against the direct fit of the mask's outline (pixel-centre outline, so the
  // semi-axes get half a pixel back).
  const H5Reader truth((fs::path(report.result_dir).parent_path() / "trial" / "truth.h5").string());
  H5Shape mask_shape;
  const std::vector<std::int64_t> masks = truth.read_integers("/contact/mask", &mask_shape);
  ASSERT_EQ(mask_shape.size(), 3u);
  const int rows = static_cast<int>(mask_shape[1]), cols = static_cast<int>(mask_shape[2]);
  const std::vector<double> hull = h5.read_doubles("/contact/hull_px");
  const std::vector<double> ellipses = h5.read_doubles("/contact/ellipse");
  double iou_deficit_sum = 0.0, centre_sq = 0.0, minor_sq = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    cv::Mat mask(rows, cols, CV_8UC1);
    for (int p = 0; p < rows * cols; ++p)
      mask.data[p] = masks[i * static_cast<std::size_t>(rows * cols) + static_cast<std::size_t>(p)] ? 255 : 0;
    std::vector<std::vector<cv::Point>> contours;
    cv::findContours(mask.clone(), contours, cv::RETR_EXTERNAL, cv::CHAIN_APPROX_NONE);
    std::vector<cv::Point2d> outline, polygon;
    for (const auto& contour : contours)
      for (const auto& p : contour) outline.emplace_back(p.x, p.y);
    const std::optional<contact::Ellipse> fit = contact::fit_ellipse_direct(outline);
    ASSERT_TRUE(fit.has_value());
    for (std::size_t p = 0; p < 50; ++p)
      polygon.emplace_back(hull[(i * 50 + p) * 2], hull[(i * 50 + p) * 2 + 1]);
    iou_deficit_sum += 1.0 - contact::mask_iou(contact::rasterize_polygon(polygon, mask.size()), mask);
    const double* e = &ellipses[i * 5];
    centre_sq += std::pow(std::hypot(e[0] - fit->cx_px, e[1] - fit->cy_px), 2);
    minor_sq += std::pow(100.0 * (e[3] / (fit->semi_minor_px + 0.5) - 1.0), 2);
  }
  const pipeline::ErrorStats* iou = report.find("contact_1-IoU", "truth mask");
  const pipeline::ErrorStats* centre = report.find("contact_centre", "truth ellipse");
  const pipeline::ErrorStats* minor = report.find("contact_semi_minor", "truth ellipse");
  ASSERT_NE(iou, nullptr);
  ASSERT_NE(centre, nullptr);
  ASSERT_NE(minor, nullptr);
  ASSERT_NE(report.find("contact_semi_major", "truth ellipse"), nullptr);
  ASSERT_NE(report.find("contact_area", "truth mask"), nullptr);
  EXPECT_EQ(centre->samples, static_cast<long>(n));
  EXPECT_NEAR(iou->mean, iou_deficit_sum / static_cast<double>(n), 1e-12);
  EXPECT_NEAR(centre->rms, std::sqrt(centre_sq / static_cast<double>(n)), 1e-9);
  EXPECT_NEAR(minor->rms, std::sqrt(minor_sq / static_cast<double>(n)), 1e-9);
  // The contact itself, at its measured values with a margin (a regression fails). Measured: 1 - IoU 0.029 to
  // 0.046, centre 1.4 to 3.3 px (frame 3), semi-axes within 2.0 %. Not the 1 px: the flat field is
  // not used on this 288x256 frame (too little background around the contact), and as the ridges stretch
  // over the fixed contact, valleys come to lie along other parts of its border (BENCHMARKS.md, contact/).
  std::printf("  contact: 1 - IoU %.4f max, centre %.3f px RMS (max %.3f), semi-minor %.2f %% RMS\n",
              iou->max_abs, centre->rms, centre->max_abs, minor->rms);
  EXPECT_LT(iou->max_abs, 0.05);
  EXPECT_LT(centre->max_abs, 3.6);
  EXPECT_LT(minor->max_abs, 2.2);

  // A result whose /contact/ellipse lacks a frame's row is refused, naming the file.
  const fs::path bad = fs::path(report.result_dir).parent_path() / "result_short_ellipse";
  fs::remove_all(bad);
  fs::copy(report.result_dir, bad, fs::copy_options::recursive);
  {
    H5::H5File file((bad / "result.h5").string(), H5F_ACC_RDWR);
    file.unlink("/contact/ellipse");
    const hsize_t dims[2] = {n - 1, 5};
    const std::vector<double> rows(static_cast<std::size_t>((n - 1) * 5), 1.0);
    file.createDataSet("/contact/ellipse", H5::PredType::NATIVE_DOUBLE, H5::DataSpace(2, dims))
        .write(rows.data(), H5::PredType::NATIVE_DOUBLE);
  }
  pipeline::ValidateOptions o;
  o.trial_dir = (fs::path(report.result_dir).parent_path() / "trial").string();
  o.result_dir = bad.string();
  o.out_dir = (bad.parent_path() / "validation_short_ellipse").string();
  o.quiet = true;
  o.write_maps = false;
  try {
    pipeline::run_validate(o);
    ADD_FAILURE() << "a result with a missing ellipse row was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("/contact"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("result.h5"), std::string::npos) << e.what();
  }
}

// The leading edge (towards the plate's motion) is compressed along the motion, the trailing edge stretched.
TEST(StrainPipeline, CompressedSideLeadsInEachDirection) {
  for (const int direction_deg : {0, 90, 180, 270}) {
    const std::string loading =
        "{field: cattaneo_mindlin, friction: 1.0, direction_deg: " + std::to_string(direction_deg) +
        ", plate_speed_mm_s: 10.0, shear_start_s: 0.0}";
    // R = 20 mm: a = 2.9 mm (152 px), as the default scene; by the last frame c/a is about 0.4, so the slip
    // annulus reaches well inside the tracked region.
    const pipeline::ValidationReport report = synthesise_and_validate(
        "direction_" + std::to_string(direction_deg), scene_yaml(loading, 6, 352, 0.02));
    const H5Reader h5((fs::path(report.result_dir) / "result.h5").string());
    const std::vector<double> reference = h5.read_doubles("/tracks/reference_px");
    const std::vector<std::int64_t> mesh = h5.read_integers("/mesh/triangles");
    H5Shape shape;
    const std::vector<double> total = h5.read_doubles("/strain/total", &shape);
    const std::size_t n = shape[0], t_count = shape[1];
    const double d = direction_deg * std::numbers::pi / 180.0;
    const double dx = std::cos(d), dy = std::sin(d);
    const double cx = 175.5, cy = 159.5, a_px = 152.0;  // contact centre = image centre
    double leading = 0.0, trailing = 0.0;
    int n_leading = 0, n_trailing = 0;
    const std::size_t last = n - 1;
    for (std::size_t tri = 0; tri < t_count; ++tri) {
      const double* e = &total[(last * t_count + tri) * 3];
      if (!std::isfinite(e[0])) continue;
      double x = 0.0, y = 0.0;
      for (int v = 0; v < 3; ++v) {
        const auto id = static_cast<std::size_t>(mesh[tri * 3 + static_cast<std::size_t>(v)]);
        x += reference[2 * id] / 3.0;
        y += reference[2 * id + 1] / 3.0;
      }
      const double along = ((x - cx) * dx + (y - cy) * dy) / a_px;
      const double e_dd = e[0] * dx * dx + e[1] * dy * dy + 2.0 * e[2] * dx * dy;
      if (along > 0.3) {
        leading += e_dd;
        ++n_leading;
      } else if (along < -0.3) {
        trailing += e_dd;
        ++n_trailing;
      }
    }
    ASSERT_GT(n_leading, 20) << direction_deg;
    ASSERT_GT(n_trailing, 20) << direction_deg;
    leading /= n_leading;
    trailing /= n_trailing;
    std::printf("  direction %3d deg: mean strain along the motion, leading %.4f, trailing %.4f\n",
                direction_deg, leading, trailing);
    // Measured: about -0.064 leading and +0.08 to +0.09 trailing in every direction.
    EXPECT_LT(leading, -0.03) << direction_deg;
    EXPECT_GT(trailing, 0.03) << direction_deg;

    // Stick radius: the Cattaneo–Mindlin slip-profile fit against the model's c on the frames with
    // 0.2 a < c < a − 0.6 mm (measured 1.5-4.4 %), and c = a (no detectable slip) on the reference frame.
    const pipeline::ErrorStats* c_fit = report.find("stick_radius_c", "model");
    ASSERT_NE(c_fit, nullptr);
    ASSERT_GE(c_fit->samples, 2) << direction_deg;
    std::printf("  direction %3d deg: stick radius error %.2f %% RMS over %ld frames\n", direction_deg,
                c_fit->rms, c_fit->samples);
    EXPECT_LT(c_fit->rms, 5.0) << direction_deg;
    const std::vector<double> radius_mm = h5.read_doubles("/stick/radius_mm");
    const std::vector<std::int64_t> status = h5.read_integers("/stick/radius_status");
    EXPECT_EQ(status[0], 1) << direction_deg;  // no tangential load yet: c = a
    EXPECT_NEAR(radius_mm[0], 2.93, 0.06) << direction_deg;
    // c is a number wherever it is measured; where the core moved but no slip shows within the tracks it is
    // NaN (not c = a), and the tracks' reach says how far they saw.
    const std::vector<double> reach = h5.read_doubles("/stick/tracks_reach_ratio");
    for (std::size_t i = 0; i < n; ++i) {
      EXPECT_EQ(std::isfinite(radius_mm[i]), status[i] != 3) << i;
      if (status[i] == 3) {
        EXPECT_TRUE(reach[i] > 0.5 && reach[i] < 0.95) << i;
      }
    }
  }
}

// Full slip (c → 0): the plate outruns the Mindlin limit (0.58 mm) after the first frame; the fitted c is 0,
// not NaN.
// Coverage and accuracy by ring of the true contact, and the predicted uncertainties' calibration, on a
// small noise-free Cattaneo–Mindlin trial (a = 152 px, 6 frames, the plate moving distally).
TEST(StrainPipeline, CoverageAndAccuracyByRingOfTheContact) {
  // With the default scene's sensor (shot and read noise, blur): the predicted SDs are noise predictions.
  std::string yaml = scene_yaml(
      "{field: cattaneo_mindlin, friction: 1.0, direction_deg: 270, plate_speed_mm_s: 10.0, shear_start_s: "
      "0.0}",
      6, 352, 0.02);
  const std::string noise_free =
      "sensor: {full_well_electrons: 0, read_noise: 0, blur_sigma_px: 0, drift: 0}";
  yaml.replace(yaml.find(noise_free), noise_free.size(),
               "sensor: {full_well_electrons: 8000, read_noise: 0.006, blur_sigma_px: 0.6, drift: 0}");
  const pipeline::ValidationReport report = synthesise_and_validate("rings", yaml);
  const auto row = [&](const std::string& quantity) {
    const pipeline::ErrorStats* r =
        report.find(quantity, quantity.rfind("coverage", 0) == 0          ? "truth mask"
                              : quantity.find("_z_") != std::string::npos ? "predicted sd"
                              : quantity.rfind("displacement", 0) == 0    ? "tracks"
                                                                          : "point");
    EXPECT_NE(r, nullptr) << quantity;
    return r ? *r : pipeline::ErrorStats{};
  };
  for (const pipeline::ErrorStats& r : report.rows)
    if (r.quantity.find("ring") != std::string::npos || r.quantity.rfind("coverage", 0) == 0)
      std::printf("  %-32s rms %.4g mean %.4g max %.4g (n = %ld)\n", r.quantity.c_str(), r.rms, r.mean,
                  r.max_abs, r.samples);
  // Every frame, the centre is covered entirely; coverage falls towards the rim, where the border exclusion
  // keeps subsets a ridge period away from the outline (docs/flow.md, why the border exclusion). Measured:
  // the contact 72 % covered (worst frame 68.7 %), 0.5-0.85 a 92.7 %, 0.85-0.95 a 18 %, the rim 0 %;
  // displacement 0.036 / 0.055 / 0.15 px RMS in the three inner rings; strain z 0.84 inside 0.5 a. Bounds
  // are the measured values with a margin (regression bounds), the centre exact.
  EXPECT_NEAR(row("coverage_deficit_ring_0-0.5").max_abs, 0.0, 0.5);
  EXPECT_LT(row("coverage_deficit_ring_0.5-0.85").mean, 25.0);
  EXPECT_LT(row("coverage_deficit_contact").max_abs, 45.0);
  EXPECT_GT(row("coverage_deficit_ring_0.95-1").mean, 90.0);  // the rim: the issue this measures
  // Accuracy inside 0.85 a: the interior figures' scale.
  EXPECT_LT(row("displacement_ring_0-0.5").rms, 0.05);
  EXPECT_LT(row("displacement_ring_0.5-0.85").rms, 0.08);
  EXPECT_LT(row("E_xx_ring_0-0.5").rms, 0.005);
  // The predicted strain SD (/strain/total_sd) is of the errors' size: calibrated within a factor of 3. (On
  // noise-free frames it is not: the prediction is of the noise, and there the errors are the matcher's and
  // the triangles' systematic ones.)
  const double z = row("strain_z_ring_0-0.5").rms;
  EXPECT_GT(z, 0.3);
  EXPECT_LT(z, 3.0);
  EXPECT_GT(row("strain_z_ring_0-0.5").samples, 1000);
  const H5Reader h5((fs::path(report.result_dir) / "result.h5").string());
  EXPECT_EQ(h5.shape("/strain/total_sd"), h5.shape("/strain/total"));
  EXPECT_EQ(h5.shape("/maps/strain_total_sd"), h5.shape("/maps/strain_total"));
  // Where the map has a value it has its predicted SD, of the interior's scale, but in the reference frame
  // (its strain is zero by definition, with no match to predict from).
  const std::vector<double> map = h5.read_doubles("/maps/strain_total");
  const std::vector<double> map_sd = h5.read_doubles("/maps/strain_total_sd");
  const std::size_t per_frame = map.size() / 6;
  long with_value = 0, with_sd = 0;
  for (std::size_t c = per_frame; c < map.size(); ++c) {
    if (!std::isfinite(map[c])) continue;
    ++with_value;
    if (std::isfinite(map_sd[c]) && map_sd[c] > 0.0 && map_sd[c] < 0.05) ++with_sd;
  }
  EXPECT_GT(with_value, 1000);
  EXPECT_GT(with_sd, 0.9 * with_value);
  EXPECT_EQ(h5.shape("/strain/source"), h5.shape("/strain/rotation_rad"));
  EXPECT_EQ(h5.shape("/tracks/subset_inside_fraction"), h5.shape("/tracks/status"));
}

// The stick radius through partial slip at the default scene's sensor noise (shot and read noise, blur):
// the fit takes each track's own match where the local fit stands in for it, since the local fit's windows
// smooth across the stick zone's edge and round c. Measured 3.1 % of a here (seeds 1-7: 2.6-3.8 %); with the
// reported positions 4.8 % (3.7-9.6 %).
TEST(StrainPipeline, StickRadiusThroughPartialSlipFromTheMatchesNotTheLocalFit) {
  std::string yaml = scene_yaml(
      "{field: cattaneo_mindlin, friction: 1.0, direction_deg: 270, plate_speed_mm_s: 5.0, shear_start_s: "
      "0.0}",
      12, 352, 0.02);
  yaml.replace(yaml.find("  sensor:"), std::string::npos,
               "  sensor: {full_well_electrons: 8000, read_noise: 0.006, blur_sigma_px: 0.6, drift: 0}\n");
  const pipeline::ValidationReport report = synthesise_and_validate("partial_slip_noise", yaml);
  const pipeline::ErrorStats* c = report.find("stick_radius_c_of_a", "model");
  ASSERT_NE(c, nullptr);
  std::printf("  c against the model: %.2f %% of a RMS over %ld frames\n", c->rms, c->samples);
  ASSERT_GE(c->samples, 5);
  EXPECT_LT(c->rms, 3.5);
}

TEST(StrainPipeline, StickRadiusIsZeroInFullSlip) {
  const pipeline::ValidationReport report = synthesise_and_validate(
      "full_slip",
      scene_yaml("{field: cattaneo_mindlin, friction: 1.0, direction_deg: 90, plate_speed_mm_s: 80.0, "
                 "shear_start_s: 0.0}",
                 4, 352, 0.02));
  const H5Reader h5((fs::path(report.result_dir) / "result.h5").string());
  const std::vector<double> radius_mm = h5.read_doubles("/stick/radius_mm");
  const std::vector<std::int64_t> status = h5.read_integers("/stick/radius_status");
  ASSERT_EQ(radius_mm.size(), 4u);
  EXPECT_EQ(status[0], 1);
  for (std::size_t i = 1; i < 4; ++i) {
    EXPECT_EQ(status[i], 0) << i;
    EXPECT_EQ(radius_mm[i], 0.0) << i;
  }
  EXPECT_LT(report.find("stick_radius_c_all_frames", "model")->max_abs, 0.05);  // mm
}

// Low strain (the 1280×1024 paper-camera scene's level: its 2 N spread over a 4.5 × 5.5 mm ellipse gives
// p0 ≈ 39 kPa, a third of the default scene's strain) on a small contact, noise-free: 0.5 N on an ellipse
// with 2.2 × 2.7 mm semi-axes at 10°, or on a circle of the same equivalent radius (R = 46 mm, a = 2.44 mm).
std::string low_strain_yaml(const std::string& shape) {
  return "calibration: {px_per_mm: 52, ridge_period_mm: 0.45, ridge_polarity: dark}\n"
         "compute: [contact, tracking, strain]\n"
         "synthesis:\n"
         "  seed: 5\n"
         "  image: {width_px: 352, height_px: 320, bit_depth: 8}\n"
         "  timing: {frames: 9, frame_rate_hz: 100, jitter_s: 0}\n"
         "  contact: {" +
         shape +
         ", normal_N: 0.5}\n"
         "  loading: {field: cattaneo_mindlin, friction: 1.0, direction_deg: 270, plate_speed_mm_s: 3.0, "
         "shear_start_s: 0.0}\n"
         "  sensor: {full_well_electrons: 0, read_noise: 0, blur_sigma_px: 0, drift: 0}\n";
}

// The truth side of U on an elliptical contact: the point truth (exact strain at the triangle centroids,
// through the ellipse map's chain rule) and the triangle truth (exact vertex displacements only) agree, and
// the truth grid's integral over the whole contact exceeds both (the untracked border band, where the
// Cattaneo–Mindlin energy concentrates).
TEST(StrainPipeline, EnergyTruthOnAnEllipticalContactIsConsistent) {
  const pipeline::ValidationReport report = synthesise_and_validate(
      "ellipse_energy_truth", low_strain_yaml("shape: ellipse, semi_axes_mm: [2.2, 2.7], angle_deg: 10"));
  const auto* u = report.find("U", "same triangles", "exact");
  const auto* u_triangle = report.find("U_triangle_truth", "same triangles", "exact");
  const auto* u_contact = report.find("U_whole_contact", "truth grid", "exact");
  ASSERT_GE(u->samples, 4);
  std::printf("  ellipse: U error %.1f %% (triangle truth %.1f %%, whole contact %.1f %%)\n", u->mean,
              u_triangle->mean, u_contact->mean);
  // Measured: point and triangle truths within 1 % of each other; the whole contact holds about twice the
  // tracked triangles' energy.
  EXPECT_NEAR(u->mean - u_triangle->mean, 0.0, 2.0);
  EXPECT_LT(u_contact->mean, -30.0);
}

// U at the 1280×1024 scene's strain level: a known limit, bounded at its measured values (the 5 %
// is asked on the default scene, where it is met: AffineFieldDatasetsAndAccuracy, BENCHMARKS.md). It fails
// on the tracking side (flow/), not on the strain or truth side: tracks within 0.4 mm of the border (the
// ridge contrast fades there and the fade envelope does not move with the skin) lag by 0.2-0.5 px RMS
// against 0.03 px inside, and the Cattaneo–Mindlin strain energy is concentrated towards the border, so at
// low strain those errors dominate U. Measured: ellipse U 10.0 % RMS, strain gain ≈ 1.0;
// circle U 73.9 %, strain gain 1.12. When the border band is fixed, tighten these to 5 % and 1 ± 0.02.
TEST(StrainPipelineKnownLimits, EnergyAtLowStrainStaysWithinItsMeasuredBounds) {
  const std::pair<const char*, double> cases[] = {
      {"shape: ellipse, semi_axes_mm: [2.2, 2.7], angle_deg: 10", 13.0},
      {"shape: hertz, radius_m: 0.046", 85.0}};
  for (const auto& [shape, u_bound_pct] : cases) {
    const pipeline::ValidationReport report =
        synthesise_and_validate("low_strain_energy", low_strain_yaml(shape));
    const auto* u = report.find("U", "same triangles", "exact");
    ASSERT_GE(u->samples, 4) << shape;
    const double gain = report.find("strain_gain", "point", "exact")->mean;
    std::printf("  %s: U %.1f %% RMS, strain gain %.3f\n", shape, u->rms, gain);
    EXPECT_LT(u->rms, u_bound_pct) << shape;
    EXPECT_NEAR(gain, 1.0, 0.15) << shape;
  }
}

}  // namespace
}  // namespace tirstrain

namespace tirstrain {
namespace {

// Reads one frame of /maps/strain_total as three G x G grids (row-major).
std::vector<double> last_frame_maps(const std::string& result_h5, std::size_t* cells) {
  const H5Reader h5(result_h5);
  H5Shape shape;
  const std::vector<double> all = h5.read_doubles("/maps/strain_total", &shape);
  const std::size_t g = shape[1], per_frame = g * g * 3;
  *cells = g;
  return {all.end() - static_cast<std::ptrdiff_t>(per_frame), all.end()};
}

// The maps of an elongated contact lie along its major axis, pointing down the image, and hold the strain in
// those axes: two contacts turned 20 degrees apart about the image's y (major axes at 80 and 100 degrees)
// get axes 20 degrees apart, not 160, and each map holds the exact uniform strain turned into its axes.
TEST(StrainPipeline, MapsOfAnElongatedContactHoldTheStrainInTheirOwnAxes) {
  const Gradient2 h{0.08, 0.03, -0.02, -0.04};
  const Strain2 exact = green_lagrange(h);
  double angles_rad[2] = {0.0, 0.0};
  int k = 0;
  for (const char* angle : {"80", "-80"}) {
    const std::string yaml =
        "calibration: {px_per_mm: 52, ridge_period_mm: 0.45, ridge_polarity: dark}\n"
        "compute: [contact, tracking, strain]\n"
        "synthesis:\n"
        "  seed: 4\n"
        "  image: {width_px: 288, height_px: 256, bit_depth: 8}\n"
        "  timing: {frames: 4, frame_rate_hz: 100, jitter_s: 0}\n"
        "  contact: {shape: ellipse, semi_axes_mm: [1.8, 1.3], angle_deg: " +
        std::string(angle) +
        ", normal_N: 2.0}\n"
        "  loading: {field: affine, gradient: [0.08, 0.03, -0.02, -0.04]}\n"
        "  sensor: {full_well_electrons: 0, read_noise: 0, blur_sigma_px: 0, drift: 0}\n";
    const pipeline::ValidationReport report = synthesise_and_validate(std::string("map_axes_") + angle, yaml);
    const std::string result = (fs::path(report.result_dir) / "result.h5").string();
    const H5Reader h5(result);
    const double axes_rad = h5.attribute_number("/maps", "axes_angle_rad");
    angles_rad[k++] = axes_rad;
    EXPECT_GE(axes_rad, 0.0);
    EXPECT_LT(axes_rad, std::numbers::pi);
    const Strain2 e = in_axes(exact, axes_rad);
    std::size_t g = 0;
    const std::vector<double> map = last_frame_maps(result, &g);
    double sum2[3] = {0, 0, 0};
    int cells = 0;
    for (std::size_t c = 0; c < g * g; ++c) {
      if (!std::isfinite(map[c * 3])) continue;
      ++cells;
      const double want[3] = {e.xx, e.yy, e.xy};
      for (std::size_t q = 0; q < 3; ++q) sum2[q] += std::pow(map[c * 3 + q] - want[q], 2);
    }
    ASSERT_GT(cells, 500);
    for (double s2 : sum2) EXPECT_LT(std::sqrt(s2 / cells), 0.004) << angle;
    // The image's own components differ from the turned ones by far more than that.
    EXPECT_GT(std::abs(e.xx - exact.xx), 0.05);
  }
  const double degree = std::numbers::pi / 180.0;
  // The ellipse fitted to the reference frame's segmented contact: measured 80.0 and 105.3 degrees.
  EXPECT_NEAR(angles_rad[0], 80.0 * degree, 7.0 * degree);
  EXPECT_NEAR(angles_rad[1], 100.0 * degree, 7.0 * degree);
}

TEST(StrainPipeline, AverageIsTheCellwiseMeanOverCoveringTrials) {
  const pipeline::ValidationReport a = synthesise_and_validate(
      "average_a", scene_yaml("{field: affine, gradient: [0.10, 0.0, 0.0, -0.04]}", 4));
  const pipeline::ValidationReport b = synthesise_and_validate(
      "average_b", scene_yaml("{field: affine, gradient: [-0.06, 0.0, 0.0, 0.08]}", 4));
  const std::string result_a = (fs::path(a.result_dir) / "result.h5").string();
  const std::string result_b = (fs::path(b.result_dir) / "result.h5").string();
  const fs::path out = scratch("average_out");
  const std::string command = std::string(TIRSTRAIN_CLI) + " average " + result_a + " " + b.result_dir +
                              " --at last --out " + out.string() + " 2>&1";
  ASSERT_EQ(std::system(command.c_str()), 0);
  std::size_t g = 0;
  const std::vector<double> map_a = last_frame_maps(result_a, &g);
  const std::vector<double> map_b = last_frame_maps(result_b, &g);
  const H5Reader h5((out / "average.h5").string());
  const std::vector<double> mean = h5.read_doubles("/maps/strain_total");
  const std::vector<double> count = h5.read_doubles("/maps/count");
  ASSERT_EQ(mean.size(), g * g * 3);
  int both = 0;
  for (std::size_t cell = 0; cell < g * g; ++cell)
    for (std::size_t c = 0; c < 3; ++c) {
      const double va = map_a[cell * 3 + c], vb = map_b[cell * 3 + c], m = mean[cell * 3 + c];
      const int n = std::isfinite(va) + std::isfinite(vb);
      ASSERT_EQ(count[cell], n) << cell;
      if (n == 2) {
        ASSERT_NEAR(m, 0.5 * (va + vb), 1e-15);
        ++both;
      } else if (n == 1) {
        ASSERT_EQ(m, std::isfinite(va) ? va : vb);
      } else {
        ASSERT_TRUE(std::isnan(m));
      }
    }
  EXPECT_GT(both, 300);
  for (const char* png : {"average_E_xx.png", "average_E_yy.png", "average_E_xy.png", "average_count.png"})
    EXPECT_TRUE(fs::exists(out / png)) << png;
  // The interior mean E_xx is about the mean of the two fields' Green–Lagrange E_xx at the last frame.
  double sum = 0.0;
  int n = 0;
  for (std::size_t cell = 0; cell < g * g; ++cell)
    if (count[cell] == 2.0 && std::isfinite(mean[cell * 3])) {
      sum += mean[cell * 3];
      ++n;
    }
  const double expected = 0.5 * ((0.10 + 0.5 * 0.10 * 0.10) + (-0.06 + 0.5 * 0.06 * 0.06));
  EXPECT_NEAR(sum / n, expected, 0.003);

  // Refused, each with the earlier average kept: a trial given twice, an output inside a result folder, a
  // time outside the trials, and --at with --frame (the command line's mistake: exit 2).
  const auto refused = [&](const std::string& args, const std::string& why, int code) {
    const std::string run =
        std::string(TIRSTRAIN_CLI) + " average " + args + " > " + (out.string() + ".log") + " 2>&1";
    const int status = std::system(run.c_str());
    EXPECT_EQ(WEXITSTATUS(status), code) << args;
    std::ifstream log(out.string() + ".log");
    const std::string text((std::istreambuf_iterator<char>(log)), std::istreambuf_iterator<char>());
    EXPECT_NE(text.find(why), std::string::npos) << args << "\n" << text;
  };
  refused(result_a + " " + a.result_dir + " --out " + out.string(), "is given twice", 1);
  refused(result_a + " " + b.result_dir + " --out " + (fs::path(a.result_dir) / "avg").string(),
          "lies inside the result folder", 1);
  refused(result_a + " " + b.result_dir + " --time-s 99 --out " + out.string(),
          "lies outside the result's frames", 1);
  refused(result_a + " " + b.result_dir + " --at last --frame 1 --out " + out.string(),
          "give one of --at, --frame and --time-s", 2);
  EXPECT_FALSE(fs::exists(fs::path(a.result_dir) / "avg"));
  EXPECT_EQ(H5Reader((out / "average.h5").string()).read_doubles("/maps/count"), count);

  // The same two trials' principal directions: field a stretches along x (e1 at 0 deg), field b along y
  // (e1 at 90 deg); both nearly uniform in direction, and Kuiper's test tells them apart.
  const fs::path orient = scratch("orientation_out");
  const std::string orient_command = std::string(TIRSTRAIN_CLI) + " orientation-stats " + result_a + " " +
                                     b.result_dir + " --at last --out " + orient.string() + " 2>&1";
  ASSERT_EQ(std::system(orient_command.c_str()), 0);
  std::ifstream jf(orient / "orientation_stats.json");
  const auto j = nlohmann::json::parse(jf);
  ASSERT_EQ(j["groups"].size(), 2u);
  const auto& pa = j["groups"][0]["principal"];
  const auto& pb = j["groups"][1]["principal"];
  const double dir_a = pa["mean_direction_deg"].get<double>();
  EXPECT_LT(std::min(dir_a, 180.0 - dir_a), 2.0);
  EXPECT_NEAR(pb["mean_direction_deg"].get<double>(), 90.0, 2.0);
  EXPECT_GT(pa["resultant_length"].get<double>(), 0.95);
  EXPECT_GT(pb["resultant_length"].get<double>(), 0.95);
  EXPECT_GT(pa["count"].get<int>(), 300);
  ASSERT_EQ(j["kuiper"]["principal"].size(), 1u);
  EXPECT_GT(j["kuiper"]["principal"][0]["kuiper_V"].get<double>(), 0.9);
  EXPECT_LT(j["kuiper"]["principal"][0]["p_value"].get<double>(), 1e-6);
  EXPECT_TRUE(fs::exists(orient / "rose_principal.png"));
}

TEST(StrainPipeline, MotionBlurredPlateFrameIsMarkedAndBridged) {
  // The plate at 20 mm/s (10.4 px per frame) under a 56-row pattern band, frame 9 exposed over 15 ms
  // (15.6 px of motion; the hard_motion_blur scene, shortened). The blurred band's loose match was 3.8 px
  // off on that scene and, stitched into the mosaic, biased every later frame by 0.17 px. Now its plate
  // displacement is the last motion carried over in time (the frame times jitter by 0.2 ms, 0.2 px of plate
  // travel), /plate/status says so (1), and the later frames match. Measured: blurred frame 0.0093 px off,
  // the other frames 0.0107 px RMS.
  const int frames = 14, blurred = 9;
  const std::string yaml =
      "calibration: {px_per_mm: 52, ridge_period_mm: 0.45, ridge_polarity: dark}\n"
      "reference_pattern: {roi_px: [0, 0, 320, 56]}\n"
      "compute: [contact, tracking, strain]\n"
      "synthesis:\n"
      "  seed: 5\n"
      "  image: {width_px: 320, height_px: 288, bit_depth: 8}\n"
      "  timing: {frames: 14, frame_rate_hz: 100, jitter_s: 0.0002}\n"
      "  contact: {shape: hertz, normal_N: 2.0, radius_m: 0.005}\n"
      "  loading: {field: cattaneo_mindlin, friction: 1.0, direction_deg: 270, plate_speed_mm_s: 20.0,\n"
      "            shear_start_s: 0.02}\n"
      "  pattern: {dot_spacing_mm: 0.22, dot_sigma_mm: 0.04, opacity: 0.6}\n"
      "  sensor: {full_well_electrons: 8000, read_noise: 0.006, blur_sigma_px: 0.6, drift: 0,\n"
      "           motion_blur_frames: [9], motion_blur_exposure_s: 0.015}\n";
  const pipeline::ValidationReport report = synthesise_and_validate("plate_blur", yaml);
  const fs::path dir = fs::path(report.result_dir).parent_path().parent_path();
  const H5Reader h5((fs::path(report.result_dir) / "result.h5").string());
  const std::vector<std::int64_t> status = h5.read_integers("/plate/status");
  ASSERT_EQ(status.size(), static_cast<std::size_t>(frames));
  const std::vector<double> plate = h5.read_doubles("/plate/displacement_px");
  const samples::Trial trial(samples::load_synth_config((dir / "scene_in.yaml").string()));
  double sharp2 = 0.0;
  int sharp = 0;
  for (int f = 1; f < frames; ++f) {
    const Vec2 truth = trial.load(f).plate_px;
    const double e = std::hypot(plate[2 * f] - truth.x, plate[2 * f + 1] - truth.y);
    if (f == blurred) {
      EXPECT_EQ(status[f], 1) << "the blurred frame is marked predicted";
      std::printf("plate: blurred frame %.4f px off\n", e);
      EXPECT_LT(e, 0.05) << "blurred frame";
    } else {
      EXPECT_EQ(status[f], 0) << "frame " << f;
      sharp2 += e * e;
      ++sharp;
    }
  }
  const double sharp_rms = std::sqrt(sharp2 / sharp);
  std::printf("plate: sharp frames %.4f px RMS\n", sharp_rms);
  EXPECT_LT(sharp_rms, 0.02);
}

// Smoothing in time (docs/flow.md "After the trial") around a frame that cannot be decoded: the tracks'
// runs end at it and start again after it, the skipped row stays NaN, the reference frame keeps X exactly,
// and the strain stage, run again over the replayed trial, differs from the unsmoothed run's.
TEST(StrainPipeline, SmoothedTracksFeedTheStrainAroundASkippedFrame) {
  const int frames = 24, skipped = 12;
  const std::string loading =
      "{field: cattaneo_mindlin, friction: 1.0, direction_deg: 0, plate_speed_mm_s: 5.0, shear_start_s: "
      "0.02}";
  const pipeline::ValidationReport base =
      synthesise_and_validate("smoothed_skipped", scene_yaml(loading, frames));
  const fs::path dir = fs::path(base.result_dir).parent_path().parent_path();
  const fs::path trial = dir / "validation" / "trial";
  char name[32];
  std::snprintf(name, sizeof name, "%06d.png", skipped);
  std::ofstream(trial / "frames" / name) << "not an image";
  const auto process = [&](const std::string& mode) {
    YAML::Node scene = YAML::LoadFile((trial / "scene.yaml").string());
    scene["tracking"]["smooth_in_time"] = mode;
    const fs::path scene_path = dir / ("scene_" + mode + ".yaml");
    std::ofstream(scene_path) << scene << "\n";
    pipeline::ProcessOptions o;
    o.input = trial.string();
    o.scene_path = scene_path.string();
    o.out_dir = (dir / ("out_" + mode)).string();
    o.quiet = true;
    o.overlay = pipeline::OverlayMode::kNone;
    pipeline::run_process(o);
    return H5Reader((fs::path(o.out_dir) / "result.h5").string());
  };
  const H5Reader on = process("on"), off = process("off");
  EXPECT_EQ(on.attribute_number("/tracks", "smoothed_in_time"), 1.0);
  EXPECT_EQ(off.attribute_number("/tracks", "smoothed_in_time"), 0.0);
  H5Shape shape;
  const std::vector<double> smoothed = on.read_doubles("/tracks/position_px", &shape);
  const std::vector<double> tracked = off.read_doubles("/tracks/position_px");
  const std::vector<double> reference = on.read_doubles("/tracks/reference_px");
  ASSERT_EQ(shape[0], static_cast<std::size_t>(frames));
  const std::size_t k_count = shape[1];
  ASSERT_EQ(tracked.size(), smoothed.size());
  H5Shape model_shape;
  const std::vector<std::int64_t> model = on.read_integers("/tracks/model", &model_shape);
  const std::vector<std::int64_t> model_off = off.read_integers("/tracks/model");
  const std::vector<double> distance = on.read_doubles("/tracks/model_mahalanobis2");
  ASSERT_EQ(model_shape, (H5Shape{shape[0], shape[1]}));
  EXPECT_EQ(on.shape("/tracks/covariance_px2"), (H5Shape{shape[0], shape[1], 3}));
  EXPECT_EQ(on.shape("/tracks/rest_chi2_per_dof"), (H5Shape{shape[0]}));
  int moved = 0, finite_skipped = 0, smoothed_in_place = 0;
  double largest = 0.0;
  for (std::size_t f = 0; f < shape[0]; ++f)
    for (std::size_t k = 0; k < k_count; ++k) {
      const double* p = &smoothed[(f * k_count + k) * 2];
      const double* q = &tracked[(f * k_count + k) * 2];
      if (f == static_cast<std::size_t>(skipped)) {
        finite_skipped += std::isfinite(p[0]) ? 1 : 0;
        continue;
      }
      ASSERT_EQ(std::isfinite(p[0]), std::isfinite(q[0])) << "frame " << f << " track " << k;
      if (!std::isfinite(p[0])) continue;
      if (f == 0) {  // the reference frame: X, exactly
        EXPECT_EQ(p[0], reference[2 * k]);
        EXPECT_EQ(p[1], reference[2 * k + 1]);
        continue;
      }
      const double d = std::hypot(p[0] - q[0], p[1] - q[1]);
      largest = std::max(largest, d);
      moved += d > 0.0 ? 1 : 0;
      // Every smoothed position is flagged as such, with the distance that accepted it; every other one
      // is what the tracker reported.
      const std::size_t at = f * k_count + k;
      if (d > 0.0) {
        EXPECT_EQ(model[at], 3) << "frame " << f << " track " << k;
        EXPECT_LE(distance[at], 13.8) << "frame " << f << " track " << k;
      } else if (model[at] == 3) {
        ++smoothed_in_place;  // the smoothing landed on the match itself
      }
      // Unsmoothed: the own match, the fusion, the rest fit, the local fit or a moving frame's affine fit
      // (0, 1, 2, 4, 5).
      EXPECT_TRUE(model_off[at] <= 2 || model_off[at] == 4 || model_off[at] == 5)
          << "frame " << f << " track " << k;
    }
  EXPECT_EQ(finite_skipped, 0);
  EXPECT_LT(smoothed_in_place, moved / 100 + 1);
  const nlohmann::json summary = nlohmann::json::parse(std::ifstream(dir / "out_on" / "summary.json"));
  const auto& by_model = summary["tracking"]["track_frames_by_model"];
  EXPECT_EQ(by_model["smoothed_in_time"].get<long>(),
            summary["tracking"]["smoothed_track_frames"].get<long>());
  EXPECT_GE(by_model["smoothed_in_time"].get<long>(), moved);
  EXPECT_GT(moved, 100);
  // Noise-free frames: the tracks' own noise is a few hundredths of a pixel, and no sample moves by more
  // than 2γσ of its series.
  EXPECT_LT(largest, 0.2);
  std::printf("smoothed around a skipped frame: %d track-frames moved, at most %.4f px\n", moved, largest);
  // The strain follows the smoothed tracks: the rerun strain stage wrote the same shape, other values.
  H5Shape strain_shape;
  const std::vector<double> strain_on = on.read_doubles("/strain/total", &strain_shape);
  const std::vector<double> strain_off = off.read_doubles("/strain/total");
  ASSERT_EQ(strain_on.size(), strain_off.size());
  EXPECT_EQ(strain_shape[0], static_cast<std::size_t>(frames));
  double strain_change = 0.0;
  for (std::size_t i = 0; i < strain_on.size(); ++i)
    if (std::isfinite(strain_on[i]) && std::isfinite(strain_off[i]))
      strain_change = std::max(strain_change, std::abs(strain_on[i] - strain_off[i]));
  EXPECT_GT(strain_change, 0.0);
}

}  // namespace
}  // namespace tirstrain
