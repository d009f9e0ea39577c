// Tare and phases (signals/phases.cpp) and friction inside them (signals/friction_trial.cpp) on synthetic
// recordings with known phase times and μ: offsets, drift, an approach, 1–5 strokes, noise and DAQ
// quantisation. Every phase time within 20 ms, every slide's μ within 2 %.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.hpp"
#include "signals/friction.hpp"
#include "signals/friction_trial.hpp"
#include "signals/phases.hpp"
#include "tests/signals/synthetic_recording.hpp"

namespace ts = tirstrain::signals;
using ts::testing::SynthRecording;

namespace {

constexpr double kTimeTolerance_s = 0.02, kMuTolerance = 0.02;

bool has_warning(const std::vector<ts::PhaseWarning>& warnings, const std::string& code) {
  return std::any_of(warnings.begin(), warnings.end(), [&](const auto& w) { return w.code == code; });
}

std::string codes(const std::vector<ts::PhaseWarning>& warnings) {
  std::string s;
  for (const auto& w : warnings) s += w.code + " ";
  return s;
}

struct Errors {
  double time_s = 0.0, mu_relative = 0.0;
};

// Compares every phase time and stroke with the truth; returns the largest errors.
Errors compare(const ts::Phases& p, const SynthRecording& c, const ts::testing::SynthOutput& truth) {
  Errors e;
  const auto time = [&](const char* what, double got, double want) {
    EXPECT_NEAR(got, want, kTimeTolerance_s) << what;
    e.time_s = std::max(e.time_s, std::abs(got - want));
  };
  time("contact start", p.contact_start_s, c.contact_s);
  time("loaded", p.loaded_s, c.loaded_s);
  time("release", p.release_s, c.release_s);
  time("contact end", p.contact_end_s, c.contact_end_s);
  EXPECT_EQ(p.strokes.size(), truth.strokes.size()) << codes(p.warnings);
  for (std::size_t k = 0; k < std::min(p.strokes.size(), truth.strokes.size()); ++k) {
    const auto& got = p.strokes[k];
    const auto& want = truth.strokes[k];
    time("slide start", got.slide_start_s, want.slide_start_s);
    time("slide end", got.slide_end_s, want.slide_end_s);
    const double mu_error = std::abs(got.mu_mean / want.mu_mean - 1.0);
    EXPECT_LT(mu_error, kMuTolerance) << "stroke " << k << ": mu " << got.mu_mean << " vs " << want.mu_mean;
    e.mu_relative = std::max(e.mu_relative, mu_error);
    EXPECT_EQ(got.direction, want.direction) << "stroke " << k;
  }
  return e;
}

}  // namespace

TEST(Phases, OneToFiveStrokesWithOffsetsDriftNoiseAndQuantisation) {
  for (int strokes = 1; strokes <= 5; ++strokes) {
    SCOPED_TRACE("strokes " + std::to_string(strokes));
    SynthRecording c;
    c.strokes = strokes;
    c.slide_into_release = strokes == 1;  // the finger lifts while still sliding
    c.seed = 11u + static_cast<unsigned>(strokes);
    const auto rec = ts::testing::synthesise(c);
    const auto p = ts::detect_phases(rec.t_s, rec.normal_N, rec.tangential_N, &rec.position_m, {});
    const Errors e = compare(p, c, rec);
    std::printf("[ measured ] %d stroke(s): largest phase-time error %.1f ms, largest mu error %.2f %%\n",
                strokes, 1e3 * e.time_s, 100.0 * e.mu_relative);
    EXPECT_TRUE(p.warnings.empty()) << codes(p.warnings);
    // The baseline is a line through the quiet stretches before and after the contact.
    EXPECT_EQ(p.tare.model, "linear");
    ASSERT_EQ(p.tare.quiet.size(), 2u);
    EXPECT_LT(p.tare.quiet[0].end_s, c.contact_s);
    EXPECT_GT(p.tare.quiet[1].start_s, c.contact_end_s);
    const double ref = p.tare.reference_s;
    EXPECT_NEAR(p.tare.normal.offset, c.offset_normal_N + c.drift_normal_N_s * ref, 1e-3);
    EXPECT_NEAR(p.tare.normal.drift_per_s, c.drift_normal_N_s, 5e-4);
    EXPECT_NEAR(p.tare.tangential.offset, c.offset_tangential_N + c.drift_tangential_N_s * ref, 1e-3);
    EXPECT_NEAR(p.tare.tangential.drift_per_s, c.drift_tangential_N_s, 5e-4);
    // The channel noise (4 mN) and the LSB (2 mN, σ 0.58 mN) seen as the scatter about the baseline.
    EXPECT_NEAR(p.tare.normal.residual_rms, std::hypot(c.noise_N, c.lsb_N / std::sqrt(12.0)), 5e-4);
    EXPECT_NEAR(p.normal_level_N, c.load_N, 5e-3);
  }
}

