#pragma once
// Polar histograms of axial directions (rose diagrams) for people to look at: sectors of [0, π) mirrored
// into [π, 2π) (θ and θ + π are the same axis), each sector's radius proportional to the square root of
// its share so that areas compare counts; angles drawn as in the image (from +x towards +y, y down), with
// the mean direction as a line. Several groups are overlaid in distinct colours.
#include <opencv2/core.hpp>

#include <string>
#include <vector>

namespace tirstrain {

struct RoseGroup {
  std::string label;
  std::vector<std::size_t> counts;  // per sector of [0, π)
  double mean_direction_rad = 0.0;  // drawn as a line through the centre
};

struct RoseOptions {
  std::string title;
  int radius_px = 200;  // radius of the largest sector
};

cv::Mat render_rose(const std::vector<RoseGroup>& groups, const RoseOptions& options);
// Renders and writes a PNG (temporary name, then rename); throws Error on failure.
void write_rose_png(const std::string& path, const std::vector<RoseGroup>& groups,
                    const RoseOptions& options);

}  // namespace tirstrain
