// The spatially adaptive local fit (flow/local_fit.hpp) on synthetic matches with known truth: it averages
// where the field is affine, keeps the detail where it is not, and never moves a match beyond its noise.
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "flow/detail/small_cholesky.hpp"
#include "flow/local_fit.hpp"
#include "flow/settings.hpp"
#include "flow/tracker.hpp"
#include "samples/generalisation.hpp"

namespace {

using tirstrain::Vec2;
using tirstrain::flow::choose_local_fits;
using tirstrain::flow::LocalFit;
using tirstrain::flow::LocalFitOptions;
using tirstrain::flow::OwnMatch;

struct Field {
  std::vector<OwnMatch> matches;
  std::vector<Vec2> truth;  // the true displacement at each match
};

// Matches on a 10 px grid of cols × rows points, each off its true displacement by independent noise σ.
Field grid_field(int cols, int rows, double sigma_px, const std::function<Vec2(Vec2)>& u, unsigned seed = 7) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma_px);
  Field f;
  for (int j = 0; j < rows; ++j)
    for (int i = 0; i < cols; ++i) {
      const Vec2 X{10.0 * i, 10.0 * j};
      const Vec2 d = u(X);
      OwnMatch m;
      m.reference_px = X;
      m.position_px = {X.x + d.x + noise(rng), X.y + d.y + noise(rng)};
      m.covariance_px2 = sigma_px * sigma_px * Eigen::Matrix2d::Identity();
      f.matches.push_back(m);
      f.truth.push_back(d);
    }
  return f;
}

LocalFitOptions options_without_shared_noise() {
  LocalFitOptions o;
  o.radii_px = {15.0, 21.2, 30.0, 42.4, 60.0, 80.0};
  o.correlation_side_px = 1.0;  // the matches above share no noise
  return o;
}

double rms_error(const Field& f, const std::vector<LocalFit>& fits) {
  double sum = 0.0;
  for (std::size_t i = 0; i < fits.size(); ++i)
    sum += std::pow(fits[i].displacement_px.x - f.truth[i].x, 2) +
           std::pow(fits[i].displacement_px.y - f.truth[i].y, 2);
  return std::sqrt(sum / (2.0 * static_cast<double>(fits.size())));
}

TEST(LocalFit, RigidShiftIsAveragedOverTheWholeFrame) {
  const double sigma = 0.02;
  const Field f = grid_field(30, 20, sigma, [](Vec2) { return Vec2{0.3, -0.2}; });
  const std::vector<LocalFit> fits = choose_local_fits(f.matches, options_without_shared_noise());
  int whole_frame = 0, windowed = 0;
  for (const LocalFit& fit : fits) {
    whole_frame += fit.window == 6 ? 1 : 0;
    if (fit.window < 0) continue;
    ++windowed;
    EXPECT_LE(fit.agreement_chi2, 9.21);
    EXPECT_LE(fit.own_mahalanobis2, fit.agreement_chi2);
  }
  EXPECT_GT(windowed, 580);  // each comparison passes at 99 %: a few tracks keep their own match
  // 600 matches: the frame's fit is within a few σ/√600 ≈ 0.0008 px; most tracks reach it.
  EXPECT_GT(whole_frame, 500);
  EXPECT_LT(rms_error(f, fits), 0.004);
  // Its predicted noise says so too (the frame fit's σ at the centre ≈ σ/√600, larger at the corners).
  EXPECT_LT(std::sqrt(fits[310].covariance_px2(0, 0)), 0.003);
}

TEST(LocalFit, ShortWaveKeepsItsAmplitude) {
  // 0.1 px at a 40 px wavelength (4 grid steps) with 0.01 px of noise: any window wider than a quarter wave
  // would flatten it, and the scales disagree long before that.
  const double sigma = 0.01, wavelength = 40.0;
  const Field f = grid_field(30, 20, sigma, [&](Vec2 X) {
    return Vec2{0.1 * std::sin(2.0 * std::numbers::pi * X.x / wavelength), 0.0};
  });
  const std::vector<LocalFit> fits = choose_local_fits(f.matches, options_without_shared_noise());
  // The in-phase gain of what is reported, by least squares against the true sine.
  double num = 0.0, den = 0.0;
  for (std::size_t i = 0; i < fits.size(); ++i) {
    num += fits[i].displacement_px.x * f.truth[i].x;
    den += f.truth[i].x * f.truth[i].x;
  }
  EXPECT_GT(num / den, 0.9);
  EXPECT_LT(rms_error(f, fits), 1.2 * sigma);
}

