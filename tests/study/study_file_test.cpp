// The study file's strict validation (pipeline/study_file.cpp) and the trial hash that decides what a
// study run redoes (pipeline/study.cpp).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "pipeline/study.hpp"
#include "pipeline/study_file.hpp"
#include "tests/support/expect_error.hpp"
#include "tests/support/scratch.hpp"

namespace tirstrain::pipeline {
namespace {

namespace fs = std::filesystem;
using tirstrain::testing::expect_error;
using tirstrain::testing::scratch_dir;

void write(const fs::path& path, const std::string& text) {
  fs::create_directories(path.parent_path());
  std::ofstream(path) << text;
}

// A folder with two recordings (one file each) and a scene.
fs::path recordings(const std::string& test) {
  const fs::path dir = scratch_dir("study_file", test);
  write(dir / "rec" / "a" / "frames.csv", "index,t_s\n0,0\n");
  write(dir / "rec" / "b" / "frames.csv", "index,t_s\n0,0.5\n");
  write(dir / "scene.yaml", "calibration: {px_per_mm: 20}\n");
  return dir;
}

TEST(StudyFile, TrialsWithConditionsAndAggregateAreRead) {
  const fs::path dir = recordings("read");
  write(dir / "s.yaml",
        "scene: scene.yaml\n"
        "trials:\n"
        "  - {name: a, input: rec/a, conditions: {normal_N: 2, speed_mm_s: 5}}\n"
        "  - {name: b, input: rec/b, scene: other.yaml, conditions: {normal_N: 4, speed_mm_s: 5}}\n"
        "aggregate:\n"
        "  power_laws: [{name: friction, normal: normal_N}]\n"
        "  maps: {by: [speed_mm_s]}\n"
        "slurm: {partition: short, cpus_per_task: 2, mem_MB: 2000, time_min: 30}\n");
  const StudySpec spec = load_study_file((dir / "s.yaml").string());
  ASSERT_EQ(spec.trials.size(), 2u);
  EXPECT_EQ(spec.trials[0].input, (dir / "rec" / "a").string());
  EXPECT_EQ(spec.trials[0].scene, (dir / "scene.yaml").string());
  EXPECT_EQ(spec.trials[1].scene, (dir / "other.yaml").string());
  EXPECT_EQ(spec.trials[1].conditions.at("normal_N"), "4");
  ASSERT_EQ(spec.aggregate.power_laws.size(), 1u);
  EXPECT_EQ(spec.aggregate.power_laws[0].mu, "mu_dynamic");
  EXPECT_EQ(spec.aggregate.maps_by, std::vector<std::string>{"speed_mm_s"});
  EXPECT_EQ(spec.slurm.partition, "short");
  EXPECT_EQ(spec.slurm.mem_MB, 2000);
}

TEST(StudyFile, GlobFormNamesTrialsByFolder) {
  const fs::path dir = recordings("glob");
  write(dir / "s.yaml", "inputs: \"rec/*/\"\nscene: scene.yaml\n");
  const StudySpec spec = load_study_file((dir / "s.yaml").string());
  ASSERT_EQ(spec.trials.size(), 2u);
  EXPECT_EQ(spec.trials[0].name, "a");
  EXPECT_EQ(spec.trials[1].name, "b");
  EXPECT_EQ(spec.trials[1].scene, (dir / "scene.yaml").string());
}

TEST(StudyFile, MistakesNameFileKeyAndLine) {
  const fs::path dir = recordings("errors");
  struct Case {
    std::string yaml, key, words;
    long row;  // 0: none expected
  };
  const std::vector<Case> cases = {
      {"trials:\n  - {name: a, input: rec/a}\n  - {name: b, input: rec/b, scnee: s.yaml}\n",
       "trials[1].scnee", "unknown key", 3},
      {"trials:\n  - {name: a, input: rec/a}\n  - {name: b, inptu: rec/b}\n", "trials[1].input", "missing",
       3},
      {"trials:\n  - {name: a, input: rec/a}\n  - {name: a, input: rec/b}\n", "trials[1].name", "two trials",
       3},
      {"trials:\n  - {name: 'a/b', input: rec/a}\n", "trials[0].name", "letters", 2},
      {"trials:\n  - {name: a, input: rec/a, conditions: {status: x}}\n", "trials[0].conditions.status",
       "column", 2},
      {"trials:\n  - {name: a, input: rec/a}\ninputs: 'rec/*'\n", "trials", "not both", 0},
      {"inputs: 'nothing/*'\n", "inputs", "matches nothing", 0},
      {"trials:\n  - {name: a, input: rec/a, conditions: {n: 1}}\naggregate: {maps: {by: [speed]}}\n",
       "aggregate.maps.by", "not a condition", 0},
      {"trials:\n  - {name: a, input: rec/a}\nslurm: {cpus_per_task: 0}\n", "slurm.cpus_per_task", "outside",
       0},
      {"trials:\n  - {name: a, input: rec/a}\nagregate: {}\n", "agregate", "unknown key", 0},
      {"trials:\n  - {name: a, input: rec/a}\naggregate: {power_laws: [{name: f, mu: mu_dyn}]}\n",
       "aggregate.power_laws[0]", "neither a condition", 0},
  };
  for (const Case& c : cases) {
    write(dir / "bad.yaml", c.yaml);
    const Error e = expect_error([&] { load_study_file((dir / "bad.yaml").string()); });
    EXPECT_EQ(e.context().key, c.key) << c.yaml << e.what();
    EXPECT_EQ(e.context().file, (dir / "bad.yaml").string()) << c.yaml;
    EXPECT_NE(e.message().find(c.words), std::string::npos) << c.yaml << e.what();
    if (c.row > 0) {
      EXPECT_EQ(e.context().row.value_or(-1), c.row) << c.yaml << e.what();
    }
  }
}

TEST(StudyHash, ChangesWithInputBytesAndSceneOnly) {
  const fs::path dir = recordings("hash");
  const StudyTrial a{"a", (dir / "rec" / "a").string(), (dir / "scene.yaml").string(), {}};
  const std::string h0 = trial_hash(a);
  EXPECT_EQ(h0.size(), 16u);
  EXPECT_EQ(trial_hash(a), h0);  // deterministic
  StudyTrial relabelled = a;
  relabelled.conditions["normal_N"] = "2";
  EXPECT_EQ(trial_hash(relabelled), h0);                        // conditions are labels, not inputs
  write(dir / "rec" / "a" / "frames.csv", "index,t_s\n0,1\n");  // one byte differs
  const std::string h1 = trial_hash(a);
  EXPECT_NE(h1, h0);
  write(dir / "scene.yaml", "calibration: {px_per_mm: 21}\n");
  EXPECT_NE(trial_hash(a), h1);
  write(dir / "rec" / "a" / "frames" / "000000.png", "x");  // a file added
  EXPECT_NE(trial_hash(a), h1);
  const Error e = expect_error([&] { trial_hash({"m", (dir / "missing").string(), "", {}}); });
  EXPECT_NE(std::string(e.what()).find("missing"), std::string::npos) << e.what();
}

}  // namespace
}  // namespace tirstrain::pipeline
