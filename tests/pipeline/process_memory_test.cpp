// `tirstrain process`, `validate`, `track` and `live` with analysis on a long trial need no more memory than
// on a short one: per-frame results go to result.h5 as frames are done (pipeline/stage.hpp). Measured as the
// child process's peak resident set (wait4's rusage), on small frames with large strain maps so that keeping
// every frame's results would show: 160x160 map cells cost 1.84 MB per frame, 110 MB over the 60 extra frames
// of the long trial.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "core/h5_file.hpp"
#include "tests/support/scratch.hpp"

namespace tirstrain {
namespace {

namespace fs = std::filesystem;

// A 160x128 Hertz contact (a = 37 px) sheared by a Cattaneo-Mindlin field, noise free.
std::string scene_yaml(int frames, double frame_rate_Hz = 100.0) {
  return "calibration: {px_per_mm: 20, ridge_period_mm: 0.45, ridge_polarity: dark}\n"
         "compute: [contact, tracking, strain]\n"
         "strain: {map_cells: 160}\n"
         "synthesis:\n"
         "  seed: 5\n"
         "  image: {width_px: 160, height_px: 128, bit_depth: 8}\n"
         "  timing: {frames: " +
         std::to_string(frames) + ", frame_rate_hz: " + std::to_string(frame_rate_Hz) +
         ", jitter_s: 0}\n"
         "  contact: {shape: hertz, normal_N: 2.0, radius_m: 0.005}\n"
         "  loading: {field: cattaneo_mindlin, friction: 1.0, direction_deg: 270, plate_speed_mm_s: 0.5, "
         "shear_start_s: 0.02}\n"
         "  sensor: {full_well_electrons: 0, read_noise: 0, blur_sigma_px: 0, drift: 0}\n";
}

struct ChildRun {
  int exit_code = -1;
  double peak_rss_MB = 0.0;
};

// Runs the CLI with `arguments` as a child and reports its own peak resident set (not the test's); its
// standard error goes to `stderr_path` when one is given.
ChildRun run_cli(const std::vector<std::string>& arguments, const std::string& stderr_path = "") {
  std::vector<std::string> argv_text = {TIRSTRAIN_CLI};
  argv_text.insert(argv_text.end(), arguments.begin(), arguments.end());
  std::vector<char*> argv;
  for (std::string& a : argv_text) argv.push_back(a.data());
  argv.push_back(nullptr);
  const pid_t pid = fork();
  if (pid == 0) {
    // Under AddressSanitizer freed memory is held back (the quarantine, 256 MB by default) and would count
    // as resident however little the run keeps; a small quarantine keeps the measure about the program.
    const char* asan = std::getenv("ASAN_OPTIONS");
    const std::string options = std::string(asan ? asan : "") + (asan ? ":" : "") + "quarantine_size_mb=16";
    setenv("ASAN_OPTIONS", options.c_str(), 1);
    if (!stderr_path.empty()) {
      const int fd = open(stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
      if (fd < 0 || dup2(fd, STDERR_FILENO) < 0) _exit(126);
      close(fd);
    }
    execv(argv[0], argv.data());
    _exit(127);
  }
  ChildRun run;
  int status = 0;
  struct rusage usage {};
  if (wait4(pid, &status, 0, &usage) != pid) return run;
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  run.peak_rss_MB = static_cast<double>(usage.ru_maxrss) / 1024.0;  // ru_maxrss is in KiB on Linux
  return run;
}

// Synthesises a trial of `frames` frames and processes it into scratch/process_memory/NAME/out; returns the
// process run.
ChildRun synth_and_process(const std::string& name, int frames) {
  const fs::path dir = testing::scratch_dir("process_memory", name);
  fs::create_directories(dir);
  { std::ofstream(dir / "scene_in.yaml") << scene_yaml(frames); }
  const ChildRun synth = run_cli(
      {"synth", "--scene", (dir / "scene_in.yaml").string(), "--out", (dir / "trial").string(), "--quiet"});
  EXPECT_EQ(synth.exit_code, 0) << name;
  const ChildRun process = run_cli(
      {"process", (dir / "trial").string(), "--out", (dir / "out").string(), "--overlay", "none", "--quiet"});
  EXPECT_EQ(process.exit_code, 0) << name;
  const H5Reader h5((dir / "out" / "result.h5").string());
  EXPECT_EQ(h5.shape("/maps/strain_total"), (H5Shape{static_cast<std::size_t>(frames), 160, 160, 3})) << name;
  EXPECT_EQ(h5.attribute_number("/", "complete"), 1.0) << name;
  return process;
}

// The command `arguments(dir)` gives, run on synth_and_process's short and long trial folders: the long one
// within 20 MB of the short one's peak resident set.
void expect_flat_memory(const std::string& command,
                        const std::function<std::vector<std::string>(const fs::path&)>& arguments) {
  const fs::path dir = fs::path(TIRSTRAIN_TEST_TMP) / "process_memory";
  const ChildRun short_run = run_cli(arguments(dir / "short")), long_run = run_cli(arguments(dir / "long"));
  std::printf("%s peak RSS: 12 frames %.1f MB, 72 frames %.1f MB\n", command.c_str(), short_run.peak_rss_MB,
              long_run.peak_rss_MB);
  EXPECT_EQ(short_run.exit_code, 0) << command;
  EXPECT_EQ(long_run.exit_code, 0) << command;
  EXPECT_LE(long_run.peak_rss_MB, short_run.peak_rss_MB + 20.0) << command;
}

TEST(ProcessMemory, LongTrialNeedsNoMoreMemoryThanAShortOne) {
  const ChildRun short_run = synth_and_process("short", 12);
  const ChildRun long_run = synth_and_process("long", 72);
  std::printf("peak RSS: 12 frames %.1f MB, 72 frames %.1f MB\n", short_run.peak_rss_MB,
              long_run.peak_rss_MB);
  ASSERT_GT(short_run.peak_rss_MB, 0.0);
  // Keeping every frame would add 110 MB (the maps alone); the bound leaves room for allocator noise.
  EXPECT_LE(long_run.peak_rss_MB, 1.25 * short_run.peak_rss_MB + 50.0);

  // On the same two trials and results: `validate` (no processing) reads the track, strain and map rows a
  // frame at a time (reading the long trial's whole arrays would add about 50 MB, the 160x160 maps' 37 MB of
  // them), and `track` writes each frame's rows as it goes.
  expect_flat_memory("validate", [](const fs::path& dir) -> std::vector<std::string> {
    return {"validate",
            "--trial",
            (dir / "trial").string(),
            "--result",
            (dir / "out").string(),
            "--out",
            (dir / "validation").string(),
            "--quiet"};
  });
  expect_flat_memory("track", [](const fs::path& dir) -> std::vector<std::string> {
    return {"track", (dir / "trial").string(),      "--grid", "6",
            "--out", (dir / "tracks.csv").string(), "--quiet"};
  });
}

// The number in `live`'s "(N frames analysed)" line, or -1.
int frames_analysed(const fs::path& stderr_path) {
  std::stringstream text;
  text << std::ifstream(stderr_path).rdbuf();
  const std::string s = text.str(), tail = " frames analysed)";
  const std::size_t end = s.find(tail), open = s.rfind('(', end);
  if (end == std::string::npos || open == std::string::npos) return -1;
  return std::stoi(s.substr(open + 1, end - open - 1));
}

// `live` with the scene's analysis stages on a recording replayed at its recorded rate: stages keep only the
// newest frame, so six times the frames analysed need no more memory. 10 frames/s leaves every frame time to
// be analysed, also under the sanitizers.
TEST(ProcessMemory, LiveAnalysisOfALongReplayNeedsNoMoreMemoryThanAShortOne) {
  ChildRun runs[2];
  int analysed[2] = {0, 0};
  const int frames[2] = {12, 72};
  for (int i = 0; i < 2; ++i) {
    const fs::path dir = testing::scratch_dir("process_memory", "live_" + std::to_string(frames[i]));
    fs::create_directories(dir);
    { std::ofstream(dir / "scene_in.yaml") << scene_yaml(frames[i], 10.0); }
    ASSERT_EQ(run_cli({"synth", "--scene", (dir / "scene_in.yaml").string(), "--out",
                       (dir / "trial").string(), "--quiet"})
                  .exit_code,
              0);
    runs[i] = run_cli({"live", (dir / "trial").string(), "--scene", (dir / "trial" / "scene.yaml").string(),
                       "--no-window", "--recorded-rate", "--quiet"},
                      (dir / "live.log").string());
    analysed[i] = frames_analysed(dir / "live.log");
    EXPECT_EQ(runs[i].exit_code, 0) << frames[i] << " frames";
  }
  std::printf("live peak RSS: %d frames analysed %.1f MB, %d analysed %.1f MB\n", analysed[0],
              runs[0].peak_rss_MB, analysed[1], runs[1].peak_rss_MB);
  EXPECT_GE(analysed[1], 48);  // most of the 72: the replay gives each frame 100 ms
  EXPECT_GT(analysed[0], 0);
  EXPECT_LE(runs[1].peak_rss_MB, runs[0].peak_rss_MB + 20.0);
}

}  // namespace
}  // namespace tirstrain
