// The ridge period from the spectrum, against rendered ridges of known period: straight and whorled ridges,
// periods that fall anywhere between the spectrum's bins, at the working resolution the segmenter measures.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <iostream>

#include "contact/ridge_period.hpp"
#include "contact/segmenter.hpp"
#include "tir_render.hpp"

namespace tirstrain::contact {
namespace {

using test::TirScene;

TEST(RidgePeriod, FallsBetweenTheSpectrumsBinsWithinAPercent) {
  double worst = 0.0, sum = 0.0;
  int count = 0;
  for (bool whorl : {false, true})
    for (double period_px = 17.0; period_px <= 33.0; period_px += 0.8) {
      TirScene scene;
      scene.whorl = whorl;
      scene.period_px = period_px;
      scene.ridge_angle_rad = 0.3 + 0.05 * period_px;
      ContactSegmenter segmenter;
      segmenter.segment(test::render_tir(scene));
      ASSERT_TRUE(segmenter.period_measured());
      const double error = *segmenter.ridge_period_px() / period_px - 1.0;
      worst = std::max(worst, std::abs(error));
      sum += std::abs(error);
      ++count;
      std::cout << "  " << (whorl ? "whorl" : "straight") << " period " << period_px << " px: error "
                << 100.0 * error << " %\n";
    }
  std::cout << "  worst " << 100.0 * worst << " %, mean |error| " << 100.0 * sum / count << " %\n";
  // A bin of the unpadded working spectrum is 2-4 % of these periods.
  EXPECT_LE(worst, 0.012);
  EXPECT_LE(sum / count, 0.004);
}

}  // namespace
}  // namespace tirstrain::contact
