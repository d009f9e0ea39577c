#pragma once
// What a report shows of one `tirstrain process` result folder, read from its result.h5 and summary.json:
// per-frame series (contact, tracks, forces, energy, stick, fit), the normalised strain maps at the key
// instants, and the angles of the polar histograms. Series a stage did not write are left empty.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace tirstrain::report {

// A key instant of the trial and where its frame came from.
struct Instant {
  std::string name;    // "onset", "t90", "full_slip", or a fallback's name ("last frame")
  long frame = -1;     // result row
  double t_s = 0.0;    // its timestamp
  std::string source;  // "force channels (/events)", "model fit (/fit)", or why a fallback was taken
};

// The strain maps of one instant on the standard ellipse (docs/formats.md, `/maps`): cells × cells values
// row-major (rows = normalised y), NaN outside the mesh.
struct StrainMaps {
  Instant instant;
  int cells = 0;
  double aspect = 1.0;                         // semi-minor / semi-major of the reference ellipse
  double axes_angle_rad = 0.0;                 // the map's +x in the image (0: the image's axes)
  std::vector<std::vector<double>> component;  // E_xx, E_yy, E_xy, e1, e2 (kMapComponents order)
  double covered_fraction = 0.0;               // finite cells among those inside the ellipse
};

inline constexpr const char* kMapComponents[] = {"E_xx", "E_yy", "E_xy", "e1", "e2"};

// Axial angles (rad, from +x towards +y, in [0, π)) with a weight each, for a polar histogram.
struct AngleSet {
  std::string what;  // e.g. "principal direction of e1 at t90"
  std::vector<double> angle_rad;
  std::vector<double> weight;
};

struct ResultData {
  std::string label;             // how figures name this result (its folder's name)
  std::string dir;               // the folder as given
  std::string software_version;  // result.h5 root attribute
  bool time_measured = true;     // false: t_s is the frame number (the input had no clock)
  std::string stages;            // comma-separated stages run
  std::string input;             // what was processed
  std::string scene_yaml;        // the scene in effect
  nlohmann::json summary;        // summary.json as written by process (empty object when missing)

  std::vector<double> t_s;                                     // every frame's timestamp, s
  std::vector<double> area_mm2, semi_major_mm, semi_minor_mm;  // NaN without a contact or ellipse
  std::vector<double> tracks_alive, tracks_born, tracks_retired;
  std::vector<double> normal_N, tangential_N, mu;       // NaN outside the channel's span (or W too small)
  std::vector<double> energy_J, energy_ratio;           // U and U / U_ext (cumulative external work)
  std::vector<double> stick_ratio, stick_radius_ratio;  // stuck area fraction and c/a of the stick fit
  // The tracks' reach over a on frames where c is not measured (the stuck core moved but no slip showed
  // within the tracks: /stick/radius_status 3), NaN elsewhere.
  std::vector<double> stick_unmeasured_reach;
  std::vector<double> fit_c_of_a, fit_tangential_N;  // the model fit (/fit), NaN where not fitted
  std::vector<std::string> fit_model;                // the fit's chosen field per frame ("" not fitted)
  double energy_ratio_at_t90 = 0.0;                  // /work/energy_ratio, NaN when absent
  std::vector<Instant> instants;
  std::vector<StrainMaps> maps;  // one per instant with maps
  AngleSet principal_directions;
  AngleSet ridge_orientation;
};

struct ReadOptions {
  double min_principal_difference = 1e-3;  // triangles whose e1 − e2 is below this have no direction
  double min_ridge_coherence = 0.3;        // ridge blocks less coherent than this are left out
};

// Reads a process output folder (or a result.h5 path). Throws Error naming the file and what is missing.
// The result.h5 of a result folder (or the file given); throws Error naming the path when there is none.
std::string result_file_of(const std::string& path);
// Throws Error naming the file when it is not a result of `tirstrain process`.
ResultData read_result(const std::string& path, const ReadOptions& options = {});

}  // namespace tirstrain::report
