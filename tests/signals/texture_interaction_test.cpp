// model/texture_interaction: v/λ, zone naming, and properties of the overlap model that hold exactly.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "model/texture_interaction.hpp"

namespace tmodel = tirstrain::model;

TEST(TextureInteraction, PredictedFrequencyIsSpeedOverWavelength) {
  EXPECT_DOUBLE_EQ(tmodel::predicted_vibration_frequency_Hz(0.1, 0.5e-3), 200.0);
  EXPECT_THROW(tmodel::predicted_vibration_frequency_Hz(0.1, 0.0), std::invalid_argument);
}

TEST(TextureInteraction, ZonesRelativeToRidgePeriod) {
  EXPECT_EQ(tmodel::classify_texture(0.2e-3, 0.45e-3), tmodel::TextureZone::finer_than_ridges);
  EXPECT_EQ(tmodel::classify_texture(0.5e-3, 0.45e-3), tmodel::TextureZone::comparable_to_ridges);
  EXPECT_EQ(tmodel::classify_texture(2e-3, 0.45e-3), tmodel::TextureZone::coarser_than_ridges);
}

TEST(TextureInteraction, OverlapIsPeriodicAndCoarseSurfacesVibrateAtVOverLambda) {
  tmodel::TextureInteractionParams p;
  p.surface_wavelength_m = 2.0e-3;  // coarser than the 0.45 mm ridges
  const auto s = tmodel::overlap_area(p);
  EXPECT_NEAR(s.time_s[1] * s.time_s.size(), p.surface_wavelength_m / p.speed_m_s, 1e-12);
  const auto pred = tmodel::predict_interaction(p);
  EXPECT_EQ(pred.zone, tmodel::TextureZone::coarser_than_ridges);
  EXPECT_EQ(pred.peak_harmonic, 1u);
  EXPECT_DOUBLE_EQ(pred.peak_frequency_Hz, p.speed_m_s / p.surface_wavelength_m);
  EXPECT_GT(pred.mean_area_m2, 0.0);
  // Zero gap (interpenetration 1): A = ∫(h_f + h_s)dx in closed form. L = 10 mm holds 5 surface wavelengths
  // (surface term exactly a_s·L/2 at every t, so no vibration) but 22.2 ridge periods (the ridge term keeps
  // its partial-period remainder).
  tmodel::TextureInteractionParams full = p;
  full.interpenetration = 1.0;
  const auto flat = tmodel::predict_interaction(full);
  const double two_pi = 2.0 * 3.14159265358979323846;
  const double ridge_term =
      0.5 * p.ridge_amplitude_m *
      (p.contact_length_m +
       p.ridge_period_m / two_pi * std::sin(two_pi * p.contact_length_m / p.ridge_period_m));
  EXPECT_NEAR(flat.mean_area_m2, ridge_term + 0.5 * p.surface_amplitude_m * p.contact_length_m,
              1e-4 * flat.mean_area_m2);
  EXPECT_LT(flat.modulation_m2, 1e-6 * flat.mean_area_m2);
}

TEST(TextureInteraction, MatchedWavelengthsModulateMostStrongly) {
  // Ridges and a surface of the same period come in and out of register together over the whole contact,
  // so the overlap swings far more than for a surface much finer than the ridges, which averages out.
  tmodel::TextureInteractionParams p;
  const auto sweep = tmodel::sweep_surface_wavelength(p, {0.1e-3, 0.45e-3});
  EXPECT_EQ(sweep[1].zone, tmodel::TextureZone::comparable_to_ridges);
  EXPECT_GT(sweep[1].modulation_m2, 5.0 * sweep[0].modulation_m2);
  for (const auto& r : sweep) EXPECT_NEAR(std::fmod(r.peak_frequency_Hz, r.surface_frequency_Hz), 0.0, 1e-9);
}

TEST(TextureInteraction, LinesAreTheHarmonicsOfVOverLambdaAndThePeakIsTheStrongest) {
  tirstrain::model::TextureInteractionParams p;
  p.surface_wavelength_m = 0.2e-3;
  p.speed_m_s = 0.05;
  const auto r = tirstrain::model::predict_interaction(p);
  ASSERT_EQ(r.lines.size(), p.samples_per_period / 2);
  double strongest = 0.0;
  for (const auto& line : r.lines) {
    EXPECT_NEAR(line.frequency_Hz, static_cast<double>(line.harmonic) * 250.0, 1e-9);
    strongest = std::max(strongest, line.amplitude_m2);
  }
  EXPECT_EQ(strongest, r.modulation_m2);
  EXPECT_EQ(r.lines[r.peak_harmonic - 1].amplitude_m2, r.modulation_m2);
}