TEST(Phases, WithoutPositionTheDirectionComesFromTheTangentialForce) {
  SynthRecording c;
  c.strokes = 3;
  const auto rec = ts::testing::synthesise(c);
  const auto p = ts::detect_phases(rec.t_s, rec.normal_N, rec.tangential_N, nullptr, {});
  compare(p, c, rec);
  for (const auto& s : p.strokes) EXPECT_EQ(s.direction_source, "tangential");
}

TEST(Phases, NegativeGoingNormalForceIsANamedWarning) {
  SynthRecording c;
  c.normal_sign = -1;
  const auto rec = ts::testing::synthesise(c);
  const auto p = ts::detect_phases(rec.t_s, rec.normal_N, rec.tangential_N, nullptr, {});
  EXPECT_TRUE(has_warning(p.warnings, "normal_force_negative")) << codes(p.warnings);
  EXPECT_EQ(p.normal_sign, -1);
  EXPECT_NEAR(p.normal_level_N, -c.load_N, 5e-3);
  // The contact is still found; μ is not, because W < 0 is below the minimum normal force.
  EXPECT_NEAR(p.contact_start_s, c.contact_s, kTimeTolerance_s);
  EXPECT_NEAR(p.contact_end_s, c.contact_end_s, kTimeTolerance_s);
  EXPECT_TRUE(p.strokes.empty());
  EXPECT_TRUE(has_warning(p.warnings, "no_slide"));
  EXPECT_THROW(ts::analyse_friction_trial(rec.t_s, rec.normal_N, rec.tangential_N, nullptr, {}),
               tirstrain::Error);
}

TEST(Phases, OneQuietStretchRemovesTheOffsetAndSaysTheDriftIsNotSeen) {
  SynthRecording c;
  c.duration_s = 7.0;  // the record ends during the slide
  c.release_s = c.contact_end_s = 8.0;
  c.drift_normal_N_s = c.drift_tangential_N_s = 0.0;
  const auto rec = ts::testing::synthesise(c);
  const auto p = ts::detect_phases(rec.t_s, rec.normal_N, rec.tangential_N, nullptr, {});
  EXPECT_EQ(p.tare.model, "constant");
  EXPECT_TRUE(has_warning(p.warnings, "drift_not_observable"));
  EXPECT_TRUE(has_warning(p.warnings, "contact_until_record_end"));
  EXPECT_NEAR(p.tare.normal.offset, c.offset_normal_N, 1e-3);
  EXPECT_NEAR(p.tare.tangential.offset, c.offset_tangential_N, 1e-3);
  EXPECT_DOUBLE_EQ(p.release_s, rec.t_s.back());
  ASSERT_EQ(p.strokes.size(), 1u);
  EXPECT_DOUBLE_EQ(p.strokes[0].slide_end_s, rec.t_s.back());
}

TEST(Phases, GivenTareStretchAndRecordsInContactThroughout) {
  SynthRecording c;
  const auto rec = ts::testing::synthesise(c);
  ts::PhaseOptions given;
  given.tare = ts::TimeStretch{0.5, 1.5};
  const auto p = ts::detect_phases(rec.t_s, rec.normal_N, rec.tangential_N, nullptr, given);
  EXPECT_EQ(p.tare.source, "given");
  EXPECT_EQ(p.tare.model, "constant");
  EXPECT_NEAR(p.tare.normal.offset, c.offset_normal_N + c.drift_normal_N_s * 1.0, 1e-3);
  given.tare = ts::TimeStretch{1.5, 0.5};
  EXPECT_THROW(ts::detect_phases(rec.t_s, rec.normal_N, rec.tangential_N, nullptr, given), tirstrain::Error);

  // W constant from the first sample: the whole record is contact, nothing can be tared.
  std::vector<double> t, w, ft;
  for (int i = 0; i <= 2000; ++i) {
    t.push_back(i / 1000.0);
    w.push_back(2.0);
    ft.push_back(i < 500 ? 0.0 : 1.6);
  }
  const auto q = ts::detect_phases(t, w, ft, nullptr, {});
  EXPECT_TRUE(has_warning(q.warnings, "contact_from_record_start"));
  EXPECT_TRUE(has_warning(q.warnings, "not_tared"));
  EXPECT_EQ(q.tare.model, "none");
  ASSERT_EQ(q.strokes.size(), 1u);
  EXPECT_NEAR(q.strokes[0].mu_mean, 0.8, 1e-12);
  // Nothing ever touches: an error, not an empty result.
  EXPECT_THROW(ts::detect_phases(t, std::vector<double>(t.size(), 0.0), ft, nullptr, {}), tirstrain::Error);
}

