#include "contact/segmenter_options.hpp"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

#include "core/error.hpp"

namespace tirstrain::contact {
namespace {

[[noreturn]] void out_of_range(const char* field, double value, const std::string& range) {
  std::ostringstream message;
  message << "contact segmentation option " << field << " = " << value << " is out of range: " << range;
  ErrorContext context;
  context.key = field;
  throw Error(message.str(), context);
}

// NaN fails every comparison, so each test is written as "inside the range".
void at_least(const char* field, double value, double minimum) {
  if (value >= minimum && std::isfinite(value)) return;
  std::ostringstream range;
  range << "must be finite and >= " << minimum;
  out_of_range(field, value, range.str());
}

void positive(const char* field, double value) {
  if (!(value > 0.0 && std::isfinite(value))) out_of_range(field, value, "must be finite and > 0");
}

void fraction(const char* field, double value) {
  if (!(value >= 0.0 && value <= 1.0)) out_of_range(field, value, "must be in [0, 1]");
}

}  // namespace

void SegmenterOptions::check() const {
  positive("px_per_mm", px_per_mm);
  if (ridge_period_px) positive("ridge_period_px", *ridge_period_px);
  positive("default_period_mm", default_period_mm);
  positive("min_period_mm", min_period_mm);
  positive("max_period_mm", max_period_mm);
  if (!(max_period_mm > min_period_mm))
    out_of_range("max_period_mm", max_period_mm, "must be > min_period_mm");
  at_least("min_period_confidence", min_period_confidence, 0.0);
  if (polarity < -1 || polarity > 1) out_of_range("polarity", polarity, "must be -1, 0 or 1");
  at_least("downsample", downsample, 0);
  at_least("hull_points", hull_points, 3);
  at_least("block_px", block_px, 1);
  if (exclude_px && (exclude_px->width < 0 || exclude_px->height < 0))
    out_of_range("exclude_px", std::min(exclude_px->width, exclude_px->height),
                 "width and height must be >= 0");
  at_least("min_area_mm2", min_area_mm2, 0.0);
  at_least("min_energy_ratio", min_energy_ratio, 0.0);
  at_least("min_energy", min_energy, 0.0);
  at_least("merge_fraction", merge_fraction, 0.0);
  at_least("merge_gap_periods", merge_gap_periods, 0.0);
  fraction("saturated_fraction", saturated_fraction);
  at_least("border_average_snr", border_average_snr, 0.0);
  at_least("border_average_periods", border_average_periods, 0.0);
  fraction("crest_edge_level", crest_edge_level);
  fraction("edge_level", edge_level);
  at_least("valley_gap_periods", valley_gap_periods, 0.0);
  at_least("spike_periods", spike_periods, 0.0);
  at_least("small_contact_periods", small_contact_periods, 0.0);
  at_least("ridge_label_below_periods", ridge_label_below_periods, 0.0);
  fraction("ridge_label_shape_weight", ridge_label_shape_weight);
  at_least("low_contrast", low_contrast, 0.0);
  at_least("full_frame_every", full_frame_every, 1);
  at_least("region_margin_periods", region_margin_periods, 0.0);
  at_least("region_margin_fraction", region_margin_fraction, 0.0);
}

SegmenterOptions with_preset(SegmenterOptions options, SegmentationPreset preset) {
  const SegmenterOptions accurate;
  options.flat_field = accurate.flat_field;
  options.border_average_snr = accurate.border_average_snr;
  options.ridge_label_centre = accurate.ridge_label_centre;
  options.ridge_label_below_periods = accurate.ridge_label_below_periods;
  options.ridge_label_shape_weight = accurate.ridge_label_shape_weight;
  options.border_band_centre = preset == SegmentationPreset::accurate;
  if (preset == SegmentationPreset::fast) {
    options.flat_field = false;
    options.border_average_snr = 0.0;
    options.ridge_label_centre = false;
    options.ridge_label_below_periods = 0.0;
  }
  return options;
}

}  // namespace tirstrain::contact
