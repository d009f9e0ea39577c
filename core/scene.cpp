#include "core/scene.hpp"

#include <algorithm>
#include <filesystem>
#include <fstream>

#include "core/atomic_output.hpp"
#include "core/detail/yaml_tree.hpp"
#include "core/error.hpp"
#include "core/yaml_reader.hpp"

namespace tirstrain {

const std::vector<std::string>& known_stages() {
  static const std::vector<std::string> stages = {"contact", "tracking", "strain", "channels", "fit"};
  return stages;
}

namespace {

// The `compute:` list: known stage names, in pipeline order as given.
std::vector<std::string> read_compute(YamlSection& top, const std::string& file) {
  // `compute:` with nothing after it is a list forgotten, not a request to run nothing.
  if (top.raw("compute").empty())
    throw Error("expected a list of stage names", {.file = file, .key = "compute"});
  std::vector<std::string> stages = top.texts("compute", {}, "stage names");
  const auto& known = known_stages();
  for (const auto& name : stages) {
    if (std::find(known.begin(), known.end(), name) != known.end()) continue;
    std::string listed;
    for (const auto& k : known) listed += (listed.empty() ? "" : ", ") + k;
    throw Error("unknown stage '" + name + "' (known: " + listed + ")", {.file = file, .key = "compute"});
  }
  return stages;
}

}  // namespace

Scene parse_scene(const SceneSection& root, const std::string& file) {
  Scene scene;
  scene.file = file;
  YamlSection top(root, file);

  YamlSection calibration = top.section("calibration");
  scene.px_per_mm_given = calibration.has("px_per_mm");
  scene.px_per_mm = calibration.number("px_per_mm", 52.0, 1e-3, 1e5);
  if (calibration.has("ridge_period_mm"))
    scene.ridge_period_mm = calibration.number("ridge_period_mm", 0.45, 0.05, 5.0);
  scene.ridge_polarity = calibration.choice("ridge_polarity", "auto", {"auto", "dark", "bright"});
  calibration.finish();

  YamlSection tissue = top.section("tissue");
  scene.tissue_given = tissue.has("E_Pa") || tissue.has("nu") || tissue.has("depth_m");
  scene.tissue.young_Pa = tissue.number("E_Pa", 1.0e6, 1.0, 1.0e12);
  scene.tissue.poisson = tissue.number("nu", 0.4, -0.999, 0.4999);
  scene.tissue.depth_m = tissue.number("depth_m", 0.002, 1e-6, 1.0);
  tissue.finish();

  YamlSection pattern = top.section("reference_pattern");
  if (pattern.has("roi_px")) {
    const auto roi = pattern.numbers("roi_px", {});
    if (roi.size() != 4 || roi[2] <= 0 || roi[3] <= 0 || roi[0] < 0 || roi[1] < 0)
      throw Error("expected [x, y, width, height] in pixels with positive width and height",
                  {.file = file, .key = "reference_pattern.roi_px"});
    scene.reference_pattern_roi = RoiPx{static_cast<int>(roi[0]), static_cast<int>(roi[1]),
                                        static_cast<int>(roi[2]), static_cast<int>(roi[3])};
  }
  scene.reference_pattern_detect = pattern.boolean("detect", true);
  pattern.finish();

  if (top.has("compute")) {
    scene.compute = read_compute(top, file);
    scene.compute_given = true;
  }
  scene.synthesis = top.raw("synthesis");
  scene.segmentation = top.raw("segmentation");
  scene.tracking = top.raw("tracking");
  scene.strain = top.raw("strain");
  scene.channels = top.raw("channels");
  scene.camera = top.raw("camera");
  top.finish();
  return scene;
}

Scene load_scene(const std::string& path) {
  return parse_scene(SceneSection::load(path), path);
}

Scene parse_scene_text(const std::string& yaml, const std::string& file) {
  return parse_scene(SceneSection::parse(yaml, file), file);
}

namespace {

YAML::Node scene_tree(const Scene& scene) {
  YAML::Node root;
  root["calibration"]["px_per_mm"] = scene.px_per_mm;
  if (scene.ridge_period_mm) root["calibration"]["ridge_period_mm"] = *scene.ridge_period_mm;
  root["calibration"]["ridge_polarity"] = scene.ridge_polarity;
  root["tissue"]["E_Pa"] = scene.tissue.young_Pa;
  root["tissue"]["nu"] = scene.tissue.poisson;
  root["tissue"]["depth_m"] = scene.tissue.depth_m;
  if (scene.reference_pattern_roi) {
    const RoiPx& r = *scene.reference_pattern_roi;
    YAML::Node roi;
    roi.push_back(r.x);
    roi.push_back(r.y);
    roi.push_back(r.width);
    roi.push_back(r.height);
    roi.SetStyle(YAML::EmitterStyle::Flow);
    root["reference_pattern"]["roi_px"] = roi;
  }
  if (!scene.reference_pattern_detect) root["reference_pattern"]["detect"] = false;
  if (scene.compute_given) {
    YAML::Node compute;
    for (const auto& s : scene.compute) compute.push_back(s);
    compute.SetStyle(YAML::EmitterStyle::Flow);
    root["compute"] = compute;
  }
  const auto add = [&root](const char* key, const SceneSection& section) {
    if (!section.empty()) root[key] = yaml_node(section);
  };
  add("synthesis", scene.synthesis);
  add("segmentation", scene.segmentation);
  add("tracking", scene.tracking);
  add("strain", scene.strain);
  add("channels", scene.channels);
  add("camera", scene.camera);
  return root;
}

}  // namespace

std::string scene_to_yaml(const Scene& scene) {
  return section_of(scene_tree(scene)).to_yaml();
}

void save_scene(const Scene& scene, const std::string& path) {
  write_text_file(path, "# tirstrain scene file\n" + scene_to_yaml(scene) + "\n");
}

}  // namespace tirstrain