// A tribometer recording as users meet it (8.5 s; press from 2.5 s; one slide from 4.54 s to the lift at
// 7.41 s; DAQ offsets; a lateral channel drifting before contact; μ wandering along the slide), analysed as a
// single loading-then-slip trial on the whole record (what goes wrong there is asserted first), then inside
// its phases.
TEST(FrictionTrial, RealRecordingAsOneTrialFailsAndInsideItsPhasesDoesNot) {
  SynthRecording c;
  c.fs_Hz = 5000.0;
  c.first_stroke_s = 4.44;
  c.slide_into_release = true;
  c.mu = {0.31};
  c.mu_wander = 0.15;
  c.mu_wander_period_s = 0.6;
  c.offset_normal_N = 2.0;  // W as recorded stays positive but shrinks on contact: offsets hide the sign
  c.normal_sign = -1;
  c.drift_tangential_N_s = 0.02;
  const auto rec = ts::testing::synthesise(c);
  const auto& slide = rec.strokes[0];

  // As recorded, whole record: the flattest high-|μ| stretch is the press (the slide wanders), full slip is
  // found after that plateau's end, and nothing says so.
  const auto mu = ts::friction_coefficient(rec.tangential_N, rec.normal_N, 0.05);
  const auto plateau = ts::detect_plateau(rec.t_s, mu.mu, mu.valid, {});
  ASSERT_TRUE(plateau);
  EXPECT_LT(plateau->end_s, slide.slide_start_s);
  const auto old_events = ts::detect_events(rec.t_s, rec.tangential_N, nullptr, {});
  EXPECT_GT(old_events.full_slip_s, plateau->end_s);
  // Offsets removed by hand and the sign flipped: the drifting lateral channel starts the "onset" during
  // the approach.
  std::vector<double> ft_hand = rec.tangential_N;
  double head = 0.0;
  for (std::size_t i = 0; rec.t_s[i] < 2.0; ++i) head += rec.tangential_N[i] / (2.0 * c.fs_Hz);
  for (double& v : ft_hand) v -= head;
  const auto hand = ts::detect_events(rec.t_s, ft_hand, nullptr, {});
  EXPECT_LT(hand.onset_s, c.contact_s);

  // Inside the phases (normal force inverted as the channel config says).
  std::vector<double> w = rec.normal_N;
  for (double& v : w) v = -v;
  const auto trial = ts::analyse_friction_trial(rec.t_s, w, rec.tangential_N, nullptr, {});
  const auto& p = trial.phases;
  ASSERT_EQ(p.strokes.size(), 1u) << codes(trial.warnings);
  EXPECT_TRUE(trial.warnings.empty()) << codes(trial.warnings);
  const auto& s = p.strokes[0];
  std::printf(
      "[ measured ] tribometer recording: slide %.4f-%.4f s (truth %.4f-%.4f), mu %.4f +- %.4f (truth %.4f, "
      "%+.2f "
      "%%); "
      "onset %.4f s, t90 %.4f s, full slip %.4f s\n",
      s.slide_start_s, s.slide_end_s, slide.slide_start_s, slide.slide_end_s, s.mu_mean, s.mu_sd,
      slide.mu_mean, 100.0 * (s.mu_mean / slide.mu_mean - 1.0), trial.events.onset_s, trial.events.fraction_s,
      trial.events.full_slip_s);
  EXPECT_NEAR(s.slide_start_s, slide.slide_start_s, kTimeTolerance_s);
  EXPECT_NEAR(s.slide_end_s, slide.slide_end_s, kTimeTolerance_s);
  EXPECT_NEAR(s.mu_mean / slide.mu_mean, 1.0, kMuTolerance);
  // μ wanders ±15 % along the slide: its spread is reported, not hidden.
  EXPECT_NEAR(s.mu_sd, 0.15 / std::sqrt(2.0) * slide.mu_mean, 0.01);
  // The tangential loading starts at 4.44 s; with no position the onset comes from F_t itself.
  EXPECT_GE(trial.events.onset_s, p.loaded_s);
  EXPECT_NEAR(trial.events.onset_s, c.first_stroke_s, 0.03);
  EXPECT_GT(trial.events.fraction_s, trial.events.onset_s);
  EXPECT_LE(trial.events.fraction_s, s.slide_start_s + kTimeTolerance_s);
  EXPECT_GE(trial.events.full_slip_s, trial.events.fraction_s);
  EXPECT_LE(trial.events.full_slip_s, s.slide_end_s);
  EXPECT_NEAR(trial.events.full_slip_s, slide.slide_start_s, kTimeTolerance_s);
}

