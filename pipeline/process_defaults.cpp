#include "pipeline/process_defaults.hpp"

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "contact/pattern_band.hpp"
#include "core/error.hpp"
#include "pipeline/channels_stage.hpp"

namespace tirstrain::pipeline {
namespace {

namespace fs = std::filesystem;

// Header names of a CSV file (first line, comma separated, spaces trimmed).
std::vector<std::string> csv_header(const std::string& path) {
  std::ifstream in(path);
  std::string line;
  std::vector<std::string> names;
  if (!in || !std::getline(in, line)) return names;
  std::stringstream cells(line);
  std::string cell;
  while (std::getline(cells, cell, ',')) {
    const auto first = cell.find_first_not_of(" \t\r");
    const auto last = cell.find_last_not_of(" \t\r");
    names.push_back(first == std::string::npos ? "" : cell.substr(first, last - first + 1));
  }
  return names;
}

// The edge a scene's band runs along (it spans the image's width or height from one side), else "inside".
std::string edge_of(const RoiPx& r, cv::Size size) {
  const bool full_width = r.x == 0 && r.width == size.width;
  const bool full_height = r.y == 0 && r.height == size.height;
  if (full_width && r.y == 0) return "top";
  if (full_width && r.y + r.height == size.height) return "bottom";
  if (full_height && r.x == 0) return "left";
  if (full_height && r.x + r.width == size.width) return "right";
  return "inside";
}

}  // namespace

std::string default_channel_file(const std::string& input) {
  std::error_code ec;
  const fs::path in(input);
  const fs::path folder = fs::is_directory(in, ec) ? in : in.parent_path();
  return (folder / "channels.csv").string();
}

SceneSection default_channels_section(const std::string& file) {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) return {};
  // Roles by the column names `tirstrain synth` writes (docs/formats.md, channels.csv).
  static const std::vector<std::pair<std::string, std::string>> known = {
      {"normal_force", "normal_N"},       {"tangential_force", "tangential_N"},
      {"plate_position_x", "plate_x_mm"}, {"plate_position_y", "plate_y_mm"},
      {"accelerometer", "accel_m_s2"},    {"trigger", "trigger_V"}};
  const std::vector<std::string> header = csv_header(file);
  const auto has = [&](const std::string& name) {
    return std::find(header.begin(), header.end(), name) != header.end();
  };
  if (!has("t_s")) return {};
  // The plate's position goes by both axes or not at all.
  const bool plate = has("plate_x_mm") && has("plate_y_mm");
  SceneSection columns;
  for (const auto& [role, column] : known)
    if (has(column) && (plate || role.rfind("plate_position_", 0) != 0)) columns = columns.with(role, column);
  if (columns.empty()) return {};
  return SceneSection().with("file", fs::absolute(file).lexically_normal().string()).with("columns", columns);
}

std::vector<std::string> default_stages(Scene& scene, const std::string& input, std::string& reason) {
  std::vector<std::string> stages = {"contact", "tracking", "strain"};
  reason = "no compute list in the scene: contact, tracking and strain from the images";
  if (!scene.channels.empty()) {
    stages.push_back("channels");
    reason += "; channels from the scene's channels section";
    return stages;
  }
  const std::string file = default_channel_file(input);
  const SceneSection section = default_channels_section(file);
  if (section.empty()) {
    reason += "; no channels (no channels section, no " + file + " with known columns)";
    return stages;
  }
  // A section or file that the channels stage would reject leaves the channels out rather than stop the run.
  Scene trial = scene;
  trial.channels = section;
  try {
    check_channel_file(trial);
  } catch (const std::exception& e) {
    reason += "; no channels (" + file + ": " + e.what() + ")";
    return stages;
  }
  scene.channels = section;
  stages.push_back("channels");
  reason += "; channels from " + file;
  return stages;
}

nlohmann::json PatternBandChoice::to_json() const {
  nlohmann::json j;
  j["source"] = source;
  j["edge"] = edge;
  if (roi_px) {
    j["roi_px"] = {roi_px->x, roi_px->y, roi_px->width, roi_px->height};
  } else {
    j["roi_px"] = nullptr;
  }
  if (confidence) {
    j["confidence"] = *confidence;
  } else {
    j["confidence"] = nullptr;
  }
  j["contact_exclusion_margin_px"] = margin_px;
  return j;
}

std::string PatternBandChoice::describe() const {
  char text[256];
  if (roi_px) {
    std::snprintf(text, sizeof text, "reference pattern band %s along the %s edge, roi_px [%d, %d, %d, %d]%s",
                  source == "scene" ? "from the scene" : "detected", edge.c_str(), roi_px->x, roi_px->y,
                  roi_px->width, roi_px->height, "");
    std::string line = text;
    if (confidence) {
      std::snprintf(text, sizeof text, ", confidence %.2f", *confidence);
      line += text;
    }
    return line;
  }
  if (source == "off")
    return "reference pattern band: detection off in the scene; plate displacement not measured";
  std::snprintf(
      text, sizeof text,
      "reference pattern band: none found along the image edges (confidence %.2f); plate displacement "
      "not measured",
      confidence.value_or(0.0));
  return text;
}

