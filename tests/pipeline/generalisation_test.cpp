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

}  // namespace
}  // namespace tirstrain::pipeline