TEST(FrictionTrial, EventsOnTheFirstStrokeWithPositionAndWork) {
  SynthRecording c;
  c.strokes = 2;
  const auto rec = ts::testing::synthesise(c);
  const auto trial = ts::analyse_friction_trial(rec.t_s, rec.normal_N, rec.tangential_N, &rec.position_m, {});
  EXPECT_TRUE(trial.warnings.empty()) << codes(trial.warnings);
  EXPECT_EQ(trial.events.onset_source, "position");
  // The plate starts at the first loading; onset is the last sample at rest.
  EXPECT_NEAR(trial.events.onset_s, c.first_stroke_s, 1e-3);
  // Cattaneo–Mindlin: 90 % of μW at u = 1 − 0.1^{2/3} of the loading time.
  const double t90 = c.first_stroke_s + (1.0 - std::pow(0.1, 2.0 / 3.0)) * c.loading_s;
  EXPECT_NEAR(trial.events.fraction_s, t90, 3e-3);
  ASSERT_TRUE(trial.events.external_work_J);
  EXPECT_GT(*trial.events.external_work_J, 0.0);
}

TEST(FrictionTrial, EventsOutsideThePhasesAreNamedWarnings) {
  // A position channel 0.3 s late (a wrong clock or a mis-wired channel): the plate "starts" after the
  // slide has begun, which the checks say instead of reporting an onset inside the slide silently.
  SynthRecording c;
  const auto rec = ts::testing::synthesise(c);
  const auto shift = static_cast<std::size_t>(0.3 * c.fs_Hz);
  std::vector<double> late(rec.position_m.size(), 0.0);
  for (std::size_t i = shift; i < late.size(); ++i) late[i] = rec.position_m[i - shift];
  const auto trial = ts::analyse_friction_trial(rec.t_s, rec.normal_N, rec.tangential_N, &late, {});
  EXPECT_TRUE(has_warning(trial.warnings, "onset_outside_loading")) << codes(trial.warnings);
  EXPECT_GT(trial.events.onset_s, trial.phases.strokes[0].slide_start_s);
  // The same recording with its own position: no warning.
  const auto good = ts::analyse_friction_trial(rec.t_s, rec.normal_N, rec.tangential_N, &rec.position_m, {});
  EXPECT_TRUE(good.warnings.empty()) << codes(good.warnings);
}

TEST(Phases, SlowLoadingStillEndsItsRiseAtFullSlip) {
  // A 0.3 s Cattaneo–Mindlin rise: the slope is 20 % of its steepest at 96 % of the slip distance, 12 ms
  // before full slip, longer than the search window for the steepest slope.
  SynthRecording c;
  c.strokes = 2;
  c.loading_s = 0.3;
  const auto rec = ts::testing::synthesise(c);
  const auto p = ts::detect_phases(rec.t_s, rec.normal_N, rec.tangential_N, &rec.position_m, {});
  const Errors e = compare(p, c, rec);
  std::printf("[ measured ] 0.3 s loading: largest phase-time error %.1f ms, largest mu error %.2f %%\n",
              1e3 * e.time_s, 100.0 * e.mu_relative);
}
