#include "strain/settings.hpp"

#include "core/error.hpp"
#include "core/yaml_reader.hpp"

namespace tirstrain::strain {

const char* to_string(StrainMode mode) {
  return mode == StrainMode::kIncremental ? "incremental" : "exact";
}

StrainStageSettings parse_strain_settings(const Scene& scene, const std::string& mode_override) {
  StrainStageSettings s;
  s.strain.px_per_mm = scene.px_per_mm;
  s.strain.young_Pa = scene.tissue.young_Pa;
  s.strain.poisson = scene.tissue.poisson;
  s.strain.depth_m = scene.tissue.depth_m;
  YamlSection y(scene.strain, scene.file, "strain");
  std::string mode = y.choice("mode", "exact", {"exact", "incremental"});
  if (!mode_override.empty()) {
    if (mode_override != "exact" && mode_override != "incremental")
      throw Error("unknown strain mode '" + mode_override + "' (exact or incremental)");
    mode = mode_override;
  }
  s.mode = mode == "incremental" ? StrainMode::kIncremental : StrainMode::kExact;
  s.strain.stick_tolerance_px = y.number("stick_tolerance_px", s.strain.stick_tolerance_px, 0.0, 1000.0);
  s.stick_zone.extent = y.number("stick_fit_extent", s.stick_zone.extent, 0.1, 1.0);
  s.stick_zone.significance = y.number("stick_fit_significance", s.stick_zone.significance, 0.0, 1e6);
  s.strain.quality.min_area_px2 = y.number("min_area_px2", s.strain.quality.min_area_px2, 0.0, 1e9);
  s.strain.quality.min_angle_deg = y.number("min_angle_deg", s.strain.quality.min_angle_deg, 0.0, 59.9);
  s.strain.quality.max_aspect = y.number("max_aspect", s.strain.quality.max_aspect, 1.0, 1e6);
  s.map_cells = static_cast<int>(y.integer("map_cells", s.map_cells, 3, 1001));
  s.overlay = y.choice("overlay", s.overlay, {"exx", "eyy", "exy", "e1", "e2", "energy"});
  s.overlay_range = y.number("overlay_range", s.overlay_range, 1e-12, 1e12);
  y.finish();
  return s;
}

}  // namespace tirstrain::strain
