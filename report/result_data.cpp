#include "report/result_data.hpp"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>

#include "core/error.hpp"
#include "core/h5_file.hpp"

namespace tirstrain::report {
namespace {

namespace fs = std::filesystem;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

std::string label_of(const std::string& result_file) {
  const fs::path folder = fs::path(result_file).parent_path();
  const std::string name = folder.filename().string();
  return name.empty() ? fs::absolute(folder).filename().string() : name;
}

std::string text_attribute(const H5Reader& h5, const std::string& name) {
  try {
    return h5.attribute_text("/", name);
  } catch (const Error&) {
    return "";
  }
}

nlohmann::json read_summary(const fs::path& folder) {
  std::ifstream in(folder / "summary.json");
  if (!in) return nlohmann::json::object();
  auto parsed = nlohmann::json::parse(in, nullptr, false);
  return parsed.is_object() ? parsed : nlohmann::json::object();
}

std::vector<double> optional_series(const H5Reader& h5, const std::string& name) {
  return h5.has(name) ? h5.read_doubles(name) : std::vector<double>{};
}

void read_identity(const H5Reader& h5, ResultData& r) {
  r.software_version = text_attribute(h5, "software_version");
  if (h5.has_attribute("/frames", "time_measured"))
    r.time_measured = h5.attribute_number("/frames", "time_measured") > 0.0;
  r.stages = text_attribute(h5, "stages");
  r.input = text_attribute(h5, "input");
  r.scene_yaml = text_attribute(h5, "scene_yaml");
  r.summary = read_summary(fs::path(h5.path()).parent_path());
}

double px_per_mm_of(const H5Reader& h5) {
  try {
    return h5.attribute_number("/contact", "px_per_mm");
  } catch (const Error&) {
    return kNaN;
  }
}

void read_contact(const H5Reader& h5, ResultData& r) {
  r.area_mm2 = optional_series(h5, "/contact/area_mm2");
  // 0 mm² is how result.h5 marks a frame without contact: a gap in the plot, not a contact of no area.
  for (double& a : r.area_mm2)
    if (a == 0.0) a = kNaN;
  if (!h5.has("/contact/ellipse")) return;
  const double px_per_mm = px_per_mm_of(h5);
  const auto ellipse = h5.read_doubles("/contact/ellipse");
  const std::size_t n = ellipse.size() / 5;
  r.semi_major_mm.assign(n, kNaN);
  r.semi_minor_mm.assign(n, kNaN);
  for (std::size_t i = 0; i < n; ++i) {
    if (ellipse[i * 5 + 2] <= 0.0) continue;  // no ellipse in this frame: zeros in the file
    r.semi_major_mm[i] = ellipse[i * 5 + 2] / px_per_mm;
    r.semi_minor_mm[i] = ellipse[i * 5 + 3] / px_per_mm;
  }
}

// Alive, born and retired per frame from each track's birth and retirement rows (a track is not alive in
// the frame that retires it; the reference frame's seeding counts as births).
void read_tracks(const H5Reader& h5, ResultData& r) {
  if (!h5.has("/tracks/born_frame")) return;
  const auto born = h5.read_integers("/tracks/born_frame");
  const auto retired = h5.read_integers("/tracks/retired_frame");
  const std::size_t n = r.t_s.size();
  std::vector<double> births(n + 1, 0.0), retirements(n + 1, 0.0);
  for (std::size_t k = 0; k < born.size(); ++k) {
    if (born[k] >= 0 && static_cast<std::size_t>(born[k]) < n) births[static_cast<std::size_t>(born[k])] += 1;
    if (retired[k] >= 0 && static_cast<std::size_t>(retired[k]) < n)
      retirements[static_cast<std::size_t>(retired[k])] += 1;
  }
  r.tracks_born.assign(births.begin(), births.begin() + static_cast<long>(n));
  r.tracks_retired.assign(retirements.begin(), retirements.begin() + static_cast<long>(n));
  r.tracks_alive.assign(n, 0.0);
  double alive = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    alive += births[i] - retirements[i];
    r.tracks_alive[i] = alive;
  }
}

// A channel at the frames, NaN where the frame lies outside the record (the file writes 0 there).
std::vector<double> channel_at_frames(const H5Reader& h5, const std::string& name,
                                      const std::vector<double>& in_span) {
  const std::string path = "/channels/at_frames/" + name;
  if (!h5.has(path)) return {};
  auto values = h5.read_doubles(path);
  for (std::size_t i = 0; i < values.size() && i < in_span.size(); ++i)
    if (in_span[i] == 0.0) values[i] = kNaN;
  return values;
}

void read_channels(const H5Reader& h5, ResultData& r) {
  if (!h5.has("/channels/at_frames/in_span")) return;
  const auto in_span = h5.read_doubles("/channels/at_frames/in_span");
  r.normal_N = channel_at_frames(h5, "normal_force_N", in_span);
  r.tangential_N = channel_at_frames(h5, "tangential_force_N", in_span);
  if (h5.has("/friction/mu") && h5.has("/friction/valid")) {
    r.mu = h5.read_doubles("/friction/mu");
    const auto valid = h5.read_doubles("/friction/valid");
    for (std::size_t i = 0; i < r.mu.size(); ++i)
      if (valid[i] == 0.0) r.mu[i] = kNaN;
  }
}

// U / U_ext where the cumulative external work is at least 1 % of its largest magnitude: just after the
// onset both are near zero and their ratio is noise.
void read_energy(const H5Reader& h5, ResultData& r) {
  r.energy_J = optional_series(h5, "/energy/total_J");
  r.energy_ratio_at_t90 = h5.has("/work/energy_ratio") ? h5.read_doubles("/work/energy_ratio").at(0) : kNaN;
  if (r.energy_J.empty() || !h5.has("/work/external_cumulative_J")) return;
  const auto external = h5.read_doubles("/work/external_cumulative_J");
  double largest = 0.0;
  for (double w : external) largest = std::max(largest, std::abs(w));
  r.energy_ratio.assign(r.energy_J.size(), kNaN);
  for (std::size_t i = 0; i < external.size() && i < r.energy_J.size(); ++i)
    if (largest > 0.0 && std::abs(external[i]) >= 0.01 * largest)
      r.energy_ratio[i] = r.energy_J[i] / external[i];
}

void read_stick(const H5Reader& h5, ResultData& r) {
  r.stick_ratio = optional_series(h5, "/stick/ratio");
  r.stick_radius_ratio = optional_series(h5, "/stick/radius_ratio");
  if (!h5.has("/stick/tracks_reach_ratio") || !h5.has("/stick/radius_status")) return;
  constexpr std::int64_t kSlipBeyondTracks = 3;  // strain::StickZoneStatus::kSlipBeyondTracks
  const std::vector<double> reach = h5.read_doubles("/stick/tracks_reach_ratio");
  const std::vector<std::int64_t> status = h5.read_integers("/stick/radius_status");
  r.stick_unmeasured_reach.assign(reach.size(), kNaN);
  for (std::size_t i = 0; i < reach.size() && i < status.size(); ++i)
    if (status[i] == kSlipBeyondTracks) r.stick_unmeasured_reach[i] = reach[i];
}

void read_fit(const H5Reader& h5, ResultData& r) {
  if (!h5.has("/fit/model")) return;
  static constexpr const char* kModels[] = {"rest", "full_stick", "partial_slip", "full_slip"};
  const auto model = h5.read_integers("/fit/model");
  const auto c = h5.read_doubles("/fit/c_mm");
  const auto a = h5.read_doubles("/fit/a_mm");
  r.fit_tangential_N = h5.read_doubles("/fit/tangential_N");
  r.fit_c_of_a.assign(model.size(), kNaN);
  r.fit_model.assign(model.size(), "");
  for (std::size_t i = 0; i < model.size(); ++i) {
    if (model[i] < 0 || model[i] > 3) continue;
    r.fit_model[i] = kModels[model[i]];
    if (a[i] > 0.0) r.fit_c_of_a[i] = c[i] / a[i];
  }
}

Instant instant_at(const ResultData& r, const std::string& name, long frame, const std::string& source) {
  return {name, frame, r.t_s.at(static_cast<std::size_t>(frame)), source};
}

// The force channels' events when the channels stage found them.
std::vector<Instant> instants_from_events(const H5Reader& h5, const ResultData& r) {
  std::vector<Instant> out;
  for (const char* name : {"onset", "t90", "full_slip"}) {
    const std::string path = std::string("/events/") + name + "_frame";
    if (!h5.has(path)) continue;
    const long frame = static_cast<long>(h5.read_integers(path).at(0));
    if (frame >= 0 && static_cast<std::size_t>(frame) < r.t_s.size())
      out.push_back(instant_at(r, name, frame, "force channels (/events)"));
  }
  return out;
}

// Without force channels, the model fit's own reading of the trial (as `tirstrain fit` picks its
// pictures): onset the first loaded frame after a rest frame, t90 the first with Q ≥ 0.9 of the largest
// fitted Q, full slip the first frame fitted as full slip.
std::vector<Instant> instants_from_fit(const ResultData& r) {
  std::vector<Instant> out;
  if (r.fit_model.empty()) return out;
  const std::string source = "model fit (/fit): no force events";
  for (std::size_t i = 1; i < r.fit_model.size(); ++i)
    if (r.fit_model[i - 1] == "rest" && !r.fit_model[i].empty() && r.fit_model[i] != "rest") {
      out.push_back(instant_at(r, "onset", static_cast<long>(i), source));
      break;
    }
  double largest = 0.0;
  for (double q : r.fit_tangential_N)
    if (std::isfinite(q)) largest = std::max(largest, std::abs(q));
  for (std::size_t i = 0; i < r.fit_tangential_N.size() && largest > 0.0; ++i)
    if (std::abs(r.fit_tangential_N[i]) >= 0.9 * largest) {
      out.push_back(instant_at(r, "t90", static_cast<long>(i), source));
      break;
    }
  for (std::size_t i = 0; i < r.fit_model.size(); ++i)
    if (r.fit_model[i] == "full_slip") {
      out.push_back(instant_at(r, "full_slip", static_cast<long>(i), source));
      break;
    }
  return out;
}

// Neither events nor a fit: the frame of largest strain energy, named as what it is.
std::vector<Instant> fallback_instants(const ResultData& r) {
  if (r.energy_J.empty()) return {};
  long best = -1;
  for (std::size_t i = 0; i < r.energy_J.size(); ++i)
    if (std::isfinite(r.energy_J[i]) &&
        (best < 0 || r.energy_J[i] > r.energy_J[static_cast<std::size_t>(best)]))
      best = static_cast<long>(i);
  if (best < 0) return {};
  return {instant_at(r, "largest U", best,
                     "no force events and no model fit: the frame of largest strain energy")};
}

void choose_instants(const H5Reader& h5, ResultData& r) {
  r.instants = instants_from_events(h5, r);
  if (r.instants.empty()) r.instants = instants_from_fit(r);
  if (r.instants.empty()) r.instants = fallback_instants(r);
}

double covered_fraction(const std::vector<double>& values, int cells, double aspect) {
  std::size_t inside = 0, finite = 0;
  for (int j = 0; j < cells; ++j)
    for (int i = 0; i < cells; ++i) {
      const double x = -1.0 + 2.0 * i / (cells - 1), y = -1.0 + 2.0 * j / (cells - 1);
      if (x * x + (y / aspect) * (y / aspect) > 1.0) continue;
      ++inside;
      if (std::isfinite(values[static_cast<std::size_t>(j * cells + i)])) ++finite;
    }
  return inside ? static_cast<double>(finite) / static_cast<double>(inside) : 0.0;
}

StrainMaps maps_at(const H5Reader& h5, const Instant& instant) {
  StrainMaps m;
  m.instant = instant;
  H5Shape shape;
  const auto total =
      h5.read_row_doubles("/maps/strain_total", static_cast<std::size_t>(instant.frame), &shape);
  const auto principal = h5.read_row_doubles("/maps/principal", static_cast<std::size_t>(instant.frame));
  m.cells = static_cast<int>(shape.at(0));
  try {
    m.aspect = h5.attribute_number("/maps", "aspect");
  } catch (const Error&) {
    m.aspect = 1.0;
  }
  if (h5.has_attribute("/maps", "axes_angle_rad"))
    m.axes_angle_rad = h5.attribute_number("/maps", "axes_angle_rad");
  const std::size_t n = shape[0] * shape[1];
  m.component.assign(5, std::vector<double>(n));
  for (std::size_t c = 0; c < n; ++c) {
    for (std::size_t k = 0; k < 3; ++k) m.component[k][c] = total[c * 3 + k];
    m.component[3][c] = principal[c * 2];
    m.component[4][c] = principal[c * 2 + 1];
  }
  m.covered_fraction = covered_fraction(m.component[0], m.cells, m.aspect);
  return m;
}

void read_maps(const H5Reader& h5, ResultData& r) {
  if (!h5.has("/maps/strain_total") || !h5.has("/maps/principal")) return;
  for (const Instant& instant : r.instants) r.maps.push_back(maps_at(h5, instant));
}

// e1's direction over the used triangles at t90 (else the last instant), one count per triangle.
void read_principal_directions(const H5Reader& h5, const ReadOptions& options, ResultData& r) {
  if (r.instants.empty() || !h5.has("/strain/principal") || !h5.has("/mesh/status")) return;
  Instant at = r.instants.back();
  for (const Instant& i : r.instants)
    if (i.name == "t90") at = i;
  const auto frame = static_cast<std::size_t>(at.frame);
  const auto principal = h5.read_row_doubles("/strain/principal", frame);
  const auto status = h5.read_row_doubles("/mesh/status", frame);
  r.principal_directions.what =
      "principal direction of e1 at " + at.name + " (frame " + std::to_string(at.frame) + ")";
  for (std::size_t t = 0; t < status.size(); ++t) {
    const double e1 = principal[t * 3], e2 = principal[t * 3 + 1], angle = principal[t * 3 + 2];
    if (status[t] != 0.0 || !std::isfinite(angle) || e1 - e2 < options.min_principal_difference) continue;
    r.principal_directions.angle_rad.push_back(angle < 0.0 ? angle + std::numbers::pi : angle);
    r.principal_directions.weight.push_back(1.0);
  }
}

long reference_row(const H5Reader& h5) {
  try {
    return static_cast<long>(h5.attribute_number("/tracks", "reference_frame_row"));
  } catch (const Error&) {
    return 0;
  }
}

// Ridge direction per block at the reference frame, weighted by the block's coherence.
void read_ridge_orientation(const H5Reader& h5, const ReadOptions& options, ResultData& r) {
  if (!h5.has("/contact/orientation_rad") || r.t_s.empty()) return;
  const auto frame =
      static_cast<std::size_t>(std::clamp(reference_row(h5), 0L, static_cast<long>(r.t_s.size()) - 1));
  const auto angle = h5.read_row_doubles("/contact/orientation_rad", frame);
  const auto coherence = h5.read_row_doubles("/contact/coherence", frame);
  r.ridge_orientation.what = "ridge orientation at the reference frame (frame " + std::to_string(frame) + ")";
  for (std::size_t b = 0; b < angle.size(); ++b) {
    if (!(coherence[b] >= options.min_ridge_coherence)) continue;
    r.ridge_orientation.angle_rad.push_back(angle[b]);
    r.ridge_orientation.weight.push_back(coherence[b]);
  }
}

}  // namespace