TEST(LocalFit, LongWaveIsAveragedAndFollowed) {
  // 0.1 px over a 400 px wavelength: nearly affine over 40-60 px windows, so the noise falls well below the
  // matches' own while the wave stays.
  const double sigma = 0.02, wavelength = 400.0;
  const Field f = grid_field(40, 20, sigma, [&](Vec2 X) {
    return Vec2{0.1 * std::sin(2.0 * std::numbers::pi * X.x / wavelength), 0.0};
  });
  const std::vector<LocalFit> fits = choose_local_fits(f.matches, options_without_shared_noise());
  EXPECT_LT(rms_error(f, fits), 0.5 * sigma);
}

TEST(LocalFit, SecondOrderFollowsABendingFieldWhereAnAffineFitStops) {
  // A Hertz-like bowl, u = 0.4 px ((X − 195) / 195)², v = 0, over 400 × 200 px with 0.02 px of noise: an
  // affine window sees its curvature (0.4 px over the half-width) once it spans a few grid steps and stops
  // there, while the second-order windows describe it exactly and grow to the widest radius.
  const double sigma = 0.02;
  const Field f = grid_field(40, 20, sigma, [](Vec2 X) {
    const double s = (X.x - 195.0) / 195.0;
    return Vec2{0.4 * s * s, 0.0};
  });
  LocalFitOptions affine = options_without_shared_noise();
  affine.order = 1;
  LocalFitOptions second = options_without_shared_noise();
  second.order = 2;
  const std::vector<LocalFit> by_affine = choose_local_fits(f.matches, affine);
  const std::vector<LocalFit> by_second = choose_local_fits(f.matches, second);
  const double affine_rms = rms_error(f, by_affine), second_rms = rms_error(f, by_second);
  std::printf("bowl: affine %.4f px, second order %.4f px (noise %.3f)\n", affine_rms, second_rms, sigma);
  EXPECT_LT(second_rms, 0.35 * sigma);
  EXPECT_LT(second_rms, 0.8 * affine_rms);
  // The wider windows are what lowers it: the median chosen radius, second order against affine.
  const auto median_radius = [](std::vector<LocalFit> fits) {
    std::vector<double> r;
    for (const LocalFit& fit : fits) r.push_back(fit.radius_px);
    std::nth_element(r.begin(), r.begin() + static_cast<std::ptrdiff_t>(r.size() / 2), r.end());
    return r[r.size() / 2];
  };
  EXPECT_GT(median_radius(by_second), median_radius(by_affine));
}

// Matches on a 10 px grid whose u and v noise are correlated (ρ), as a subset's are when its ridges run
// obliquely: pinned across them, free along them.
Field correlated_grid_field(int cols, int rows, double sigma_px, double rho,
                            const std::function<Vec2(Vec2)>& u, unsigned seed = 11) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, 1.0);
  Field f;
  for (int j = 0; j < rows; ++j)
    for (int i = 0; i < cols; ++i) {
      const Vec2 X{10.0 * i, 10.0 * j};
      const Vec2 d = u(X);
      const double a = noise(rng), b = noise(rng);
      OwnMatch m;
      m.reference_px = X;
      m.position_px = {X.x + d.x + sigma_px * a,
                       X.y + d.y + sigma_px * (rho * a + std::sqrt(1 - rho * rho) * b)};
      m.covariance_px2 << 1.0, rho, rho, 1.0;
      m.covariance_px2 *= sigma_px * sigma_px;
      f.matches.push_back(m);
      f.truth.push_back(d);
    }
  return f;
}

