#include "strain/settings.hpp"

#include "core/error.hpp"
#include "core/yaml_reader.hpp"

namespace tirstrain::strain {

const char* to_string(StrainMode mode) {
  return mode == StrainMode::kIncremental ? "incremental" : "exact";
}

StrainStageOptions parse_strain_options(const Scene& scene, const std::string& mode_override) {
  StrainStageOptions s;
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
  s.check();
  return s;
}

namespace {

[[noreturn]] void fail(const std::string& key, const std::string& message) {
  throw Error(message, {.key = "strain." + key});
}

}  // namespace

void QualityCriteria::check() const {
  if (!(min_area_px2 >= 0.0)) fail("min_area_px2", "must not be negative");
  if (!(min_angle_deg >= 0.0 && min_angle_deg < 60.0)) fail("min_angle_deg", "must lie in [0, 60) degrees");
  if (!(max_aspect >= 1.0)) fail("max_aspect", "must be at least 1");
}

void StrainOptions::check() const {
  quality.check();
  if (!(px_per_mm > 0.0)) throw Error("must be positive", {.key = "px_per_mm"});
  if (!(young_Pa > 0.0)) throw Error("must be positive", {.key = "tissue.E_Pa"});
  if (!(poisson > -1.0 && poisson < 0.5)) throw Error("must lie in (-1, 0.5)", {.key = "tissue.nu"});
  if (!(depth_m > 0.0)) throw Error("must be positive", {.key = "tissue.depth_m"});
  if (!(stick_tolerance_px >= 0.0)) fail("stick_tolerance_px", "must not be negative");
}

void StickZoneOptions::check() const {
  if (!(extent > 0.0 && extent <= 1.0)) fail("stick_fit_extent", "must lie in (0, 1]");
  if (!(significance >= 0.0)) fail("stick_fit_significance", "must not be negative");
  if (!(min_slip_px >= 0.0 && chi2_slip >= 0.0 && chi2_stick >= 0.0))
    fail("stick_fit", "thresholds must not be negative");
  if (min_points < 3) fail("stick_fit", "needs at least 3 points");
  if (grid < 2) fail("stick_fit", "needs a k grid of at least 2");
}

void StrainStageOptions::check() const {
  strain.check();
  stick_zone.check();
  if (map_cells < 3) fail("map_cells", "must be at least 3");
  if (!(overlay_range > 0.0)) fail("overlay_range", "must be positive");
}

}  // namespace tirstrain::strain
