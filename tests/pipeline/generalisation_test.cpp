// The tracking generalisation benchmark (pipeline/generalisation.hpp) at the small test sizes: the chirp's
// resolution measure against exact displacements, and the default (auto) preset on every case, both
// textures, 0.5 % noise, each against an error bound about 1.5-2x what it measures.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "pipeline/generalisation.hpp"
#include "samples/generalisation.hpp"

namespace tirstrain::pipeline {
namespace {

using samples::GeneralisationField;
using samples::GeneralisationTexture;

GeneralisationResult run_case(GeneralisationField field, GeneralisationTexture texture) {
  const samples::GeneralisationCase sequence(samples::generalisation_config(field, texture, 0.005, true));
  std::vector<cv::Mat> frames;
  for (int k = 0; k < sequence.frames(); ++k)
    frames.push_back(sequence.add_noise(sequence.render_clean(k), k));
  GeneralisationResult r = run_generalisation(sequence, frames, "auto");
  std::printf(
      "[ measured ] %s/%s: %d seeded, %.0f alive, RMS %.4f px, bias %.4f px, max %.3f px, resolution %.1f px "
      "(%.2f radii), long-wave RMS %.4f px, %d rest frames\n",
      r.field.c_str(), r.texture.c_str(), r.seeded, r.alive_mean, r.rms_px, r.bias_px, r.max_px,
      r.resolution_px, r.resolution_radii, r.long_wave_rms_px, r.rest_frames);
  EXPECT_GT(r.seeded, 0);
  return r;
}

TEST(Generalisation, ChirpResolutionOfTheExactFieldIsItsShortestWindow) {
  // Exact displacements reproduce every window's amplitude (gain 1, quadrature 0) down to the shortest
  // wavelength the 10 px grid samples (2.5 steps per wavelength).
  const samples::GeneralisationCase sequence(samples::generalisation_config(
      GeneralisationField::kChirp, GeneralisationTexture::kSpeckle, 0.0, true));
  std::vector<Vec2> X;
  std::vector<double> u;
  for (double y = 15.0; y < 80.0; y += 10.0)
    for (double x = 15.0; x < 497.0; x += 10.0) {
      X.push_back({x, y});
      u.push_back(sequence.field({x, y}, 1).displacement_px.x);
    }
  const ChirpResolution r = chirp_resolution(sequence, X, u, 0.9);
  ASSERT_GT(r.windows.size(), 10u);
  for (const ChirpWindow& w : r.windows) {
    EXPECT_NEAR(w.gain, 1.0, 1e-9) << w.wavelength_px;
    EXPECT_NEAR(w.quadrature, 0.0, 1e-9) << w.wavelength_px;
  }
  EXPECT_EQ(r.resolved_wavelength_px, r.windows.back().wavelength_px);
  EXPECT_LT(r.resolved_wavelength_px, 27.0);
  EXPECT_GE(r.resolved_wavelength_px, 25.0);
}

TEST(Generalisation, ChirpResolutionIsWhereTheGainFirstFallsBelowTheThreshold) {
  // A field whose measured amplitude halves below 60 px: the resolution lies between the last window
  // above 60 px and the first below.
  const samples::GeneralisationCase sequence(samples::generalisation_config(
      GeneralisationField::kChirp, GeneralisationTexture::kSpeckle, 0.0, true));
  std::vector<Vec2> X;
  std::vector<double> u;
  for (double x = 15.0; x < 497.0; x += 2.0)
    for (double y = 15.0; y < 80.0; y += 10.0) {
      X.push_back({x, y});
      const double gain = sequence.chirp_wavelength_px(x) >= 60.0 ? 1.0 : 0.5;
      u.push_back(gain * sequence.field({x, y}, 1).displacement_px.x);
    }
  const ChirpResolution r = chirp_resolution(sequence, X, u, 0.9);
  EXPECT_GT(r.resolved_wavelength_px, 50.0);
  EXPECT_LT(r.resolved_wavelength_px, 75.0);
}

struct Bound {
  GeneralisationTexture texture;
  double rms_px;
};

// Runs the case on both textures and checks each RMS error against its bound; at least 60 % of the seeded
// tracks stay alive on average (the stretch and the shifts carry some out of the frame).
void expect_within(GeneralisationField field, const Bound (&bounds)[2]) {
  for (const Bound& b : bounds) {
    const GeneralisationResult r = run_case(field, b.texture);
    EXPECT_LT(r.rms_px, b.rms_px) << r.field << "/" << r.texture;
    EXPECT_GT(r.alive_mean, 0.6 * r.seeded) << r.field << "/" << r.texture;
  }
}

// Bounds: RMS of (x_t - X) - u(X) over every track-frame after frame 0, auto preset, 0.5 % noise, 192 x 128
// (the chirp 512 x 96). Measured (px): speckle / fingerprint in each comment.

TEST(Generalisation, SubpixelShiftsAutoPreset) {
  // 0.0116 / 0.021; no frame is taken for rest (a 0.05 px shift is a motion the rest test sees).
  expect_within(GeneralisationField::kSubpixelShift,
                {{GeneralisationTexture::kSpeckle, 0.02}, {GeneralisationTexture::kFingerprint, 0.04}});
}

TEST(Generalisation, IntegerShiftsAutoPreset) {
  // 0.0072 / 0.019, jumps of 8-12 px between frames caught by the global shift.
  expect_within(GeneralisationField::kIntegerShift,
                {{GeneralisationTexture::kSpeckle, 0.013}, {GeneralisationTexture::kFingerprint, 0.033}});
}

TEST(Generalisation, ChirpAutoPreset) {
  // 0.060 / 0.071 over all wavelengths (10-200 px at this size; the short ones are beyond any 13 px
  // subset). The chirp frame is not taken for rest: an affine fit, which holds none of the 0.1 px sine,
  // would make the error the field's own RMS everywhere, A / sqrt(2) = 0.071 px, and the gain at the long
  // wavelengths ~0. Measured: resolution 76 / 84 px (5.9 / 6.5 subset radii), RMS over wavelengths ≥ 10
  // radii 0.0127 / 0.0270 px.
  expect_within(GeneralisationField::kChirp,
                {{GeneralisationTexture::kSpeckle, 0.09}, {GeneralisationTexture::kFingerprint, 0.10}});
  for (const GeneralisationTexture texture :
       {GeneralisationTexture::kSpeckle, GeneralisationTexture::kFingerprint}) {
    const GeneralisationResult r = run_case(GeneralisationField::kChirp, texture);
    EXPECT_EQ(r.rest_frames, 0) << r.texture;
    EXPECT_LT(r.resolution_px, 110.0) << r.texture;
    EXPECT_LT(r.long_wave_rms_px, texture == GeneralisationTexture::kSpeckle ? 0.02 : 0.04) << r.texture;
  }
}

TEST(Generalisation, StepAutoPreset) {
  // 0.032 / 0.059, most of it in the narrowest steps (w = 20 px, shear up to 0.25).
  expect_within(GeneralisationField::kStep,
                {{GeneralisationTexture::kSpeckle, 0.06}, {GeneralisationTexture::kFingerprint, 0.10}});
}

TEST(Generalisation, StretchAutoPreset) {
  // 0.0075 / 0.034 over 6 frames to 45 %.
  expect_within(GeneralisationField::kStretch,
                {{GeneralisationTexture::kSpeckle, 0.015}, {GeneralisationTexture::kFingerprint, 0.06}});
}

TEST(Generalisation, RotationAutoPreset) {
  // 0.033 / 0.051 over 6 frames to 10 deg.
  expect_within(GeneralisationField::kRotation,
                {{GeneralisationTexture::kSpeckle, 0.06}, {GeneralisationTexture::kFingerprint, 0.09}});
}

TEST(Generalisation, CreepAutoPreset) {
  // 0.0085 / 0.016; on the fingerprint the first frame (0.02 px of creep, below the matches' noise) is
  // taken for rest, on the speckle none.
  expect_within(GeneralisationField::kCreep,
                {{GeneralisationTexture::kSpeckle, 0.015}, {GeneralisationTexture::kFingerprint, 0.03}});
}

}  // namespace
}  // namespace tirstrain::pipeline
