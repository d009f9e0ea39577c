#pragma once
// The scene's `strain:` section (strict: unknown keys are errors naming the file and key).
//
//   strain:
//     mode: exact                 # exact (F against the reference) | incremental (the paper's running sum)
//     stick_tolerance_px: 0.5     # a triangle is stuck when its centroid follows the plate this closely
//     stick_fit_extent: 0.95      # stick radius c (strain/stick_zone.hpp): fitted on tracks within this
//                                 # fraction of the contact radius
//     stick_fit_significance: 4   # slip detected when the fitted slip exceeds this × the residual RMS
//     min_area_px2: 2             # triangle quality criteria (strain/mesh.hpp)
//     min_angle_deg: 15
//     max_aspect: 10
//     map_cells: 65               # normalised maps: cells across the standard ellipse's [-1, 1] square
//     overlay: e1                 # component drawn on the overlay: exx, eyy, exy, e1, e2, energy
//     overlay_range: 0.2          # colour scale ±range (strain) or 0..range (energy density, J/m³)
#include <string>

#include "core/scene.hpp"
#include "strain/deformation.hpp"
#include "strain/stick_zone.hpp"

namespace tirstrain::strain {

enum class StrainMode { kExact, kIncremental };

struct StrainStageOptions {
  StrainOptions strain;         // quality criteria, tissue and calibration, stick tolerance
  StickZoneOptions stick_zone;  // the stick radius fit (`stick_fit_extent`, `stick_fit_significance`)
  StrainMode mode = StrainMode::kExact;  // `mode`: exact or incremental; default exact
  int map_cells = 65;                    // `map_cells`: normalised map cells across [-1, 1]; default 65
  std::string overlay = "e1";            // `overlay`: component drawn on the overlay; default e1
  double overlay_range = 0.2;  // `overlay_range`: colour scale ±range (strain) or 0..range (J/m³); 0.2
  // Throws Error naming the scene key of the first value out of range.
  void check() const;
};

// `mode_override` (e.g. from `--strain-mode`), if not empty, replaces the section's `mode`.
StrainStageOptions parse_strain_options(const Scene& scene, const std::string& mode_override = "");

const char* to_string(StrainMode mode);

}  // namespace tirstrain::strain