// A band the frames do not hold whole was written for another camera or region of interest: the scene is
// wrong, and a clipped band would hide it.
void check_pattern_band(const Scene& scene, cv::Size image_size) {
  if (!scene.reference_pattern_roi) return;
  const RoiPx& r = *scene.reference_pattern_roi;
  const cv::Rect band(r.x, r.y, r.width, r.height);
  if ((band & cv::Rect({0, 0}, image_size)) == band) return;
  throw Error("the pattern band [" + std::to_string(r.x) + ", " + std::to_string(r.y) + ", " +
                  std::to_string(r.width) + ", " + std::to_string(r.height) + "] (x, y, width, height) " +
                  ((band & cv::Rect({0, 0}, image_size)).empty() ? "lies outside" : "reaches outside") +
                  " the " + std::to_string(image_size.width) + " x " + std::to_string(image_size.height) +
                  " px frames",
              {.file = scene.file, .key = "reference_pattern.roi_px"});
}

// A band the scene gives is used as given, but a dot band the images show elsewhere (another camera's scene,
// frames turned upside down) would have the plate measured on skin or background, hundreds of px off with
// nothing to tell: that is said. A scene band away from the edges, where detection does not look, or
// images with no band found, are not judged.
std::string scene_band_elsewhere(const RoiPx& r, const cv::Mat& first_frame) {
  const contact::PatternBand band = contact::detect_pattern_band(first_frame);
  if (band.edge == contact::ImageEdge::kNone) return {};
  const cv::Rect scene_band(r.x, r.y, r.width, r.height);
  const double shared = (scene_band & band.roi_px).area();
  const double either = scene_band.area() + band.roi_px.area() - shared;
  if (either > 0.0 && shared / either >= 0.3) return {};
  char text[512];
  std::snprintf(
      text, sizeof text,
      "the scene's reference_pattern.roi_px [%d, %d, %d, %d] is not where the images show the printed "
      "dot band: the first frame has one along the %s edge, roi_px [%d, %d, %d, %d] (confidence "
      "%.2f); the plate displacement is measured on what the scene's band holds, so check roi_px "
      "(or remove it to use the band found)",
      r.x, r.y, r.width, r.height, contact::to_string(band.edge).c_str(), band.roi_px.x, band.roi_px.y,
      band.roi_px.width, band.roi_px.height, band.confidence);
  return text;
}

PatternBandChoice resolve_pattern_band(Scene& scene, const cv::Mat& first_frame) {
  check_pattern_band(scene, first_frame.size());
  PatternBandChoice choice;
  if (scene.reference_pattern_roi) {
    choice.source = "scene";
    choice.roi_px = scene.reference_pattern_roi;
    choice.edge = edge_of(*scene.reference_pattern_roi, first_frame.size());
    choice.warning = scene_band_elsewhere(*scene.reference_pattern_roi, first_frame);
    return choice;
  }
  if (!scene.reference_pattern_detect) {
    choice.source = "off";
    choice.edge = "none";
    return choice;
  }
  const contact::PatternBand band = contact::detect_pattern_band(first_frame);
  choice.confidence = band.confidence;
  choice.edge = contact::to_string(band.edge);
  if (band.edge == contact::ImageEdge::kNone) {
    choice.source = "none";
    return choice;
  }
  choice.source = "detected";
  const cv::Rect& r = band.roi_px;
  choice.roi_px = RoiPx{r.x, r.y, r.width, r.height};
  choice.margin_px = band.margin_px;
  scene.reference_pattern_roi = choice.roi_px;
  scene.reference_pattern_margin_px = band.margin_px;
  return choice;
}

std::vector<std::string> default_value_notes(const Scene& scene) {
  std::vector<std::string> notes;
  char text[256];
  if (!scene.px_per_mm_given) {
    std::snprintf(
        text, sizeof text,
        "calibration: px_per_mm = %g is the default (no scene gives calibration.px_per_mm): lengths, "
        "areas and the ridge period in mm are only as right as it is",
        scene.px_per_mm);
    notes.emplace_back(text);
  }
  if (!scene.tissue_given) {
    std::snprintf(text, sizeof text,
                  "tissue: E = %g Pa, nu = %g, depth = %g m are the defaults (no scene gives tissue): strain "
                  "energy scales with E and depth",
                  scene.tissue.young_Pa, scene.tissue.poisson, scene.tissue.depth_m);
    notes.emplace_back(text);
  }
  return notes;
}

}  // namespace tirstrain::pipeline
