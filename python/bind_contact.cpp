// tirstrain.segment: contact segmentation (contact/) of one frame, options by SegmenterOptions' field names.
#include <pybind11/stl.h>

#include <map>
#include <string>
#include <variant>

#include "contact/segmenter.hpp"
#include "core/error.hpp"
#include "python/arrays.hpp"
#include "python/bindings.hpp"

namespace tirstrain::python {

namespace {

using contact::SegmenterOptions;
using Field = std::variant<double SegmenterOptions::*, int SegmenterOptions::*, bool SegmenterOptions::*>;

// The options a caller may set, by their SegmenterOptions name (contact/segmenter_options.hpp documents
// each).
const std::map<std::string, Field>& option_fields() {
  static const std::map<std::string, Field> fields = {
      {"px_per_mm", &SegmenterOptions::px_per_mm},
      {"default_period_mm", &SegmenterOptions::default_period_mm},
      {"min_period_mm", &SegmenterOptions::min_period_mm},
      {"max_period_mm", &SegmenterOptions::max_period_mm},
      {"min_period_confidence", &SegmenterOptions::min_period_confidence},
      {"polarity", &SegmenterOptions::polarity},
      {"downsample", &SegmenterOptions::downsample},
      {"hull_points", &SegmenterOptions::hull_points},
      {"block_px", &SegmenterOptions::block_px},
      {"orientation", &SegmenterOptions::orientation},
      {"min_area_mm2", &SegmenterOptions::min_area_mm2},
      {"min_energy_ratio", &SegmenterOptions::min_energy_ratio},
      {"min_energy", &SegmenterOptions::min_energy},
      {"merge_fraction", &SegmenterOptions::merge_fraction},
      {"merge_gap_periods", &SegmenterOptions::merge_gap_periods},
      {"saturated_fraction", &SegmenterOptions::saturated_fraction},
      {"flat_field", &SegmenterOptions::flat_field},
      {"border_average_snr", &SegmenterOptions::border_average_snr},
      {"border_average_periods", &SegmenterOptions::border_average_periods},
      {"crest_edge_level", &SegmenterOptions::crest_edge_level},
      {"edge_level", &SegmenterOptions::edge_level},
      {"valley_gap_periods", &SegmenterOptions::valley_gap_periods},
      {"spike_periods", &SegmenterOptions::spike_periods},
      {"small_contact_periods", &SegmenterOptions::small_contact_periods},
      {"ridge_label_below_periods", &SegmenterOptions::ridge_label_below_periods},
      {"ridge_label_centre", &SegmenterOptions::ridge_label_centre},
      {"ridge_label_shape_weight", &SegmenterOptions::ridge_label_shape_weight},
      {"border_band_centre", &SegmenterOptions::border_band_centre},
      {"small_contact_ellipse_outline", &SegmenterOptions::small_contact_ellipse_outline},
      {"low_contrast", &SegmenterOptions::low_contrast},
  };
  return fields;
}

contact::SegmentationPreset parse_preset(const std::string& name) {
  if (name == "accurate") return contact::SegmentationPreset::accurate;
  if (name == "balanced") return contact::SegmentationPreset::balanced;
  if (name == "fast") return contact::SegmentationPreset::fast;
  throw Error("unknown preset '" + name + "' (use accurate, balanced or fast)", {.key = "preset"});
}

// The preset first, then every other option on top of it, then the ranges checked.
SegmenterOptions parse_options(const py::kwargs& kwargs) {
  SegmenterOptions options;
  if (kwargs.contains("preset"))
    options = contact::with_preset(options, parse_preset(py::cast<std::string>(kwargs["preset"])));
  for (const auto& [key_handle, value] : kwargs) {
    const std::string key = py::cast<std::string>(key_handle);
    if (key == "preset") continue;
    // A value of the wrong type names its keyword, as a range error does.
    try {
      if (key == "ridge_period_px") {
        options.ridge_period_px = value.is_none() ? std::nullopt : std::optional(py::cast<double>(value));
        continue;
      }
      const auto field = option_fields().find(key);
      if (field == option_fields().end()) throw Error("unknown segmentation option", {.key = key});
      std::visit(
          [&](auto member) {
            options.*member = py::cast<std::remove_reference_t<decltype(options.*member)>>(value);
          },
          field->second);
    } catch (const py::cast_error&) {
      throw Error(
          "expected a number or a flag, got " + std::string(py::str(py::type::of(value).attr("__name__"))),
          {.key = key});
    }
  }
  options.check();
  return options;
}

py::object ellipse_dict(const std::optional<contact::Ellipse>& e) {
  if (!e) return py::none();
  py::dict d;
  d["cx_px"] = e->cx_px;
  d["cy_px"] = e->cy_px;
  d["semi_major_px"] = e->semi_major_px;
  d["semi_minor_px"] = e->semi_minor_px;
  d["angle_rad"] = e->angle_rad;
  return d;
}

py::dict segment(const py::object& frame, const py::kwargs& kwargs) {
  const SegmenterOptions options = parse_options(kwargs);
  const ImageView view = image_view(frame, "frame");
  contact::ContactResult r;
  {
    py::gil_scoped_release release;
    contact::ContactSegmenter segmenter(options);
    r = segmenter.segment(view.mat);
  }
  auto hull = new_array<double>({static_cast<py::ssize_t>(r.hull_px.size()), 2});
  for (std::size_t i = 0; i < r.hull_px.size(); ++i) {
    hull.mutable_at(static_cast<py::ssize_t>(i), 0) = r.hull_px[i].x;
    hull.mutable_at(static_cast<py::ssize_t>(i), 1) = r.hull_px[i].y;
  }
  py::dict out;
  out["hull_px"] = hull;
  out["ellipse"] = ellipse_dict(r.ellipse);
  out["area_mm2"] = r.area_mm2;
  out["status"] = r.status;
  out["status_text"] = contact::contact_status_text(r.status);
  out["ridge_period_px"] = r.ridge_period_px;
  return out;
}

}  // namespace

void bind_contact(py::module_& m) {
  using namespace py::literals;
  m.def("segment", &segment, "frame"_a,
        "Segments the contact in one frame (2-D uint8, uint16 or float32 NumPy array) with contact/.\n"
        "Keyword options: preset (accurate, balanced, fast) and any field of SegmenterOptions by name\n"
        "(px_per_mm, ridge_period_px, polarity, hull_points, min_area_mm2, ...;\n"
        "contact/segmenter_options.hpp). Returns a dict: hull_px [M, 2] (empty without contact), ellipse\n"
        "(cx_px, cy_px, semi_major_px, semi_minor_px, angle_rad; None when none was fitted), area_mm2,\n"
        "status (ContactFlag bits), status_text and ridge_period_px.");
}

}  // namespace tirstrain::python
