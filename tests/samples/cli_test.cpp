// `tirstrain synth` end to end: outputs, truth.h5 contents, determinism, example scenes and bad scene files.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "core/csv.hpp"
#include "core/h5_file.hpp"
#include "core/scene.hpp"
#include "core/yaml_reader.hpp"
#include "samples/synth.hpp"
#include "test_support.hpp"

namespace fs = std::filesystem;

namespace tirstrain::samples {
namespace {

using testing::clean_scene;
using testing::config_of;
using testing::run_cli;
using testing::scratch_dir;
using testing::write_yaml;

std::string read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

YAML::Node small_scene() {
  YAML::Node scene = clean_scene(160, 128, 4, 50.0);
  scene["reference_pattern"]["roi_px"] = YAML::Load("[0, 0, 160, 20]");
  scene["synthesis"]["contact"]["normal_N"] = 0.5;
  return scene;
}

TEST(SamplesCli, WritesACompleteTrialDirectory) {
  const std::string dir = scratch_dir("cli-complete");
  const YAML::Node scene = small_scene();
  write_yaml(scene, dir + "/scene.yaml");
  const auto r =
      run_cli("synth --scene " + dir + "/scene.yaml --out " + dir + "/trial --quiet", dir + "/log.txt");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const fs::path trial(dir + "/trial");
  EXPECT_FALSE(fs::exists(dir + "/trial.partial"));
  for (int k = 0; k < 4; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", k);
    const cv::Mat image = cv::imread((trial / "frames" / name).string(), cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(image.empty()) << name;
    EXPECT_EQ(image.type(), CV_16U);
    EXPECT_EQ(image.cols, 160);
    EXPECT_EQ(image.rows, 128);
  }
  // The written frame is the in-memory render through the sensor model, bit for bit.
  const Trial memory(config_of(scene));
  const cv::Mat expected = memory.apply_sensor(memory.render_clean(2), 2);
  const cv::Mat written = cv::imread((trial / "frames" / "000002.png").string(), cv::IMREAD_UNCHANGED);
  EXPECT_EQ(cv::norm(expected, written, cv::NORM_INF), 0.0);

  const CsvTable frames = read_numeric_csv((trial / "frames.csv").string());
  ASSERT_EQ(frames.rows(), 4u);
  EXPECT_EQ(frames.column("index")[3], 3.0);
  EXPECT_DOUBLE_EQ(frames.column("t_s")[3], 0.06);
  const CsvTable channels = read_numeric_csv((trial / "channels.csv").string());
  for (const char* name : {"t_s", "normal_N", "tangential_N", "plate_x_mm", "plate_y_mm", "accel_m_s2"})
    EXPECT_TRUE(channels.has(name)) << name;
  EXPECT_EQ(channels.rows(), 81u);  // 0 .. 80 ms at 1 kHz (last frame + one frame period)

  // scene.yaml is a scene `tirstrain process` accepts, with the pattern band and the seed used.
  const Scene written_scene = load_scene((trial / "scene.yaml").string());
  ASSERT_TRUE(written_scene.reference_pattern_roi);
  EXPECT_EQ(written_scene.reference_pattern_roi->height, 20);
  EXPECT_DOUBLE_EQ(written_scene.px_per_mm, 52.0);
  EXPECT_EQ(YamlSection(written_scene.synthesis, written_scene.file, "synthesis").integer("seed", -1), 7);

  const H5Reader truth((trial / "truth.h5").string());
  EXPECT_EQ(truth.attribute_text("/", "format"), kTruthFormat);
  EXPECT_EQ(truth.shape("/contact/mask"), (H5Shape{4, 128, 160}));
  EXPECT_EQ(truth.shape("/field/displacement_px"), (H5Shape{4, 32, 40, 2}));
  EXPECT_EQ(truth.shape("/field/gradient"), (H5Shape{4, 32, 40, 4}));
  EXPECT_EQ(truth.shape("/field/strain"), (H5Shape{4, 32, 40, 3}));
  EXPECT_EQ(truth.shape("/field/in_contact"), (H5Shape{4, 32, 40}));
  EXPECT_EQ(truth.shape("/plate/displacement_px"), (H5Shape{4, 2}));
  for (const char* name : {"/load/normal_N", "/load/tangential_N", "/load/stick_radius_m",
                           "/load/rigid_shift_m", "/frames/t_s", "/load/full_slip"})
    EXPECT_EQ(truth.shape(name), (H5Shape{4})) << name;
  // The file holds exactly what the in-memory trial applied.
  const auto displacement = truth.read_doubles("/field/displacement_px");
  const auto strain = truth.read_doubles("/field/strain");
  for (int k = 0; k < 4; ++k) {
    const GridTruth g = memory.grid_truth(k);
    for (std::size_t i = 0; i < g.displacement_px.size(); ++i)
      ASSERT_EQ(displacement[k * g.displacement_px.size() + i], g.displacement_px[i]);
    for (std::size_t i = 0; i < g.strain.size(); ++i) ASSERT_EQ(strain[k * g.strain.size() + i], g.strain[i]);
  }
  // Ridge orientation on 32 x 32 blocks of the image (5 x 4 blocks of 160 x 128), per frame.
  EXPECT_EQ(truth.shape("/texture/orientation_rad"), (H5Shape{4, 4, 5}));
  EXPECT_EQ(truth.shape("/texture/orientation_coherence"), (H5Shape{4, 4, 5}));
  EXPECT_EQ(truth.attribute_number("/texture/orientation_rad", "block_px"), 32.0);
  const auto orientation = truth.read_doubles("/texture/orientation_rad");
  const auto coherence = truth.read_doubles("/texture/orientation_coherence");
  for (int k = 0; k < 4; ++k) {
    const Trial::OrientationBlocks o = memory.ridge_orientation_blocks(k, 32);
    for (int i = 0; i < 20; ++i) {
      ASSERT_EQ(orientation[static_cast<std::size_t>(20 * k + i)],
                o.orientation_rad.at<double>(i / 5, i % 5));
      ASSERT_EQ(coherence[static_cast<std::size_t>(20 * k + i)], o.coherence.at<double>(i / 5, i % 5));
    }
  }
  const auto tangential = truth.read_doubles("/load/tangential_N");
  EXPECT_EQ(tangential[0], 0.0);
  EXPECT_GT(tangential[3], 0.0);
}

TEST(SamplesCli, SameSeedSameBytesOtherSeedOtherImages) {
  const std::string dir = scratch_dir("cli-seed");
  YAML::Node scene = clean_scene(96, 80, 2, 50.0);
  scene["synthesis"]["sensor"] = YAML::Load("{read_noise: 0.01, full_well_electrons: 5000}");
  scene["synthesis"]["image"]["bit_depth"] = 8;
  write_yaml(scene, dir + "/scene.yaml");
  const std::string base = "synth --quiet --scene " + dir + "/scene.yaml --out " + dir;
  ASSERT_EQ(run_cli(base + "/a --seed 5", dir + "/a.log").exit_code, 0);
  ASSERT_EQ(run_cli(base + "/b --seed 5", dir + "/b.log").exit_code, 0);
  ASSERT_EQ(run_cli(base + "/c --seed 6", dir + "/c.log").exit_code, 0);
  for (const char* f : {"frames/000000.png", "frames/000001.png", "channels.csv", "frames.csv"})
    EXPECT_EQ(read_bytes(dir + "/a/" + f), read_bytes(dir + "/b/" + f)) << f;
  EXPECT_NE(read_bytes(dir + "/a/frames/000001.png"), read_bytes(dir + "/c/frames/000001.png"));
}

struct BadScene {
  const char* what;
  const char* yaml_path;  // where to change the clean scene ("synthesis.contact.normal_N")
  const char* value;      // YAML text; "<remove>" deletes the key
  const char* key;        // the key the message must name
};

TEST(SamplesCli, BadSceneFilesNameKeyAndFileAndLeaveNoOutput) {
  const BadScene cases[] = {
      {"unknown key", "synthesis.contact.nromal_N", "2.0", "synthesis.contact.nromal_N"},
      {"unknown section", "synthesis.lighting", "{drift: 1}", "synthesis.lighting"},
      {"missing required key", "synthesis.timing.frames", "<remove>", "synthesis.timing.frames"},
      {"missing synthesis section", "synthesis", "<remove>", "synthesis"},
      {"wrong type", "synthesis.image.width_px", "wide", "synthesis.image.width_px"},
      {"wrong type (list)", "synthesis.loading.direction_deg", "[1, 2]", "synthesis.loading.direction_deg"},
      {"out of range", "synthesis.loading.friction", "-0.5", "synthesis.loading.friction"},
      {"out of range (bit depth)", "synthesis.image.bit_depth", "12", "synthesis.image.bit_depth"},
      {"out of range (orientation blocks)", "synthesis.truth.orientation_block_px", "2",
       "synthesis.truth.orientation_block_px"},
      {"wrong type (pores)", "synthesis.fingerprint.pore_depth", "deep", "synthesis.fingerprint.pore_depth"},
      {"bad choice", "synthesis.loading.field", "twist", "synthesis.loading.field"},
      {"core key wrong type", "tissue.E_Pa", "soft", "tissue.E_Pa"},
      {"Poisson ratio at the incompressible limit", "tissue.nu", "0.5", "tissue.nu"},
  };
  const std::string dir = scratch_dir("cli-bad");
  int index = 0;
  for (const BadScene& c : cases) {
    YAML::Node root = clean_scene(64, 64, 2, 10.0);
    std::vector<std::string> parts;
    std::stringstream path(c.yaml_path);
    for (std::string part; std::getline(path, part, '.');) parts.push_back(part);
    YAML::Node node = root;
    for (std::size_t i = 0; i + 1 < parts.size(); ++i) node.reset(node[parts[i]]);
    if (std::string(c.value) == "<remove>")
      node.remove(parts.back());
    else
      node[parts.back()] = YAML::Load(c.value);
    const std::string scene_file = dir + "/bad" + std::to_string(index) + ".yaml";
    const std::string out = dir + "/out" + std::to_string(index);
    write_yaml(root, scene_file);
    const auto r = run_cli("synth --scene " + scene_file + " --out " + out,
                           dir + "/log" + std::to_string(index) + ".txt");
    EXPECT_NE(r.exit_code, 0) << c.what;
    EXPECT_NE(r.output.find(c.key), std::string::npos) << c.what << ": " << r.output;
    EXPECT_NE(r.output.find(scene_file), std::string::npos) << c.what << ": " << r.output;
    EXPECT_FALSE(fs::exists(out)) << c.what;
    EXPECT_FALSE(fs::exists(out + ".partial")) << c.what;
    ++index;
  }
}

// synth replaces its output folder as a whole: an earlier trial there is replaced, a folder holding
// anything else is refused and left as it was.
TEST(SamplesCli, ReplacesAnEarlierTrialButNotSomeoneElsesFolder) {
  const std::string dir = scratch_dir("cli-replace");
  write_yaml(small_scene(), dir + "/scene.yaml");
  const std::string synth = "synth --scene " + dir + "/scene.yaml --quiet --out ";
  ASSERT_EQ(run_cli(synth + dir + "/trial", dir + "/log1.txt").exit_code, 0);
  ASSERT_EQ(run_cli(synth + dir + "/trial", dir + "/log2.txt").exit_code, 0);
  fs::create_directories(dir + "/mine");
  std::ofstream(dir + "/mine/notes.txt") << "keep";
  const auto r = run_cli(synth + dir + "/mine", dir + "/log3.txt");
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("notes.txt"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(dir + "/mine/notes.txt"));
  EXPECT_FALSE(fs::exists(dir + "/mine/truth.h5"));
}

// A seed that truth.h5 and the written scene could not hold exactly (negative, past 2^53) is a usage error.
TEST(SamplesCli, RefusesASeedThatWouldNotReadBack) {
  const std::string dir = scratch_dir("cli-seed");
  write_yaml(small_scene(), dir + "/scene.yaml");
  for (const char* seed : {"-1", "9007199254740993", "99999999999999999999"}) {
    const auto r = run_cli("synth --scene " + dir + "/scene.yaml --quiet --out " + dir + "/t --seed " + seed,
                           dir + "/log.txt");
    EXPECT_EQ(r.exit_code, 2) << seed << ": " << r.output;
    EXPECT_FALSE(fs::exists(dir + "/t")) << seed;
  }
}

TEST(SamplesCli, HelpStatesUnits) {
  const std::string dir = scratch_dir("cli-help");
  const auto r = run_cli("synth --help", dir + "/help.txt");
  EXPECT_EQ(r.exit_code, 0);
  for (const char* word : {"--scene", "--out", "--seed", "--quiet", "truth.h5", "accel_m_s2", "px"})
    EXPECT_NE(r.output.find(word), std::string::npos) << word;
}

TEST(SamplesScenes, EveryExampleSceneIsValid) {
  int count = 0;
  for (const auto& entry : fs::directory_iterator(fs::path(TIRSTRAIN_SOURCE_DIR) / "samples" / "scenes")) {
    if (entry.path().extension() != ".yaml") continue;
    SCOPED_TRACE(entry.path().string());
    const Trial trial(load_synth_config(entry.path().string()));
    EXPECT_GE(trial.frames(), 2);
    const LoadState last = trial.load(trial.frames() - 1);
    EXPECT_GE(last.normal_N, 0.0);
    ++count;
  }
  EXPECT_GE(count, 15);
  const SynthConfig d = load_synth_config(std::string(TIRSTRAIN_SOURCE_DIR) + "/samples/scenes/default.yaml");
  EXPECT_EQ(d.timing.frames, 60);
  EXPECT_EQ(d.image.width_px, 640);
  EXPECT_EQ(d.image.height_px, 512);
}

}  // namespace
}  // namespace tirstrain::samples