TEST(LocalFit, AComponentFlatOverTheFrameTakesTheFramesFitOfItAlone) {
  // u a 40 px wave (the joint windows stop within a few grid steps), v = 0 everywhere, the two components'
  // noise correlated (ρ 0.7). v alone passes the frame's fit of it: its error falls to a fraction of the
  // noise, while u, which no wide window describes, is left exactly as the joint windows gave it.
  const double sigma = 0.02, rho = 0.7, wavelength = 40.0;
  const Field f = correlated_grid_field(40, 20, sigma, rho, [&](Vec2 X) {
    return Vec2{0.1 * std::sin(2.0 * std::numbers::pi * X.x / wavelength), 0.0};
  });
  LocalFitOptions joint = options_without_shared_noise();
  joint.per_component = false;
  const std::vector<LocalFit> by_joint = choose_local_fits(f.matches, joint);
  const std::vector<LocalFit> by_component = choose_local_fits(f.matches, options_without_shared_noise());
  const auto rms = [&](const std::vector<LocalFit>& fits, int c) {
    double sum = 0.0;
    for (std::size_t i = 0; i < fits.size(); ++i) {
      const double e =
          c == 0 ? fits[i].displacement_px.x - f.truth[i].x : fits[i].displacement_px.y - f.truth[i].y;
      sum += e * e;
    }
    return std::sqrt(sum / static_cast<double>(fits.size()));
  };
  std::printf("wave in u, flat v: v %.4f px joint, %.4f px by component; u %.4f / %.4f px (noise %.3f)\n",
              rms(by_joint, 1), rms(by_component, 1), rms(by_joint, 0), rms(by_component, 0), sigma);
  EXPECT_LT(rms(by_component, 1), 0.5 * rms(by_joint, 1));
  int v_on_frame = 0;
  double on_frame_sum = 0.0;
  for (std::size_t i = 0; i < by_component.size(); ++i) {
    const LocalFit& fit = by_component[i];
    if (fit.component_radius_px[1] > 80.0) {
      ++v_on_frame;
      on_frame_sum += std::pow(fit.displacement_px.y - f.truth[i].y, 2);
    }
    // u is never taken further than the joint windows went.
    EXPECT_LE(fit.component_radius_px[0], 80.0);
    EXPECT_DOUBLE_EQ(fit.displacement_px.x, by_joint[i].displacement_px.x);
    // The pair still lies within the own match's noise, as every joint window's does.
    if (fit.reports_fit()) {
      EXPECT_LE(fit.own_mahalanobis2, 9.21 + 1e-9);
    }
  }
  // Those whose own v lies more than about 2.2 σ off (in the correlated noise) keep it: the frame's fit
  // would move them beyond their noise. The rest: 800 matches put the frame's fit of v within a few
  // σ/√800 ≈ 0.0007 px.
  EXPECT_GT(v_on_frame, 700);
  EXPECT_LT(std::sqrt(on_frame_sum / v_on_frame), 0.1 * sigma);
}

TEST(LocalFit, StepIsNotSmearedAcrossItsEdge) {
  // Two rigid halves 0.3 px apart across y = 95: the tracks near the edge keep windows that do not reach
  // across it (or their own match); none is pulled beyond its noise.
  const double sigma = 0.01;
  const Field f = grid_field(30, 20, sigma, [](Vec2 X) { return Vec2{X.y < 95.0 ? 0.0 : 0.3, 0.0}; });
  const std::vector<LocalFit> fits = choose_local_fits(f.matches, options_without_shared_noise());
  double worst = 0.0;
  for (std::size_t i = 0; i < fits.size(); ++i)
    worst = std::max(worst, std::abs(fits[i].displacement_px.x - f.truth[i].x));
  EXPECT_LT(worst, 4.5 * sigma);
  EXPECT_LT(rms_error(f, fits), sigma);
}

TEST(LocalFit, AnOutlierKeepsItsOwnMatchAndDoesNotPullItsNeighbours) {
  const double sigma = 0.01;
  Field f = grid_field(20, 20, sigma, [](Vec2) { return Vec2{0.1, 0.1}; });
  const std::size_t odd = 210;
  f.matches[odd].position_px.x += 0.5;  // a match 50 σ off: not the field
  const std::vector<LocalFit> fits = choose_local_fits(f.matches, options_without_shared_noise());
  EXPECT_EQ(fits[odd].window, -1);
  EXPECT_DOUBLE_EQ(fits[odd].displacement_px.x, f.matches[odd].position_px.x - f.matches[odd].reference_px.x);
  for (std::size_t i = 0; i < fits.size(); ++i)
    if (i != odd) {
      EXPECT_LT(std::abs(fits[i].displacement_px.x - 0.1), 4.0 * sigma) << i;
    }
}

TEST(LocalFit, SharedNoiseIsCountedOnce) {
  // The same matches declared to share their noise with every neighbour within 41 px predict a wider
  // uncertainty for the same fit: overlapping subsets are not independent evidence.
  const Field f = grid_field(30, 20, 0.02, [](Vec2) { return Vec2{0.0, 0.0}; });
  LocalFitOptions shared = options_without_shared_noise();
  shared.correlation_side_px = 41.0;
  const LocalFit alone = choose_local_fits(f.matches, options_without_shared_noise())[310];
  const LocalFit together = choose_local_fits(f.matches, shared)[310];
  ASSERT_EQ(alone.window, together.window);
  EXPECT_GT(together.covariance_px2(0, 0), 8.0 * alone.covariance_px2(0, 0));
}