std::string result_file_of(const std::string& path) {
  const fs::path p(path);
  if (!fs::exists(p))
    throw Error("no such result: give a folder written by `tirstrain process`", {.file = path});
  const fs::path file = fs::is_directory(p) ? p / "result.h5" : p;
  if (!fs::exists(file))
    throw Error("no result.h5 here: give a folder written by `tirstrain process` (or its result.h5)",
                {.file = file.string()});
  return file.string();
}

ResultData read_result(const std::string& path, const ReadOptions& options) {
  const std::string file = result_file_of(path);
  const H5Reader h5(file);
  if (!h5.has("/frames/t_s") || text_attribute(h5, "stages").empty())
    throw Error("not a result of `tirstrain process` (no /frames/t_s or stages attribute)", {.file = file});
  ResultData r;
  r.dir = path;
  r.label = label_of(file);
  read_identity(h5, r);
  r.t_s = h5.read_doubles("/frames/t_s");
  read_contact(h5, r);
  read_tracks(h5, r);
  read_channels(h5, r);
  read_energy(h5, r);
  read_stick(h5, r);
  read_fit(h5, r);
  choose_instants(h5, r);
  read_maps(h5, r);
  read_principal_directions(h5, options, r);
  read_ridge_orientation(h5, options, r);
  return r;
}

}  // namespace tirstrain::report