TEST(LocalFit, MatchWithoutCovarianceKeepsItsOwn) {
  Field f = grid_field(10, 10, 0.01, [](Vec2) { return Vec2{0.2, 0.0}; });
  f.matches[44].covariance_px2(0, 0) = std::numeric_limits<double>::quiet_NaN();
  const std::vector<LocalFit> fits = choose_local_fits(f.matches, options_without_shared_noise());
  EXPECT_EQ(fits[44].window, -1);
  EXPECT_GE(fits[45].window, 0);
}

}  // namespace

namespace {

using tirstrain::flow::FeatureTracker;
using tirstrain::flow::TrackerOptions;
using tirstrain::flow::TrackModel;

// The tracker with the local fit on (the scene key `local_fit: true`) over the small speckle stretch of the
// generalisation benchmark: every position a local fit gives is flagged with its window and lies within its
// own match's noise, and the error falls against the same run without it. The frame's affine fit, which
// would stand in for the uniform stretch's matches first, is off.
double stretch_rms(bool local_fit, int& fitted, double& worst_distance2, bool& windows_given) {
  const tirstrain::samples::GeneralisationCase sequence(tirstrain::samples::generalisation_config(
      tirstrain::samples::GeneralisationField::kStretch, tirstrain::samples::GeneralisationTexture::kSpeckle,
      0.005, true));
  TrackerOptions s = tirstrain::flow::parse_tracking_options(tirstrain::Scene{}, "auto");
  s.births.enabled = false;
  s.local_fit.enabled = local_fit;
  s.affine_fit.enabled = false;
  FeatureTracker tracker(s);
  std::vector<Vec2> points;
  for (double y = 16; y < sequence.height() - 16; y += 10)
    for (double x = 16; x < sequence.width() - 16; x += 10) points.push_back({x, y});
  tracker.start(sequence.add_noise(sequence.render_clean(0), 0), cv::Mat(), 0.0, points);
  double sum = 0.0;
  long n = 0;
  fitted = 0;
  worst_distance2 = 0.0;
  windows_given = true;
  for (int frame = 1; frame < sequence.frames(); ++frame) {
    tracker.track(sequence.add_noise(sequence.render_clean(frame), frame), cv::Mat(), 0.01 * frame);
    for (const auto& t : tracker.tracks()) {
      if (!tirstrain::flow::is_alive(t.status)) continue;
      const Vec2 u = sequence.field(t.reference_px, frame).displacement_px;
      sum += std::pow(t.position_px.x - t.reference_px.x - u.x, 2) +
             std::pow(t.position_px.y - t.reference_px.y - u.y, 2);
      ++n;
      if (t.model != TrackModel::kLocalFit) {
        windows_given = windows_given && std::isnan(t.model_window_px[0]) && std::isnan(t.model_window_px[1]);
        continue;
      }
      ++fitted;
      // Each component's window: 0 where that component is the own match's, else at least the smallest.
      for (double w : t.model_window_px)
        windows_given = windows_given && (w == 0.0 || w >= 1.5 * s.seeding.grid_step_px - 1e-9);
      windows_given = windows_given && std::max(t.model_window_px[0], t.model_window_px[1]) > 0.0;
      worst_distance2 = std::max(worst_distance2, t.model_mahalanobis2);
    }
  }
  return std::sqrt(sum / (2.0 * static_cast<double>(n)));
}

TEST(LocalFit, TrackerFlagsEveryLocalFitAndLowersTheError) {
  int fitted_on = 0, fitted_off = 0;
  double worst_on = 0.0, worst_off = 0.0;
  bool windows_on = false, windows_off = false;
  const double on = stretch_rms(true, fitted_on, worst_on, windows_on);
  const double off = stretch_rms(false, fitted_off, worst_off, windows_off);
  std::printf("speckle stretch: %.4f px with the local fit (%d track-frames), %.4f px without\n", on,
              fitted_on, off);
  EXPECT_EQ(fitted_off, 0);
  EXPECT_GT(fitted_on, 100);
  EXPECT_TRUE(windows_on);
  EXPECT_TRUE(windows_off);
  EXPECT_LE(worst_on, 9.21 + 1e-9);  // within the own match's noise, as the agreement test demands
  EXPECT_LT(on, off);
}

// The windows' 12 × 12 solver against Eigen's LLT: the same solutions, a condition bound no larger than
// Eigen's estimate, and the same refusal of a matrix that is not positive definite.
TEST(SmallCholesky, SolvesAsEigensLltAndBoundsItsConditionEstimate) {
  using Matrix = Eigen::Matrix<double, 12, 12>;
  std::mt19937 rng(11);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    // B Bᵀ with columns scaled over six decades: conditioning from good to near the windows' 1e-10 limit.
    Matrix b;
    for (int r = 0; r < 12; ++r)
      for (int c = 0; c < 12; ++c) b(r, c) = normal(rng) * std::pow(10.0, -0.5 * (c % 7) * (trial % 4));
    const Matrix a = b * b.transpose() + 1e-12 * Matrix::Identity();
    Eigen::Matrix<double, 12, 3> right;
    for (int r = 0; r < 12; ++r)
      for (int c = 0; c < 3; ++c) right(r, c) = normal(rng);
    tirstrain::flow::detail::SmallCholesky<12> small;
    ASSERT_TRUE(small.compute(a));
    const Eigen::LLT<Matrix, Eigen::Lower> llt(a);
    ASSERT_EQ(llt.info(), Eigen::Success);
    Eigen::Matrix<double, 12, 3> x = right;
    small.solve_in_place(x);
    const Eigen::Matrix<double, 12, 3> expected = llt.solve(right);
    const double condition = 1.0 / llt.rcond();
    EXPECT_LE((x - expected).norm(), 1e-13 * condition * expected.norm()) << trial;
    EXPECT_LE(small.rcond_lower_bound(), llt.rcond() * (1.0 + 1e-12)) << trial;
    EXPECT_GT(small.rcond_lower_bound(), 1e-3 * llt.rcond()) << trial;  // a useful bound, not a vacuous one
    // The comparison bound is never above the explicit one (on these dense random factors it is far looser).
    EXPECT_LE(small.rcond_comparison_bound(), small.rcond_lower_bound() * (1.0 + 1e-12)) << trial;
  }
  Matrix indefinite = Matrix::Identity();
  indefinite(7, 7) = -1.0;
  tirstrain::flow::detail::SmallCholesky<12> small;
  EXPECT_FALSE(small.compute(indefinite));
  Matrix not_a_number = Matrix::Identity();
  not_a_number(3, 3) = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(small.compute(not_a_number));
}

TEST(SmallCholesky, ComparisonBoundIsCloseOnTheWindowsNormalMatrices) {
  // A window's normal matrix as the local fit builds it: matches on a 10 px grid within radius r, the
  // second-order basis in coordinates scaled by the widest radius (80 px), each match weighted by the inverse
  // of a subset's covariance that is 100 times larger along its ridges than across them. On such matrices
  // the two triangular solves bound rcond within a few times Eigen's estimate, far above the 1e-10 limit,
  // so the cheaper test decides alone.
  using Matrix = Eigen::Matrix<double, 12, 12>;
  for (double radius_px : {15.0, 21.2, 30.0, 42.4, 60.0, 80.0})
    for (double ridge_rad : {0.0, 0.7}) {
      const Eigen::Matrix2d rotation = Eigen::Rotation2Dd(ridge_rad).toRotationMatrix();
      const Eigen::Matrix2d weight =
          rotation * Eigen::Vector2d(1.0 / 0.01, 1.0 / 0.0001).asDiagonal() * rotation.transpose();
      Matrix normal = Matrix::Zero();
      for (int i = -8; i <= 8; ++i)
        for (int j = -8; j <= 8; ++j) {
          const double x = 10.0 * i, y = 10.0 * j;
          if (x * x + y * y > radius_px * radius_px) continue;
          const double u = x / 80.0, v = y / 80.0;
          const double basis[6] = {1.0, u, v, u * u, u * v, v * v};
          Eigen::Matrix<double, 2, 12> a = Eigen::Matrix<double, 2, 12>::Zero();
          for (int p = 0; p < 6; ++p) a(0, 2 * p) = a(1, 2 * p + 1) = basis[p];
          normal += a.transpose() * weight * a;
        }
      tirstrain::flow::detail::SmallCholesky<12> small;
      ASSERT_TRUE(small.compute(normal)) << radius_px;
      const Eigen::LLT<Matrix, Eigen::Lower> llt(normal);
      const double comparison = small.rcond_comparison_bound();
      EXPECT_LE(comparison, small.rcond_lower_bound() * (1.0 + 1e-12)) << radius_px;
      EXPECT_GT(comparison, 0.1 * llt.rcond()) << radius_px << " " << ridge_rad;  // measured: within ×3.3
      EXPECT_GT(comparison, 1e-10) << radius_px;
    }
}

}  // namespace
